"""Binary Bottle codec: YARP's exact bytes, every tag, truncation and fuzzing."""

from __future__ import annotations

import math
import struct
import time

import pytest
from hypothesis import given
from hypothesis import strategies as st

from codec_helpers import FUZZ, bottles
from yarp_lite.bottle import (Bottle, Dict, Float32, Int8, Int16, Int64, Tag, Vocab, decode,
                              decode_prefix, encode, tag_of, vocab_decode, vocab_encode)
from yarp_lite.errors import LocalProtocolError, NeedMoreData, RemoteProtocolError

# Captured from real YARP 3.5 (`yarp write` of "1 2 3" and of
# 'hello "a b" 3.5 (x y) [vo] {1 2}').
REAL_123 = bytes.fromhex("0101000003000000010000000200000003000000")
REAL_MIXED = bytes.fromhex(
    "0001000006000000040000000500000068656c6c6f04000000030000006120620a0000000000000000"
    "000c4004010000020000000100000078010000007909000000766f00000c000000020000000102")


def test_typed_int_list_matches_real_yarp():
    assert encode(Bottle([1, 2, 3])) == REAL_123


def test_mixed_list_matches_real_yarp():
    bottle = Bottle(["hello", "a b", 3.5, Bottle(["x", "y"]), Vocab("vo"), b"\x01\x02"])
    assert encode(bottle) == REAL_MIXED


def test_decoding_real_yarp_bytes_keeps_types():
    bottle = decode(REAL_MIXED)
    assert bottle == ["hello", "a b", 3.5, ["x", "y"], "vo", b"\x01\x02"]
    assert isinstance(bottle[4], Vocab) and bottle[4].code == vocab_encode("vo")
    assert encode(bottle) == REAL_MIXED


@pytest.mark.parametrize("value, tag", [
    (Int8(-5), Tag.INT8), (Int16(300), Tag.INT16), (7, Tag.INT32), (Int64(7), Tag.INT64),
    (1 << 40, Tag.INT64), (Float32(0.5), Tag.FLOAT32), (0.5, Tag.FLOAT64),
    (Vocab("ok"), Tag.VOCAB32), (True, Tag.VOCAB32), ("s", Tag.STRING), (b"b", Tag.BLOB),
    (bytearray(b"b"), Tag.BLOB), ([1, 2], Tag.LIST + Tag.INT32), (["a", 1], Tag.LIST),
    (Dict.from_mapping({"a": 1}), Tag.LIST | Tag.DICT), ({"a": 1}, Tag.LIST | Tag.DICT),
])
def test_tags_follow_yarp(value, tag):
    assert tag_of(value) == tag


def test_every_type_round_trips_bit_identically():
    bottle = Bottle([Int8(-128), Int16(-32768), -(1 << 31), Int64(1 << 62), Float32(1.5),
                     -0.0, math.inf, Vocab("many"), "héllo\0", b"\x00\xff",
                     Bottle([]), Bottle([Int8(1), Int8(2)]), Bottle([Float32(1), Float32(2)]),
                     Bottle([Vocab("a"), Vocab("b")]), Bottle(["x", "y"]), Bottle([b"1", b""]),
                     Dict.from_mapping({"b": 2, "a": (1, 2)}), Bottle([Bottle([1]), 2.5])])
    data = encode(bottle)
    again = decode(data)
    assert encode(again) == data
    assert isinstance(again[0], Int8) and isinstance(again[3], Int64)
    assert isinstance(again[16], Dict) and again[16].to_mapping() == {"a": [1, 2], "b": 2}


def test_typed_list_layout():
    # A list of three int8 is one tag for the whole list, then raw bytes.
    # Outer list: code 256 (its item is a list), one item tagged 256+INT8,
    # then the count and the raw bytes.
    assert encode(Bottle([Bottle([Int8(1), Int8(2), Int8(3)])])) == struct.pack(
        "<iiii", Tag.LIST, 1, Tag.LIST + Tag.INT8, 3) + bytes([1, 2, 3])


