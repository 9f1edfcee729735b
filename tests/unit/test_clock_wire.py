"""yarp_lite/clock_wire.py: the network clock's ``sec nsec`` tick, as YARP writes and reads it."""

from __future__ import annotations

import struct

import pytest
from hypothesis import given, strategies as st

from codec_helpers import FUZZ, bottles
from yarp_lite import bottle as codec
from yarp_lite.bottle import Bottle
from yarp_lite.clock_wire import MAX_SECONDS, Tick, decode_tick, encode_tick
from yarp_lite.errors import LocalProtocolError, NeedMoreData, RemoteProtocolError


def test_a_tick_is_a_list_of_two_int32_as_yarp_writes_it():
    """``addInt32(sec); addInt32(nsec)``: tag list|int32 (257), 2 items, then the two."""
    assert codec.encode(encode_tick(12.5)) == struct.pack("<4i", 256 + 1, 2, 12, 500_000_000)
    assert encode_tick(12.5).to_text() == "12 500000000"


@pytest.mark.parametrize("seconds, sec, nsec", [(0.0, 0, 0), (1.0, 1, 0), (1.002, 1, 2_000_000),
                                                (0.999999999, 0, 999_999_999),
                                                (0.9999999999, 1, 0)])
def test_seconds_split_into_whole_seconds_and_nanoseconds(seconds, sec, nsec):
    assert Tick.at(seconds) == Tick(sec, nsec)
    assert decode_tick(encode_tick(seconds)) == Tick(sec, nsec)


def test_a_tick_arriving_byte_by_byte_is_read_only_whole():
    data = codec.encode(encode_tick(3.25)) + b"trailing"
    for end in range(1, 16):
        with pytest.raises(NeedMoreData):
            codec.decode_prefix(data[:end])
    bottle, used = codec.decode_prefix(data)
    assert used == 16 and decode_tick(bottle) == Tick(3, 250_000_000)


@pytest.mark.parametrize("bottle, named", [
    (Bottle([1]), "got 1 values"),
    (Bottle([1, 2, 3]), "got 3 values"),
    (Bottle([1.5, 0]), "sec must be an int32, got float"),
    (Bottle([1, "x"]), "nsec must be an int32, got str"),
    (Bottle([-1, 0]), "sec is negative"),
    (Bottle([1, 1_000_000_000]), "nsec must be 0 to 999999999"),
    (Bottle([1, -5]), "nsec must be 0 to 999999999"),
])
def test_a_malformed_tick_is_refused_naming_the_fault(bottle, named):
    with pytest.raises(RemoteProtocolError, match=named):
        decode_tick(bottle, "/here/clock:i")


@pytest.mark.parametrize("seconds", [-1.0, float("nan"), float("inf"), MAX_SECONDS + 1.0])
def test_a_time_no_tick_can_hold_is_the_callers_mistake(seconds):
    with pytest.raises(LocalProtocolError, match="a clock tick holds"):
        encode_tick(seconds)


@given(st.floats(min_value=0, max_value=MAX_SECONDS - 1, allow_nan=False))
def test_any_time_survives_the_wire_to_the_nanosecond(seconds):
    wire = codec.decode(codec.encode(encode_tick(seconds)))
    assert abs(decode_tick(wire).seconds - seconds) <= max(1e-9, seconds * 1e-15) + 1e-9


@FUZZ
@given(bottles)
def test_any_bottle_gives_a_tick_or_a_peer_error(bottle):
    try:
        tick = decode_tick(bottle)
    except RemoteProtocolError:
        return
    assert 0 <= tick.nsec < 1_000_000_000 and tick.sec >= 0


@FUZZ
@given(st.binary(max_size=40))
def test_any_bytes_give_a_tick_or_a_peer_error(data):
    try:
        bottle = codec.decode(data)
    except RemoteProtocolError:
        return
    try:
        tick = decode_tick(bottle)
    except RemoteProtocolError:
        return
    assert 0 <= tick.nsec < 1_000_000_000 and tick.sec >= 0
