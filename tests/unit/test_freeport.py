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


def test_runs_are_found_while_single_ports_are_scattered(monkeypatch):
    monkeypatch.setattr(freeport, "_given", [])
    monkeypatch.setattr(freeport, "is_free", lambda port, host="": True)
    singles = [freeport.free_port() for _ in range(1000)]  # never released, as in a test run
    assert all(11000 <= port < 11000 + freeport.SINGLES for port in singles)
    assert len(set(singles)) == 1000
    runs = [freeport.free_port(span=400) for _ in range(40)]  # 45 fit when packed
    assert all(not set(range(a, a + 400)) & set(range(b, b + 400)) for a in runs for b in runs if a != b)
    assert all(not set(range(r, r + 400)) & set(singles) for r in runs)


def test_ports_in_use_are_skipped():
    with socket.socket() as held:
        held.bind(("127.0.0.1", 0))
        assert not freeport.is_free(held.getsockname()[1])
