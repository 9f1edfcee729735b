"""The bridge's threads, started and joined in one place (bridge.transport.nursery)."""

from __future__ import annotations

import threading

from bridge.transport.nursery import Nursery


def test_threads_are_named_for_their_owner_joined_in_one_call_and_a_stuck_one_named():
    release, stuck = threading.Event(), threading.Event()
    nursery = Nursery("bridge")
    nursery.start_soon(lambda: release.wait(5), "tcp send")
    nursery.start_soon(lambda: stuck.wait(30), "tcp receive")
    assert sorted(nursery.alive()) == ["bridge tcp receive", "bridge tcp send"]
    release.set()
    assert nursery.join(timeout=0.5) == ["bridge tcp receive"]   # the one still blocked
    stuck.set()
    assert nursery.join(timeout=5) == []
    assert nursery.alive() == []


def test_finished_threads_are_forgotten_as_new_ones_start():
    nursery = Nursery("bridge")
    for number in range(50):        # a connection's handshake per reconnection
        nursery.start_soon(lambda: None, f"handshake {number}").join()
    nursery.start_soon(lambda: None, "last").join()
    assert len(nursery._threads) <= 2
    assert nursery.join(timeout=1) == []


def test_a_thread_joining_its_own_nursery_does_not_wait_for_itself():
    nursery = Nursery("bridge")
    left = []
    done = threading.Event()

    def stop_from_inside() -> None:
        left.extend(nursery.join(timeout=1))
        done.set()

    nursery.start_soon(stop_from_inside, "stopper")
    assert done.wait(5) and left == []
