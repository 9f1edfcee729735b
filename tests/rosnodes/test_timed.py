"""Timed commands (the paper's QtTimedButton): countdown, second press cancels, never sent."""

import pytest
from hypothesis import given
from hypothesis import strategies as st

from rosnodes.timed import CANCELLED, SENT, WAITING, Countdowns


def test_a_dangerous_command_waits_its_countdown_then_is_sent_once():
    timer = Countdowns(default=3.0)
    event = timer.request("gaze_control", "home", now=10.0, payload="bottle")
    assert (event.state, event.remaining) == (WAITING, 3.0)
    assert [(e.state, e.remaining) for e in timer.tick(11.0)] == [(WAITING, 2.0)]
    sent = timer.tick(13.0)
    assert [(e.state, e.pending.payload) for e in sent] == [(SENT, "bottle")]
    assert timer.tick(20.0) == [] and timer.waiting == 0


def test_the_second_press_cancels_and_nothing_is_sent():
    timer = Countdowns()
    timer.request("gaze_control", "home", now=0.0)
    event = timer.request("gaze_control", "home", now=1.0)
    assert event.state == CANCELLED and event.remaining == pytest.approx(2.0)
    assert timer.tick(100.0) == []


def test_other_commands_and_modules_wait_on_their_own():
    timer = Countdowns(default=3.0)
    timer.request("gaze_control", "home", now=0.0)
    timer.request("gaze_control", "look_at 1 2 3", now=0.5, countdown=1.0)
    timer.request("drc_valve", "home", now=0.0)
    assert sorted(e.pending.text for e in timer.tick(1.6) if e.state == SENT) == ["look_at 1 2 3"]
    assert [e.pending.module for e in timer.cancel_all("gaze_control")] == ["gaze_control"]
    assert [e.pending.module for e in timer.tick(5.0)] == ["drc_valve"]


def test_a_negative_countdown_is_refused():
    with pytest.raises(ValueError, match="cannot be negative"):
        Countdowns().request("m", "x", now=0.0, countdown=-1.0)


@given(st.lists(st.tuples(st.sampled_from(["a", "b"]), st.floats(0, 10)), max_size=30))
def test_each_command_is_sent_at_most_once_and_only_if_not_cancelled(presses):
    """Presses in time order: a command is sent iff its last press run started a countdown."""
    timer = Countdowns(default=2.0)
    sent, now = [], 0.0
    for text, gap in presses:
        now += gap
        sent += [e.pending.text for e in timer.tick(now) if e.state == SENT]
        timer.request("m", text, now)
    sent += [e.pending.text for e in timer.tick(now + 10) if e.state == SENT]
    assert timer.waiting == 0
    # Replay the rule by hand.
    expected, waiting_since = [], {}
    now = 0.0
    for text, gap in presses:
        now += gap
        for other, since in sorted(waiting_since.items(), key=lambda item: item[1]):
            if since + 2.0 - now <= 0:  # the same arithmetic as the deadline
                expected.append(other)
                del waiting_since[other]
        if text in waiting_since:
            del waiting_since[text]
        else:
            waiting_since[text] = now
    expected += sorted(waiting_since, key=waiting_since.get)
    assert sorted(sent) == sorted(expected)
