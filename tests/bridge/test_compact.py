"""The compact Bottle codec: lossless against YARP's own encoding, deltas, bad input."""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from bridge.errors import BridgeProtocolError
from bridge.wire import compact
from codec_helpers import FUZZ, bottles
from yarp_lite.bottle import Bottle, Dict, Float32, Int8, Vocab, encode


def test_a_status_costs_a_few_bytes_instead_of_yarps_25():
    status = Bottle([12, "a"])
    assert len(encode(status)) == 25
    assert len(compact.encode(status)) == 6
    assert encode(compact.decode(compact.encode(status))) == encode(status)


def test_types_survive_exactly():
    bottle = Bottle([Int8(-3), Float32(1.5), Vocab("get"), True, 2 ** 40, b"\x00\xff", -0.0,
                     math.nan, math.inf, 1e300, 0.1, Dict.from_mapping({"a": 1}),
                     Bottle([1.0, 2.0, 3.0]), Bottle([1, 2, 3])])
    again = compact.decode(compact.encode(bottle))
    assert encode(again) == encode(bottle)


def test_float_vectors_shrink_when_exact_in_float32():
    vector = Bottle([0.5 * i for i in range(100)])
    assert len(compact.encode(vector)) < len(encode(vector)) / 2


@FUZZ
@given(bottles)
def test_round_trip_is_byte_identical_on_the_yarp_side(bottle):
    assert encode(compact.decode(compact.encode(bottle))) == encode(bottle)


@FUZZ
@given(bottles, bottles)
def test_deltas_rebuild_the_new_message_exactly(old, new):
    delta = compact.encode_delta(new, old)
    if delta is None:  # the shapes differ: a full message is needed
        assert compact.shape_and_leaves(new)[0] != compact.shape_and_leaves(old)[0]
        return
    assert encode(compact.decode_delta(delta, old)) == encode(new)


def test_a_status_whose_sequence_moved_costs_two_bytes():
    previous = Bottle([12, "a", 0.25])
    delta = compact.encode_delta(Bottle([13, "a", 0.25]), previous)
    assert len(delta) == 2
    assert compact.decode_delta(delta, previous) == Bottle([13, "a", 0.25])


def test_delta_of_a_different_shape_is_refused():
    assert compact.encode_delta(Bottle([1, "a"]), Bottle([1, 2])) is None


@FUZZ
@given(st.binary(max_size=200))
def test_any_input_decodes_or_raises_the_peer_error(data):
    try:
        bottle = compact.decode(data)
    except BridgeProtocolError:
        return
    encode(bottle)  # what the bridge decodes, YARP can carry


@FUZZ
@given(st.binary(max_size=40))
def test_any_delta_applies_or_raises_the_peer_error(data):
    try:
        compact.decode_delta(data, Bottle([1, "a", [2.5, Int8(3)]]))
    except BridgeProtocolError:
        pass


@pytest.mark.parametrize("data, problem", [
    (b"\x05\x00", "exceeds"),                 # five items announced, one byte left
    (b"\x01\x09\x05ab", "truncated"),          # string of 5 bytes, 2 present
    (b"\x01\x00\x01\x00", "after the compact"),  # trailing garbage
    (b"\x01\x0e", "unknown value kind"),
    (b"\x01\x04\xff\xff\xff\xff\x7f", "exceeds 32 bits"),
    (b"\x01\x00\x80\x80\x80\x80\x10", "does not fit in 32 bits"),  # INT32 of 2**31
    (b"\x01\x03\xff\xff\xff\xff\xff\xff\xff\xff\xff\x03", "does not fit in 64 bits"),
])
def test_malformed_input_names_the_problem(data, problem):
    with pytest.raises(BridgeProtocolError, match=problem):
        compact.decode(data)


def test_an_int32_delta_may_not_overflow_int32():
    previous = Bottle([(1 << 31) - 1])
    with pytest.raises(BridgeProtocolError, match="does not fit in 32 bits"):
        compact.decode_delta(b"\x01\x02", previous)  # +1 past the largest int32
    assert compact.decode_delta(b"\x01\x01", previous) == Bottle([(1 << 31) - 2])


def test_deep_nesting_is_refused():
    data = b"\x01\x0b" * 100 + b"\x00"
    with pytest.raises(BridgeProtocolError, match="nested deeper"):
        compact.decode(data)
