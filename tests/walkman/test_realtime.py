"""walkman.realtime: a thread asks for SCHED_FIFO and learns why it cannot have it."""

import os
import threading

import pytest

from walkman.realtime import keep_priority, make_realtime, make_realtime_once, realtime_refused


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


@pytest.mark.requires("root")
def test_a_reader_kept_at_a_priority_follows_its_module_and_asks_only_on_a_change(monkeypatch):
    """A module's reader threads: above its loop while it controls, below every loop while
    it is idle (walkman.hal.robot.Robot._reader_priority), the kernel asked once per change."""
    monkeypatch.delenv("WALKMAN_NO_RT", raising=False)
    asked, seen = [], []
    import walkman.realtime as realtime
    monkeypatch.setattr(realtime, "make_realtime",
                        lambda priority: asked.append(priority) or make_realtime(priority))

    def reader() -> None:
        for priority in (10, 10, 55, 55, 55, 10):
            keep_priority(priority)
            seen.append(os.sched_getparam(0).sched_priority)
        make_realtime_once(55)              # a thread already kept: left where it is
        seen.append(os.sched_getparam(0).sched_priority)

    in_a_thread(reader)
    assert seen == [10, 10, 55, 55, 55, 10, 10]
    assert asked == [10, 55, 10]
