"""walkman.realtime: a thread asks for SCHED_FIFO and learns why it cannot have it."""

import os
import threading

import pytest

from walkman.realtime import make_realtime, realtime_refused


def in_a_thread(function):
    """``function()``'s result and the thread's scheduling policy after it, in a thread of
    its own (the test process itself stays at normal priority)."""
    out = {}

    def run() -> None:
        out["result"] = function()
        out["policy"] = os.sched_getscheduler(0)

    thread = threading.Thread(target=run)
    thread.start()
    thread.join()
    return out["result"], out["policy"]


def test_opting_out_is_the_reason_given(monkeypatch):
    monkeypatch.setenv("WALKMAN_NO_RT", "1")
    assert in_a_thread(lambda: realtime_refused(1)) == ("WALKMAN_NO_RT is set", os.SCHED_OTHER)
    assert in_a_thread(lambda: make_realtime(1)) == (False, os.SCHED_OTHER)


def test_a_priority_the_kernel_refuses_is_reported_not_raised(monkeypatch):
    monkeypatch.delenv("WALKMAN_NO_RT", raising=False)
    reason, policy = in_a_thread(lambda: realtime_refused(1000))   # FIFO's range is 1..99
    assert reason and "Invalid argument" in reason
    assert policy == os.SCHED_OTHER


@pytest.mark.requires("root")
def test_granted_the_thread_runs_fifo_at_that_priority(monkeypatch):
    monkeypatch.delenv("WALKMAN_NO_RT", raising=False)
    seen = {}

    def become() -> None:
        seen["refused"] = realtime_refused(3)
        seen["priority"] = os.sched_getparam(0).sched_priority

    _, policy = in_a_thread(lambda: become())
    assert seen == {"refused": None, "priority": 3}
    assert policy == os.SCHED_FIFO
