"""Port numbers for servers: free, below the ephemeral range, never handed out twice --
not by this process, nor by any other on the machine while the one given them lives."""

import socket
import subprocess
import sys

import pytest

from yarp_lite import freeport


@pytest.fixture
def registry(tmp_path, monkeypatch):
    """A registry of this test's own: what other tests and processes were given does not matter."""
    path = tmp_path / "ports.json"
    monkeypatch.setenv("YARP_LITE_PORT_REGISTRY", str(path))
    monkeypatch.setattr(freeport, "_cursor", {})
    return path


@pytest.fixture
def nothing_bound(monkeypatch):
    monkeypatch.setattr(freeport, "is_free", lambda port, host="": True)


def test_a_run_given_out_is_not_given_again_until_released(registry, nothing_bound):
    # A window with room for exactly one run of 400.
    window = {"span": 400, "start": 31500, "end": 31901}
    first = freeport.free_port(**window)
    assert first == 31500
    with pytest.raises(RuntimeError, match="no run of 400 free TCP ports"):
        freeport.free_port(**window)
    freeport.release(first)
    assert freeport.free_port(**window) == first


def test_runs_are_found_while_single_ports_are_scattered(registry, nothing_bound):
    singles = [freeport.free_port() for _ in range(1000)]  # never released, as in a test run
    assert all(11000 <= port < 11000 + freeport.SINGLES for port in singles)
    assert len(set(singles)) == 1000
    runs = [freeport.free_port(span=400) for _ in range(40)]  # 45 fit when packed
    assert all(not set(range(a, a + 400)) & set(range(b, b + 400)) for a in runs for b in runs if a != b)
    assert all(not set(range(r, r + 400)) & set(singles) for r in runs)


_OTHER_PROCESS = """
import sys
from yarp_lite import freeport
freeport.is_free = lambda port, host="": True   # as in the test: only the registry counts
print(freeport.free_port(span=400, start=31500, end=31901), flush=True)
sys.stdin.read()   # hold the run until told to end
"""


def test_a_run_another_live_process_holds_is_not_given_until_it_ends(registry, nothing_bound):
    window = {"span": 400, "start": 31500, "end": 31901}
    other = subprocess.Popen([sys.executable, "-c", _OTHER_PROCESS], stdin=subprocess.PIPE,
                             stdout=subprocess.PIPE, text=True, cwd=freeport.__file__.rsplit("/", 2)[0])
    try:
        assert int(other.stdout.readline()) == 31500   # its is_free is real: the run is unbound
        with pytest.raises(RuntimeError, match="no run of 400 free TCP ports"):
            freeport.free_port(**window)
    finally:
        other.stdin.close()
        other.wait(timeout=20)
    assert freeport.free_port(**window) == 31500       # its runs ended with it


def test_a_torn_registry_file_is_forgotten_not_fatal(registry, nothing_bound):
    registry.write_text('[{"start": 1')
    assert 11000 <= freeport.free_port() < 11000 + freeport.SINGLES


def test_ports_in_use_are_skipped():
    with socket.socket() as held:
        held.bind(("127.0.0.1", 0))
        assert not freeport.is_free(held.getsockname()[1])
