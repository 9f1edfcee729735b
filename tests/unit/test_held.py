"""yarp_lite.held: what an output port keeps for readers that connect later (pure)."""

from __future__ import annotations

import pytest
from hypothesis import given, strategies as st

from yarp_lite.bottle import Bottle
from yarp_lite.carriers import BottlePayload
from yarp_lite.errors import LocalProtocolError
from yarp_lite.held import HeldMessages, HoldPolicy
from harness import ManualClock as Clock


def texts(held) -> list:
    return [h.payload.bottle()[0] for h in held]


def hold(count: int = 4, max_age: float = 10.0):
    clock = Clock()
    return HeldMessages(HoldPolicy(count, max_age), clock), clock


def write(messages: HeldMessages, text: str):
    return messages.written("D", BottlePayload(Bottle([text])))


def test_a_message_no_reader_took_is_owed_to_the_first_that_connects():
    messages, _ = hold()
    write(messages, "a")
    write(messages, "b")
    owed = messages.owed("/bridge")
    assert texts(owed) == ["a", "b"]
    for held in owed:
        messages.handed(held, "/bridge")
    assert messages.owed("/bridge") == []
    assert messages.handed_over == 2


def test_a_reader_back_under_its_name_gets_only_what_it_missed():
    messages, _ = hold()
    took = write(messages, "took")
    messages.taken(took, "/bridge")
    write(messages, "missed")
    assert texts(messages.owed("/bridge")) == ["missed"]
    # a new reader gets the recent history, as a latched topic
    assert texts(messages.owed("/look")) == ["took", "missed"]


def test_held_messages_are_bounded_by_count_and_age():
    messages, clock = hold(count=3, max_age=10.0)
    for text in "abcd":                  # written at 100, 104, 108, 112
        write(messages, text)
        clock.now += 4.0
    clock.now = 112.0
    assert texts(messages.owed("/r")) == ["b", "c", "d"]     # the count: a is pushed out
    assert messages.never_taken == 1
    clock.now = 115.0                                        # b is 11 s old
    assert texts(messages.owed("/r")) == ["c", "d"]
    assert messages.never_taken == 2
    clock.now = 200.0
    assert messages.owed("/r") == [] and len(messages) == 0


def test_a_message_some_reader_took_is_not_counted_as_never_taken():
    messages, clock = hold(count=1)
    messages.taken(write(messages, "a"), "/r")
    write(messages, "b")
    clock.now += 60
    assert messages.owed("/r") == []
    assert messages.never_taken == 1                         # b only


@pytest.mark.parametrize("count, max_age", [(0, 1.0), (1, 0.0), (1, -1.0), (1, float("nan"))])
def test_a_policy_that_holds_nothing_is_a_usage_error(count, max_age):
    with pytest.raises(LocalProtocolError, match="at least one message"):
        HoldPolicy(count, max_age)


operations = st.lists(st.one_of(
    st.tuples(st.just("write"), st.floats(0.0, 5.0)),               # after this many seconds
    st.tuples(st.just("take"), st.sampled_from(["/a", "/b"])),      # the newest, by a reader
), max_size=40)


@given(operations, st.integers(1, 6), st.floats(1.0, 20.0))
def test_owed_is_every_recent_message_the_reader_has_not_taken_in_order(ops, count, max_age):
    messages, clock = hold(count, max_age)
    model = []                                  # (written, text, readers), never forgotten
    for number, (what, value) in enumerate(ops):
        if what == "write":
            clock.now += value
            held = write(messages, str(number))
            model.append((clock.now, str(number), set(), held))
        elif model:
            model[-1][2].add(value)
            messages.taken(model[-1][3], value)
    for reader in ("/a", "/b", "/new"):
        recent = model[-count:]
        expected = [text for written, text, readers, _ in recent
                    if written >= clock.now - max_age and reader not in readers]
        assert texts(messages.owed(reader)) == expected
