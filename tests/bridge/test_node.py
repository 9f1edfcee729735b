"""The bridge node's own decisions, without sockets (its wiring is tested as processes)."""

from __future__ import annotations

from bridge.node import COMMAND_WINDOW, StatusEvents
from yarp_lite.bottle import Bottle


class Clock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


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
