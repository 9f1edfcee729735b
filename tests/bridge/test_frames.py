"""TCP frames: bodies round trip, the splitter never half-consumes, bad bodies are named."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from bridge.errors import BridgeProtocolError, BridgeUsageError
from bridge.flows import FlowKey
from bridge.wire import frames
from bridge.wire.frames import Auth, DataFrame, Entry, FrameSplitter, Hello, Resume
from codec_helpers import FUZZ

entries = st.builds(Entry, st.integers(0, 255), st.integers(0, 7), st.binary(max_size=300),
                    st.booleans())
presences = st.none() | st.frozensets(st.builds(FlowKey, st.integers(0, 255), st.integers(0, 7)),
                                       max_size=20)
data_frames = st.builds(DataFrame, st.lists(entries, max_size=6).map(tuple),
                        st.none() | st.integers(0, 2 ** 40), st.none() | st.integers(0, 2 ** 40),
                        presences)
hellos = st.builds(Hello, st.sampled_from(["robot", "pilot"]), st.binary(min_size=8, max_size=8),
                   st.integers(0, 2 ** 64 - 1), st.binary(min_size=16, max_size=16),
                   st.booleans())
any_frame = data_frames | hellos | st.builds(Resume, st.integers(0, 2 ** 40)) | \
    st.builds(Auth, st.binary(min_size=16, max_size=16))


@FUZZ
@given(st.lists(st.tuples(any_frame, st.binary(max_size=8)), min_size=1, max_size=4))
def test_frames_round_trip_whole_and_one_byte_at_a_time(sequence):
    wire = b"".join(frames.wrap(frames.body_of(f), trailer) for f, trailer in sequence)
    for chunk in (len(wire), 1):
        splitter = FrameSplitter()
        got, expected = [], list(sequence)
        for start in range(0, len(wire), chunk):
            splitter.feed(wire[start:start + chunk])
            while expected:
                record = splitter.next_record(len(expected[0][1]))
                if record is None:
                    break
                body, trailer = record
                got.append((frames.parse_body(body), trailer))
                expected.pop(0)
        assert got == sequence and splitter.pending == 0


def test_a_status_entry_costs_two_bytes_of_framing():
    entry = Entry(7, 2, b"\x02\x00\x18\x09\x01a")
    assert len(frames.entry_bytes(entry)) == 2 + len(entry.payload)
    assert len(frames.wrap(frames.data_body((entry,)))) == 1 + 1 + 8  # length, flags, entry


def test_long_payloads_use_an_escaped_length():
    entry = Entry(1, 0, bytes(300))
    assert frames.parse_body(frames.data_body((entry,))) == DataFrame((entry,))


@FUZZ
@given(st.binary(max_size=100))
def test_garbage_bodies_parse_or_raise_the_peer_error(data):
    try:
        frames.parse_body(data)
    except BridgeProtocolError:
        pass


def test_a_huge_declared_length_is_refused_without_waiting():
    splitter = FrameSplitter(max_frame=1 << 20)
    splitter.feed(b"\xff\xff\xff\xff\x0f")
    with pytest.raises(BridgeProtocolError, match="exceeds"):
        splitter.next_record(8)
    handshake = FrameSplitter()
    handshake.feed(b"\x7f")
    with pytest.raises(BridgeProtocolError, match="64-byte limit"):
        handshake.next_record(0, frames.MAX_HANDSHAKE_FRAME)


def test_unknown_flags_and_malformed_handshake_frames_are_refused():
    with pytest.raises(BridgeProtocolError, match="unknown bits"):
        frames.parse_body(b"\x80")
    with pytest.raises(BridgeProtocolError, match="malformed HELLO"):
        frames.parse_body(b"\x04\x04r")
    with pytest.raises(BridgeProtocolError, match="protocol 1, we speak 4"):
        frames.parse_body(b"\x04\x01r" + bytes(16))
    good = frames.hello_body(Hello("robot", bytes(8), 1, bytes(16)))
    with pytest.raises(BridgeProtocolError, match="unknown side"):
        frames.parse_body(good[:2] + b"x" + good[3:])
    with pytest.raises(BridgeProtocolError, match="key flag"):
        frames.parse_body(good[:-1] + b"\x07")
    with pytest.raises(BridgeProtocolError, match="malformed AUTH"):
        frames.parse_body(b"\x10" + bytes(3))


def test_presence_costs_two_bytes_a_module_and_an_empty_one_is_said():
    present = frozenset({FlowKey(7, 0), FlowKey(7, 1), FlowKey(7, 2), FlowKey(7, 3),
                         FlowKey(2, 2)})
    body = frames.data_body(presence=present)
    assert body == bytes((0x20, 2, 2, 0b100, 7, 0b1111))
    assert frames.parse_body(body) == DataFrame(presence=present)
    assert frames.parse_body(frames.data_body(presence=frozenset())) == \
        DataFrame(presence=frozenset())
    assert frames.parse_body(frames.data_body()).presence is None


@pytest.mark.parametrize("body, problem", [
    (bytes((0x20, 2, 7, 1, 2, 1)), "not increasing at id 2"),
    (bytes((0x20, 2, 7, 1, 7, 1)), "not increasing at id 7"),
    (bytes((0x20, 1, 7, 0)), "id 7 with no kind"),
    (bytes((0x20, 0x81, 0x02)), "lists 257 modules"),
    (bytes((0x20, 2, 7, 1)), "truncated inside: presence entry"),
])
def test_a_malformed_presence_is_named(body, problem):
    with pytest.raises(BridgeProtocolError, match=problem):
        frames.parse_body(body)


def test_entry_cut_inside_is_named():
    with pytest.raises(BridgeProtocolError, match="truncated inside|cut"):
        frames.parse_body(b"\x00\x07\x05ab")


def test_local_misuse_is_a_usage_error():
    with pytest.raises(BridgeUsageError):
        frames.entry_bytes(Entry(256, 0, b""))
    with pytest.raises(BridgeUsageError):
        frames.hello_body(Hello("robot", b"short", 1))
    with pytest.raises(BridgeUsageError):
        frames.presence_bytes(frozenset({FlowKey(3, 8)}))
    with pytest.raises(BridgeUsageError):
        frames.auth_body(Auth(b"short"))
