"""The lockstep wire and barrier (walkman/hal/lockstep.py): pure, no sockets."""

from __future__ import annotations

import threading
import time

import pytest
from hypothesis import given
from hypothesis import strategies as st

from walkman.hal.lockstep import (Barrier, Join, Leave, LockstepGate, Tick, decode, encode)
from walkman.hal.protocol import HalProtocolError
from yarp_lite.bottle import Bottle
from yarp_lite.bottle_text import parse

pytestmark = pytest.mark.offline

MESSAGES = [Join("/walking", 0.002), Tick("/walking", 17, 0.044, ("left_leg", "right_leg")),
            Tick("/gaze", 3, 1.5, ()), Leave("/walking")]


@pytest.mark.parametrize("message", MESSAGES)
def test_every_message_survives_the_wire_and_its_text_form(message):
    bottle = encode(message)
    assert decode(bottle) == message
    assert decode(parse(bottle.to_text())) == message       # as `yarp write` would send it


@pytest.mark.parametrize("text, says", [
    ("", "unknown message None"),
    ("hold /walking", "unknown message 'hold'"),
    ("join /walking", "join takes 2 values, got 1"),
    ("join walking 1.0", "must be a port prefix like /walking, got 'walking'"),
    ("join /walking -1.0", "join's due time must be a robot time"),
    ("join /walking nan", "join's due time must be a robot time"),
    ('join /walking "soon"', "join's due time must be a robot time"),
    ("tick /walking 1.5 0.2 ()", "tick's round must be a state count"),
    ("tick /walking -3 0.2 ()", "tick's round must be a state count"),
    ("tick /walking 3 0.2 left_leg", "tick's chains must be a list of chain names"),
    ("tick /walking 3 0.2 (1 2)", "tick's chains must be a list of chain names"),
    ("leave /walking now", "leave takes 1 values, got 2"),
])
def test_a_malformed_message_is_refused_naming_what_is_wrong(text, says):
    with pytest.raises(HalProtocolError, match="lockstep: ") as raised:
        decode(parse(text))
    assert says in str(raised.value)


@given(st.recursive(st.one_of(st.integers(-2**31, 2**31 - 1), st.floats(), st.text(max_size=8),
                              st.sampled_from(["join", "tick", "leave", "/walking"])),
                    lambda inner: st.lists(inner, max_size=5).map(Bottle), max_leaves=12))
def test_any_bottle_is_a_message_or_refused(values):
    bottle = values if isinstance(values, Bottle) else Bottle([values])
    try:
        assert decode(bottle) in (decode(encode(decode(bottle))),)
    except HalProtocolError:
        pass


def test_a_member_holds_the_round_it_is_due_at_until_its_tick_and_commands_are_in():
    barrier = Barrier()
    barrier.receive(Join("/walking", 0.002))
    assert barrier.holding(0.0) == []                       # before its round: free
    assert barrier.holding(0.002) == ["/walking"]           # its round: held
    barrier.receive(Tick("/walking", 1, 0.012, ("left_leg", "right_leg")))
    assert barrier.holding(0.002) == ["/walking"]           # the tick overtook its commands
    assert barrier.commanded("/walking", "left_leg", 1)
    assert barrier.holding(0.002) == ["/walking"]
    assert not barrier.commanded("/other", "right_leg", 1)  # another module's command
    assert barrier.commanded("/walking", "right_leg", 1)
    assert barrier.holding(0.002) == []
    assert barrier.holding(0.010) == []
    assert barrier.holding(0.012 - 1e-9) == ["/walking"]    # float sums: the same round


def test_commands_that_came_before_their_tick_are_not_waited_for():
    barrier = Barrier()
    barrier.receive(Join("/walking", 0.002))
    barrier.commanded("/walking", "left_leg", 1)
    barrier.receive(Tick("/walking", 1, 0.012, ("left_leg",)))
    assert barrier.holding(0.002) == []