def test_dict_is_a_tagged_full_bottle():
    data = encode(Bottle([Dict.from_mapping({"k": 1})]))
    assert struct.unpack_from("<iii", data) == (Tag.LIST, 1, Tag.LIST | Tag.DICT)
    # ...followed by a complete Bottle with its own list code: ((k 1))
    assert decode(data[12:]) == [["k", 1]]


def test_vocab_text_round_trip_and_yarp_decoding_of_negative_codes():
    assert vocab_decode(vocab_encode("help")) == "help"
    assert vocab_encode("toolong") == vocab_encode("tool")
    # YARP's signed division never prints bytes of a negative code.
    assert vocab_decode(-1) == ""


def test_out_of_range_integers_are_local_errors():
    with pytest.raises(LocalProtocolError):
        Int8(200)
    with pytest.raises(LocalProtocolError):
        encode(Bottle([1 << 70]))
    with pytest.raises(LocalProtocolError):
        encode(Bottle([object()]))


def test_every_strict_prefix_needs_more_data():
    for cut in range(len(REAL_MIXED)):
        with pytest.raises(NeedMoreData):
            decode_prefix(REAL_MIXED[:cut])


def test_whole_buffer_decoding_rejects_truncation_and_garbage():
    with pytest.raises(RemoteProtocolError, match="truncated"):
        decode(REAL_MIXED[:-1])
    with pytest.raises(RemoteProtocolError, match="unexpected bytes after"):
        decode(REAL_MIXED + b"\0")


@pytest.mark.parametrize("data, problem", [
    (struct.pack("<iii", 256, 1, 77), "unknown type tag 77"),
    (struct.pack("<ii", 256, -1), "negative list length"),
    (struct.pack("<iiii", 256, 1, Tag.STRING, -5), "negative length"),
    (struct.pack("<ii", 256 + 33, 2), "typed list of unknown element type"),
    (struct.pack("<ii", 1 << 20, 0), "invalid top-level list code"),
])
def test_malformed_bottles_name_the_problem(data, problem):
    with pytest.raises(RemoteProtocolError, match=problem):
        decode(data)


def test_bogus_lengths_cost_nothing():
    started = time.perf_counter()
    for data in (struct.pack("<iiii", 256, 1, Tag.STRING, 0x7FFFFFFF),
                 struct.pack("<iiii", 256, 1, Tag.BLOB, 0x7FFFFFFF),
                 struct.pack("<ii", 256, 0x7FFFFFFF),
                 struct.pack("<ii", 256 + Tag.FLOAT64, 0x7FFFFFFF)):
        with pytest.raises(RemoteProtocolError, match="truncated"):
            decode(data)
    assert time.perf_counter() - started < 1.0  # no 2 GB allocation happened


def test_deep_nesting_is_refused_not_a_crash():
    data = struct.pack("<ii", 256, 1)
    for _ in range(500):
        data += struct.pack("<ii", 256, 1)
    data += struct.pack("<ii", 256, 0)
    with pytest.raises(RemoteProtocolError, match="nested deeper"):
        decode(data)


# -- property-based -------------------------------------------------------------------



@FUZZ
@given(bottles)
def test_encode_decode_is_the_identity_on_bytes(bottle):
    data = encode(bottle)
    assert encode(decode(data)) == data


@FUZZ
@given(st.binary(max_size=200))
def test_any_input_decodes_or_raises_the_peer_error(data):
    try:
        decode(data)
    except RemoteProtocolError:
        pass


@FUZZ
@given(bottles, st.data())
def test_corrupting_one_byte_never_raises_anything_else(bottle, data):
    raw = bytearray(encode(bottle))
    index = data.draw(st.integers(0, len(raw) - 1))
    raw[index] = data.draw(st.integers(0, 255))
    try:
        decode(bytes(raw))
    except RemoteProtocolError:
        pass


@FUZZ
@given(bottles, st.binary(min_size=0, max_size=70000))
def test_chunked_encoding_equals_plain_encoding(bottle, big):
    from yarp_lite.bottle import encode_chunks

    bottle = Bottle([*bottle, big, Bottle([big, "tail"])])
    chunks = encode_chunks(bottle)
    assert b"".join(bytes(chunk) for chunk in chunks) == encode(bottle)
    if len(big) >= 16384:
        assert any(isinstance(chunk, memoryview) for chunk in chunks)  # not copied
