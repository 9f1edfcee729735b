"""The supervisor's watch on a module process: a starting process is not a hung one."""

from __future__ import annotations

import os
import subprocess
import threading
import time

import pytest

from walkman.gym import supervisor
from walkman.gym.supervisor import Supervisor


@pytest.fixture
def short_timeouts(monkeypatch):
    monkeypatch.setattr(supervisor, "HEARTBEAT_TIMEOUT", 0.5)
    monkeypatch.setattr(supervisor, "STARTUP_TIMEOUT", 2.5)


def watched(beats: int):
    """A child that sleeps, a pipe beaten ``beats`` times 0.2 s apart; (seconds until
    the watch killed it, the watch's return)."""
    read_fd, write_fd = os.pipe()
    watcher = Supervisor([])
    watcher.child = subprocess.Popen(["sleep", "60"])

    def beat() -> None:
        for _ in range(beats):
            os.write(write_fd, b".")
            time.sleep(0.2)

    threading.Thread(target=beat, daemon=True).start()
    began = time.monotonic()
    try:
        code = watcher._watch(read_fd)
    finally:
        os.close(read_fd)
        os.close(write_fd)
        if watcher.child.poll() is None:
            watcher.child.kill()
    return time.monotonic() - began, code


def test_a_module_that_never_beat_gets_the_startup_time(short_timeouts):
    seconds, code = watched(beats=0)
    assert code is None                       # killed for want of a heartbeat
    assert 2.5 <= seconds < 4.5, seconds      # not the 0.5 s of a running module


def test_a_module_that_stops_beating_is_killed_after_the_heartbeat_timeout(short_timeouts):
    seconds, code = watched(beats=5)          # about 1 s of beats, then silence
    assert code is None
    assert 1.3 <= seconds < 2.4, seconds      # the last beat + 0.5 s, well before 2.5 s
