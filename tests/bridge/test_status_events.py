"""Which GYM statuses leave at once (bridge.gym.status_events), on a hand-driven clock."""

from __future__ import annotations

from bridge.gym.status_events import COMMAND_WINDOW, StatusEvents
from harness import ManualClock as Clock
from yarp_lite.bottle import Bottle


def status(seq: int, state: str, *data) -> Bottle:
    return Bottle([seq, state, *data])


def test_a_new_state_is_an_event_and_a_repeated_status_is_not():
    events = StatusEvents(Clock())
    assert not events.is_event(7, status(2, "idle"))  # the first one: nothing to compare
    assert not events.is_event(7, status(3, "idle"))  # only the message counter moved
    assert events.is_event(7, status(4, "running"))
    assert not events.is_event(7, status(5, "running"))


def test_changing_data_is_an_event_only_right_after_a_command():
    clock = Clock()
    events = StatusEvents(clock)
    events.is_event(3, status(2, "running", 40.0))
    assert not events.is_event(3, status(3, "running", 40.5))  # drifting by itself
    events.commanded(3)
    clock.now += COMMAND_WINDOW / 2
    assert events.is_event(3, status(4, "running", 12.0))       # the command's effect
    clock.now += COMMAND_WINDOW
    assert not events.is_event(3, status(5, "running", 12.5))
    assert not events.is_event(4, status(2, "running", 1.0))    # modules are apart


def test_the_status_answering_a_command_is_told_apart_from_later_ones():
    """The first change after a command, and a new state, also go as datagram copies
    (bridge.transport.copies); later changes within the window are events by TCP only."""
    clock = Clock()
    events = StatusEvents(clock)
    events.classify(3, status(2, "running", 40.0))
    events.commanded(3)
    assert events.classify(3, status(3, "running", 41.0)) == "first answer"
    assert events.classify(3, status(4, "running", 42.0)) == "answer"
    assert events.classify(3, status(5, "running", 42.0)) is None   # nothing changed
    events.commanded(3)
    assert events.classify(3, status(6, "reached", 42.0)) == "state"
    assert events.classify(3, status(7, "reached", 43.0)) == "answer"  # answered by the state
