"""walkman.gym.validity: the lifetime trailer a switch or command carries."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, strategies as st

from walkman.gym.validity import (DEFAULT_VALIDITY, Lifetime, ValidityError, aged,
                                  check_validity, describe_expiry, split, stamp)
from yarp_lite.bottle import Bottle
from yarp_lite.bottle_text import parse

TURN = parse("(turn 1.5) 42")


def test_a_stamped_command_splits_back_into_itself_and_its_lifetime():
    stamped = stamp(TURN, Lifetime(0.25, 10.0))
    assert stamped.to_text() == "(turn 1.5) 42 (age 0.25 valid 10.0)"
    assert split(stamped) == (TURN, Lifetime(0.25, 10.0))


def test_a_command_without_a_trailer_has_no_lifetime():
    assert split(TURN) == (TURN, None)
    assert split(parse("start 3")) == (parse("start 3"), None)


def test_each_hop_adds_the_time_it_held_the_command():
    once = aged(TURN, 1.5)                    # a bridge gives a bare command a trailer
    assert split(once) == (TURN, Lifetime(1.5, None))
    twice = aged(stamp(TURN, Lifetime(0.5, 5.0)), 3.0)
    assert split(twice) == (TURN, Lifetime(3.5, 5.0))
    assert split(aged(twice, -2.0))[1].age == 3.5   # a clock stepping back adds nothing


def test_expiry_compares_the_age_with_the_validity_or_the_module_default():
    assert not Lifetime(9.9).expired(DEFAULT_VALIDITY)
    assert Lifetime(10.1).expired(DEFAULT_VALIDITY)
    assert Lifetime(10.1, 60.0).remaining(DEFAULT_VALIDITY) == pytest.approx(49.9)
    assert Lifetime(4.0, 3.0).expired(600.0)


def test_the_refusal_says_what_how_old_and_not_run():
    text = describe_expiry("turn 1.57", Lifetime(23.2, 10.0), DEFAULT_VALIDITY)
    assert text == "`turn 1.57` expired after 23 s in the queue (valid 10 s); not run"


@pytest.mark.parametrize("text, problem", [
    ("start 3 (age)", None),                              # one item: an argument, not a trailer
    ("start 3 (age x)", "age must be a finite number"),
    ("start 3 (age -1)", "age must be a finite number"),
    ("start 3 (age 1 valid)", "a lifetime is"),
    ("start 3 (age 1 until 4)", "got 'until' for valid"),
    ("start 3 (age 1 valid inf)", "valid must be a finite number"),
    ("start 3 (age 1 valid 2 3)", "a lifetime is"),
])
def test_a_malformed_trailer_is_refused_with_what_is_wrong(text, problem):
    bottle = parse(text)
    if problem is None:
        assert split(bottle) == (bottle, None)
        return
    with pytest.raises(ValidityError, match=problem):
        split(bottle)
    assert aged(bottle, 5.0) == bottle   # a hop never makes a bad message look good


@pytest.mark.parametrize("seconds", [0, -1, math.nan, math.inf, 1e9, "10", True])
def test_a_validity_asked_for_must_be_a_sensible_number_of_seconds(seconds):
    with pytest.raises(ValidityError, match="a validity is a number of seconds"):
        check_validity(seconds)


values = st.recursive(
    st.one_of(st.integers(-2**31, 2**31 - 1), st.floats(allow_nan=True),
              st.sampled_from(["age", "valid", "turn", "start"]), st.text(max_size=5)),
    lambda children: st.lists(children, max_size=5).map(Bottle), max_leaves=12)


@given(st.lists(values, max_size=6).map(Bottle))
def test_any_bottle_splits_or_is_refused_and_aging_never_raises(bottle):
    try:
        message, lifetime = split(bottle)
    except ValidityError:
        assert aged(bottle, 1.0) == bottle
        return
    if lifetime is None:
        assert message == bottle
    older = split(aged(bottle, 1.0))
    assert older[0] == message
    assert older[1].age == pytest.approx((lifetime.age if lifetime else 0.0) + 1.0, abs=1e-3)
