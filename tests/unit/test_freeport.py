"""Port numbers for servers: free, below the ephemeral range, never handed out twice."""

import socket

import pytest

from yarp_lite import freeport


def test_a_run_given_out_is_not_given_again_until_released(monkeypatch):
    monkeypatch.setattr(freeport, "_given", [])  # what other tests were given does not matter
    monkeypatch.setattr(freeport, "is_free", lambda port, host="": True)  # nor what is bound
    # A window with room for exactly one run of 400.
    window = {"span": 400, "start": 31500, "end": 31901}
    first = freeport.free_port(**window)
    assert first == 31500
    with pytest.raises(RuntimeError, match="no run of 400 free TCP ports"):
        freeport.free_port(**window)
    freeport.release(first)
    assert freeport.free_port(**window) == first


def test_ports_in_use_are_skipped():
    with socket.socket() as held:
        held.bind(("127.0.0.1", 0))
        assert not freeport.is_free(held.getsockname()[1])