def test_an_older_command_does_not_count_for_a_newer_tick():
    barrier = Barrier()
    barrier.receive(Join("/walking", 0.002))
    barrier.commanded("/walking", "left_leg", 1)
    barrier.receive(Tick("/walking", 6, 0.022, ("left_leg",)))
    assert not barrier.commanded("/walking", "left_leg", 5)
    assert barrier.holding(0.012) == ["/walking"]
    assert barrier.commanded("/walking", "left_leg", 6)
    assert barrier.holding(0.012) == []


def test_leave_frees_the_physics_and_a_tick_after_it_rejoins():
    barrier = Barrier()
    assert barrier.receive(Join("/a", 0.0)).startswith("/a joined")
    barrier.receive(Join("/b", 0.0))
    assert barrier.holding(0.002) == ["/a", "/b"]
    assert barrier.receive(Leave("/a")) == "/a left"
    assert barrier.receive(Leave("/a")) is None             # twice: nothing more to say
    assert barrier.holding(0.002) == ["/b"]
    assert "is back" in barrier.receive(Tick("/a", 5, 0.004, ()))
    assert barrier.holding(0.004) == ["/a", "/b"]


def test_the_gate_holds_until_the_member_ticks_and_repeats_the_state_meanwhile():
    gate = LockstepGate(timeout=10.0)
    gate.receive(encode(Join("/walking", 0.002)))
    beats = []
    released = threading.Event()

    def physics():
        gate.hold(0.002, lambda: True, heartbeat=lambda: beats.append(time.monotonic()))
        released.set()

    thread = threading.Thread(target=physics)
    thread.start()
    assert not released.wait(0.35)
    assert len(beats) >= 2                                  # the robot stays visible
    gate.receive(encode(Tick("/walking", 1, 0.012, ("torso",))))
    assert not released.wait(0.1)                           # its command is not in yet
    gate.commanded("/walking", "torso", 1)
    assert released.wait(2.0)
    thread.join()
    assert gate.members == ["/walking"] and gate.dropped == 0


def test_a_member_that_stalls_leaves_after_the_timeout_with_a_log_line(caplog):
    gate = LockstepGate(timeout=0.3)
    gate.receive(encode(Join("/walking", 0.002)))
    start = time.monotonic()
    gate.hold(0.002, lambda: True)
    assert time.monotonic() - start >= 0.3
    assert gate.members == [] and gate.dropped == 1
    assert "/walking did not handle the round at robot time 0.002 s within 0.3 s; it leaves " \
           "the barrier" in caplog.text
    assert gate.refuse_reset() is None


def test_a_shutdown_ends_a_hold_at_once():
    gate = LockstepGate(timeout=60.0)
    gate.receive(encode(Join("/walking", 0.0)))
    running = [True]
    threading.Timer(0.2, lambda: running.__setitem__(0, False)).start()
    start = time.monotonic()
    gate.hold(0.002, lambda: running[0])
    assert time.monotonic() - start < 5.0


def test_garbage_on_the_port_is_logged_and_changes_nothing(caplog):
    gate = LockstepGate()
    gate.receive(encode(Join("/walking", 0.002)))
    gate.receive(parse("tick /walking oops 0.2 ()"))
    gate.receive(parse("leave"))
    assert gate.members == ["/walking"]
    assert "refused on the lockstep port (#1 of this burst): lockstep: tick's round" \
        in caplog.text
    assert "modules are in lockstep with the robot (/walking)" in gate.refuse_reset()


def test_a_chain_commanded_twice_in_a_tick_holds_until_both_commands_are_in():
    barrier = Barrier()
    barrier.receive(Join("/walking", 0.002))
    barrier.commanded("/walking", "torso", 1)
    barrier.receive(Tick("/walking", 1, 0.012, ("torso", "torso", "head")))
    barrier.commanded("/walking", "head", 1)
    assert barrier.holding(0.002) == ["/walking"]      # one of torso's two only
    barrier.commanded("/walking", "torso", 1)
    assert barrier.holding(0.002) == []
