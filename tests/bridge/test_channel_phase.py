"""The TCP channel's phase table: concurrent handshakes, replacements, illegal events."""

from __future__ import annotations

import threading

import pytest

from bridge.errors import BridgeUsageError
from bridge.transport.channel_phase import ChannelPhase
from harness import ManualClock as Clock


def test_one_handshake_goes_up_and_down():
    clock = Clock()
    phase = ChannelPhase(clock)
    assert (phase.phase, phase.since) == ("down", 100.0)
    clock.now = 101.0
    assert phase.move("connected") == "handshake" and phase.since == 101.0
    clock.now = 102.0
    assert phase.move("hello_ok") == "up" and phase.since == 102.0
    clock.now = 103.0
    assert phase.move("lost") == "down" and phase.since == 103.0


def test_a_second_handshake_is_no_illegal_transition():
    """Two connections in their handshake at once (the listener runs up to four): the old
    table raised on the second "connected" outside the handshake's error handling, the
    thread died and its socket leaked."""
    clock = Clock()
    phase = ChannelPhase(clock)
    phase.move("connected")
    clock.now = 101.0
    assert phase.move("connected") == "handshake" and phase.since == 100.0   # no change
    assert phase.move("failed") == "handshake"          # the other one still runs
    assert phase.move("failed") == "down"


def test_a_proven_connection_replaces_the_link_and_candidates_leave_it_up():
    clock = Clock()
    phase = ChannelPhase(clock)
    phase.move("connected")
    phase.move("hello_ok")
    phase.move("connected")                              # a candidate beside the link
    assert phase.phase == "up"
    assert phase.move("failed") == "up"                  # a stranger failed: still up
    phase.move("connected")
    phase.move("connected")
    clock.now = 105.0
    assert phase.move("hello_ok") == "up" and phase.since == 105.0    # a new link is up
    assert phase.move("hello_ok") == "up"                # and another one replaced it
    phase.move("connected")
    assert phase.move("lost") == "handshake"             # a link gone, a handshake runs
    assert phase.move("failed") == "down"


@pytest.mark.parametrize("events, bad", [([], "failed"), ([], "hello_ok"), ([], "lost"),
                                         (["connected"], "lost"), ([], "up")])
def test_an_impossible_event_names_itself_and_the_phase(events, bad):
    phase = ChannelPhase()
    for event in events:
        phase.move(event)
    with pytest.raises(BridgeUsageError, match=f"'{bad}'"):
        phase.move(bad)
    assert phase.handshakes == len(events)               # nothing changed


def test_concurrent_handshakes_keep_the_count():
    phase = ChannelPhase()
    barrier = threading.Barrier(8)

    def handshake(index: int) -> None:
        barrier.wait()
        for _ in range(500):
            phase.move("connected")
            phase.move("hello_ok" if index % 2 else "failed")

    threads = [threading.Thread(target=handshake, args=(i,)) for i in range(8)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert (phase.handshakes, phase.link_up, phase.phase) == (0, True, "up")
    assert phase.move("lost") == "down"
