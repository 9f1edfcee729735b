"""The supervisor's watch on a module process: a starting process is not a hung one, and a
quitting one is not restarted."""

from __future__ import annotations

import os
import subprocess
import threading
import sys
import time
from typing import Optional

import pytest

from walkman.gym import supervisor
from walkman.gym.runner import EXIT_QUIT, QUITTING, SIGNALS_ARMED
from walkman.gym.supervisor import Supervisor


@pytest.fixture
def short_timeouts(monkeypatch):
    monkeypatch.setattr(supervisor, "HEARTBEAT_TIMEOUT", 0.5)
    monkeypatch.setattr(supervisor, "STARTUP_TIMEOUT", 2.5)
    monkeypatch.setattr(supervisor, "QUIT_GRACE", 1.5)


#: When the beating thread last wrote, taken just before the write (the watch cannot have
#: read it earlier), in s since the watch began.
last_write: list = []


def watched(beats: int, then: bytes = b"", child_lives: float = 60,
            child: Optional[subprocess.Popen] = None):
    """A child that sleeps ``child_lives`` s (or ``child``), a pipe beaten ``beats`` times
    0.2 s apart and then written ``then``; (seconds until the watch ended, the watch's
    return), and :data:`last_write` set."""
    read_fd, write_fd = os.pipe()
    watcher = Supervisor([])
    watcher.child = child or subprocess.Popen(["sleep", str(child_lives)])
    last_write.clear()
    began = time.monotonic()

    def write(data: bytes) -> None:
        last_write[:] = [time.monotonic() - began]
        os.write(write_fd, data)

    def beat() -> None:
        for _ in range(beats):
            write(b".")
            time.sleep(0.2)
        if then:
            write(then)

    threading.Thread(target=beat, daemon=True).start()
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


def test_a_module_that_armed_its_signals_but_never_beat_still_gets_the_startup_time(
        short_timeouts):
    """Its stack handlers come before its imports: that word is not a beat."""
    seconds, code = watched(beats=0, then=SIGNALS_ARMED)
    assert code is None
    assert 2.5 <= seconds < 4.5, seconds


def test_a_module_that_stops_beating_is_killed_after_the_heartbeat_timeout(short_timeouts):
    seconds, code = watched(beats=5)          # about 1 s of beats, then silence
    assert code is None
    # Not before the last beat + 0.5 s (fc37 of 2026-11-28, beside two burners: 1.299 s
    # from the watch's start failed a bound of 1.3 s that assumed the beats on time), and
    # before the 2.5 s a starting module is given.
    assert last_write[0] + 0.5 <= seconds < 2.4, (seconds, last_write)


#: A module process hung in ``hung_here``, with the runner's faulthandler on SIGUSR2.
HUNG_MODULE = """
import faulthandler, signal, time
faulthandler.register(signal.SIGUSR2, all_threads=True)
def hung_here():
    print("hanging", flush=True)
    time.sleep(60)
hung_here()
"""


def test_a_hung_module_prints_where_it_hung_before_it_is_killed(short_timeouts):
    """A restart cannot tell where the module hung (a drc_door that lost its heartbeat in the
    one-session test of 2026-11-28 left no trace): its threads' stacks come first."""
    child = subprocess.Popen([sys.executable, "-c", HUNG_MODULE], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True)
    assert child.stdout.readline() == "hanging\n"
    seconds, code = watched(beats=2, child=child)
    assert code is None and child.poll() is not None          # killed
    stacks = child.stderr.read()
    child.stdout.close()
    child.stderr.close()
    assert "in hung_here" in stacks and "Current thread" in stacks, stacks


def test_a_module_closing_after_a_quit_is_given_the_quit_grace_not_the_heartbeat_timeout(
        short_timeouts):
    """fc14 of 2026-11-28: closing a dozen ports after ``quit`` took over 5 s under load; the
    supervisor took the silence for a hang and started a fresh module, stopped."""
    seconds, code = watched(beats=3, then=QUITTING)        # then silence, still running
    assert code == EXIT_QUIT                  # killed, and counted as the quit: no restart
    # the grace after the quitting word, not the 0.5 s heartbeat timeout
    assert last_write[0] + 1.5 <= seconds < 3.5, (seconds, last_write)


def test_a_module_that_ends_within_the_quit_grace_gives_its_own_exit(short_timeouts):
    seconds, code = watched(beats=2, then=QUITTING + b".", child_lives=1.2)
    assert code == 0 and seconds < 1.5 + 1.2, seconds


def _watched_saying(words: bytes, sent: list) -> Supervisor:
    """A supervisor that watched a child (killed after 0.3 s) whose pipe said ``words`` and
    ended; the signals it passes on go to ``sent``."""
    import signal
    watcher = Supervisor([])
    watcher.child = subprocess.Popen(["sleep", "60"])
    watcher.child.send_signal = sent.append
    try:
        read_fd, write_fd = os.pipe()
        os.write(write_fd, words)
        os.close(write_fd)
        threading.Timer(0.3, os.kill, (watcher.child.pid, signal.SIGKILL)).start()
        watcher._watch(read_fd)
        os.close(read_fd)
    finally:
        if watcher.child.poll() is None:
            os.kill(watcher.child.pid, signal.SIGKILL)
        watcher.child.wait()
    return watcher


def test_stacks_are_asked_only_of_a_module_that_has_armed_its_handlers(short_timeouts):
    """A module still importing has no SIGUSR1 handler: the signal would kill it (and the
    supervisor start another) instead of printing anything.  Its first beat is no sign
    either: it can come seconds after the module says it is ready (CI of 2026-12-03)."""
    import signal
    sent: list = []
    watcher = Supervisor([])
    watcher.child = subprocess.Popen(["sleep", "60"])
    watcher.child.send_signal = sent.append
    try:
        watcher.show_stacks(signal.SIGUSR1, None)       # nothing said yet
        assert sent == []
    finally:
        os.kill(watcher.child.pid, signal.SIGKILL)
        watcher.child.wait()
    assert not _watched_saying(b".", sent).child_armed             # a beat alone
    assert _watched_saying(SIGNALS_ARMED, sent).child_armed
    watcher.child = subprocess.Popen(["sleep", "60"])
    watcher.child.send_signal = sent.append
    watcher.child_armed = True
    try:
        watcher.show_stacks(signal.SIGUSR1, None)
        assert sent == [signal.SIGUSR1]
    finally:
        os.kill(watcher.child.pid, signal.SIGKILL)
        watcher.child.wait()
