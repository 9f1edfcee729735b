"""TCP frames: round trips, byte-by-byte decoding, and every kind of bad frame."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from bridge import frames
from bridge.errors import BridgeProtocolError, BridgeUsageError
from bridge.frames import DataFrame, Entry, FrameDecoder, Hello, Resume
from codec_helpers import FUZZ

entries = st.builds(Entry, st.integers(0, 255), st.integers(0, 7), st.binary(max_size=300),
                    st.booleans())
data_frames = st.builds(DataFrame, st.lists(entries, max_size=6).map(tuple),
                        st.none() | st.integers(0, 2 ** 40), st.none() | st.integers(0, 2 ** 40))
hellos = st.builds(Hello, st.sampled_from(["robot", "pilot"]), st.binary(min_size=8, max_size=8),
                   st.integers(0, 2 ** 64 - 1))


def encode(frame) -> bytes:
    if isinstance(frame, Hello):
        return frames.encode_hello(frame)
    if isinstance(frame, Resume):
        return frames.encode_resume(frame)
    return frames.encode_data(frame.entries, frame.ack, frame.seq)


@FUZZ
@given(st.lists(data_frames | hellos | st.builds(Resume, st.integers(0, 2 ** 40)),
                min_size=1, max_size=4))
def test_frames_round_trip_whole_and_one_byte_at_a_time(sequence):
    wire = b"".join(encode(f) for f in sequence)
    assert FrameDecoder().feed(wire) == sequence
    decoder = FrameDecoder()
    got = []
    for index in range(len(wire)):
        got.extend(decoder.feed(wire[index:index + 1]))
    assert got == sequence and decoder.pending == 0


def test_a_status_entry_costs_two_bytes_of_framing():
    entry = Entry(7, 2, b"\x02\x00\x18\x09\x01a")
    assert len(frames.entry_bytes(entry)) == 2 + len(entry.payload)
    frame = frames.encode_data((entry,))
    assert len(frame) == 1 + 1 + 8 + 2  # length, flags, entry, CRC


def test_long_payloads_use_an_escaped_length():
    entry = Entry(1, 0, bytes(300))
    assert frames.decode(frames.encode_data((entry,))) == DataFrame((entry,))


@FUZZ
@given(st.binary(max_size=100))
def test_garbage_parses_or_raises_the_peer_error(data):
    try:
        FrameDecoder().feed(data)
    except BridgeProtocolError:
        pass


@FUZZ
@given(data_frames, st.data())
def test_any_corrupted_byte_after_the_length_is_caught(frame, data):
    wire = bytearray(encode(frame))
    _, start = frames.get_varint(wire, 0)
    index = data.draw(st.integers(start, len(wire) - 1))
    wire[index] ^= data.draw(st.integers(1, 255))
    with pytest.raises(BridgeProtocolError):
        FrameDecoder().feed(bytes(wire))


def test_a_huge_declared_length_is_refused_without_waiting():
    decoder = FrameDecoder(max_frame=1 << 20)
    with pytest.raises(BridgeProtocolError, match="exceeds"):
        decoder.feed(b"\xff\xff\xff\xff\x0f")


def test_crc_mismatch_is_named():
    wire = bytearray(frames.encode_data((Entry(1, 0, b"abc"),)))
    wire[-1] ^= 1
    with pytest.raises(BridgeProtocolError, match="CRC"):
        FrameDecoder().feed(bytes(wire))


def test_unknown_flags_and_malformed_hello_are_refused():
    body = b"\x40"
    with pytest.raises(BridgeProtocolError, match="unknown bits"):
        frames.decode(frames._wrap(body))
    with pytest.raises(BridgeProtocolError, match="malformed HELLO"):
        frames.decode(frames._wrap(b"\x04\x01r"))
    with pytest.raises(BridgeProtocolError, match="unknown side"):
        frames.decode(frames._wrap(b"\x04\x01x" + bytes(16)))


def test_entry_cut_inside_is_named():
    with pytest.raises(BridgeProtocolError, match="truncated inside|cut"):
        frames.decode(frames._wrap(b"\x00\x07\x05ab"))


def test_local_misuse_is_a_usage_error():
    with pytest.raises(BridgeUsageError):
        frames.entry_bytes(Entry(256, 0, b""))
    with pytest.raises(BridgeUsageError):
        frames.encode_hello(Hello("robot", b"short", 1))
