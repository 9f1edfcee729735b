"""Connection-protocol codec: index, port commands, acks, and the message decoder."""

from __future__ import annotations

import struct

import pytest
from hypothesis import given
from hypothesis import strategies as st

from codec_helpers import FUZZ, feed_one_byte_at_a_time
from yarp_lite.bottle import Bottle, decode, encode
from yarp_lite.carriers import carrier_for_header
from yarp_lite.errors import RemoteProtocolError
from yarp_lite.framing import (ACK, DATA_NO_REPLY, MessageDecoder, encode_index,
                               encode_message, encode_port_command, encode_sender_name,
                               parse_payload, parse_yarp_number, yarp_number)

# Bytes captured from real YARP 3.5 (yarp write /w -> yarp read /r).
REAL_HEADER = b"YA\xe4\x1e\x00\x00RP\x03\x00\x00\x00/w\x00"
REAL_INDEX_123 = (b"YA\n\x00\x00\x00RP\x02\x01\xff\xff\xff\xff\xff\xff\xff\xff"
                  b"\x08\x00\x00\x00\x14\x00\x00\x00\x00\x00\x00\x00")
REAL_QUIT = (b"YA\n\x00\x00\x00RP\x01\x01\xff\xff\xff\xff\xff\xff\xff\xff\n\x00\x00\x00"
             b"\x00\x00\x00\x00\x02\x00\x00\x00~\x00\x00\x01q\x00")


def test_header_and_sender_name_match_real_yarp():
    assert carrier_for_header(REAL_HEADER[:8]).name == "tcp"
    assert REAL_HEADER == carrier_for_header(REAL_HEADER[:8]).header + encode_sender_name("/w")


def test_index_matches_real_yarp():
    payload = encode(Bottle([1, 2, 3]))
    message = b"".join(encode_message("D", [payload]))
    assert message.startswith(REAL_INDEX_123)
    assert message[len(REAL_INDEX_123):] == DATA_NO_REPLY + payload


def test_quit_command_matches_real_yarp():
    assert b"".join(encode_message("q")) == REAL_QUIT


@pytest.mark.parametrize("header, name", [
    (yarp_number(7777 + 3 + 128), "tcp"), (yarp_number(7777 + 3), "fast_tcp"),
    (yarp_number(7777), "udp"), (yarp_number(7777 + 128), "udp"), (b"CONNECT ", "text"),
    (b"CONNACK ", "text_ack"), (b"NAME_SER", "name_ser"),
])
def test_carrier_headers(header, name):
    assert carrier_for_header(header).name == name


@pytest.mark.parametrize("header", [b"GET / HT", yarp_number(7777 + 2), b"\0" * 8,
                                    yarp_number(12)])
def test_unknown_headers(header):
    assert carrier_for_header(header) is None


def test_yarp_numbers():
    assert parse_yarp_number(yarp_number(-5)) == -5
    assert parse_yarp_number(b"XA\0\0\0\0RP") is None


def test_payload_commands():
    assert parse_payload(DATA_NO_REPLY + b"x").command == "D"
    message = parse_payload(encode_port_command("/read")[0:] + b"")
    assert (message.command, message.text) == ("/", "/read")
    with_envelope = parse_payload(encode_port_command("d stamp 12") + b"data")
    assert with_envelope.command == "d" and with_envelope.envelope == "stamp 12"
    assert bytes(with_envelope.payload) == b"data" and with_envelope.wants_reply


@pytest.mark.parametrize("payload, problem", [
    (b"\0\0\0", "no port command"), (b"\0\0\0\0xd\0\x01", "lacks '~'"),
    (b"\x05\0\0\0~\0\0\x01abc", "not NUL-terminated"),
])
def test_bad_payloads(payload, problem):
    with pytest.raises(RemoteProtocolError, match=problem):
        parse_payload(payload)


def _stream_of_messages(count: int = 3) -> bytes:
    chunks = []
    for index in range(count):
        chunks += encode_message("d" if index % 2 else "D", [encode(Bottle([index, "x" * index]))])
    chunks += encode_message("*")
    return b"".join(chunks)


def test_decoder_byte_by_byte_equals_all_at_once():
    data = _stream_of_messages()
    whole = MessageDecoder()
    whole.feed(data)
    expected = []
    while (message := whole.next_message()) is not None:
        expected.append(message)
    trickled = feed_one_byte_at_a_time(MessageDecoder(), data, lambda d: d.next_message())
    assert [(m.command, m.text, bytes(m.payload)) for m in trickled] == \
        [(m.command, m.text, bytes(m.payload)) for m in expected]
    assert [decode(m.payload) for m in expected[:3]] == [[0, ""], [1, "x"], [2, "xx"]]
    assert expected[3].command == "*"


def test_decoder_payload_window_receives_in_place():
    payload = encode(Bottle([b"\x07" * 100000]))
    data = b"".join(encode_message("D", [payload]))
    decoder = MessageDecoder()
    decoder.feed(data[:100])
    assert decoder.next_message() is None
    window = decoder.payload_window()
    rest = data[100:]
    window[:len(rest)] = rest
    decoder.commit(len(rest))
    message = decoder.next_message()
    assert decode(message.payload)[0] == b"\x07" * 100000


@pytest.mark.parametrize("data, problem", [
    (b"XX" + b"\0" * 30, "index header: expected a YA..RP number"),
    (yarp_number(11) + b"\0" * 30, "announces 11 bytes"),
    (yarp_number(10) + bytes([1, 1]) + b"\xff" * 8 + struct.pack("<ii", -4, 0), "negative block"),
    (yarp_number(10) + bytes([1, 1]) + b"\xff" * 8 + struct.pack("<ii", 0x7FFFFFFF, 0),
     "exceeds"),
])
def test_decoder_rejects_bad_indexes(data, problem):
    decoder = MessageDecoder(max_message=1 << 20)
    decoder.feed(data)
    with pytest.raises(RemoteProtocolError, match=problem):
        decoder.next_message()


@FUZZ
@given(st.binary(max_size=300))
def test_decoder_fuzz_parses_or_raises_peer_error(data):
    decoder = MessageDecoder(max_message=1 << 16)
    decoder.feed(data)
    try:
        while decoder.next_message() is not None:
            pass
    except RemoteProtocolError:
        pass


def test_ack_is_a_zero_length_yarp_number():
    assert ACK == b"YA\0\0\0\0RP"


def test_index_refuses_too_many_blocks():
    with pytest.raises(ValueError):
        encode_index([1] * 256)


def test_sender_name_length_is_clamped_and_needs_its_four_bytes():
    from yarp_lite.errors import NeedMoreData
    from yarp_lite.framing import MAX_SENDER_NAME, sender_name_length

    assert sender_name_length(REAL_HEADER[8:12]) == 3
    assert sender_name_length(struct.pack("<i", -5)) == 1
    assert sender_name_length(struct.pack("<i", 1 << 30)) == MAX_SENDER_NAME
    with pytest.raises(NeedMoreData):
        sender_name_length(b"\x03\x00")  # struct.error before


def test_an_index_alone_cannot_make_the_decoder_allocate_what_it_announces():
    import tracemalloc

    from yarp_lite.framing import INITIAL_PAYLOAD, encode_index

    decoder = MessageDecoder(max_message=256 << 20)
    tracemalloc.start()
    try:
        decoder.feed(encode_index([8, 200 << 20]) + b"\0\0\0\0~D\0\x01" + b"x" * 10)
        assert decoder.next_message() is None
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 2 * INITIAL_PAYLOAD


def test_a_payload_received_through_growing_windows_is_whole():
    from yarp_lite.framing import INITIAL_PAYLOAD, encode_message

    data = bytes(range(256)) * ((3 * INITIAL_PAYLOAD) // 256 + 7)
    wire = b"".join(bytes(chunk) for chunk in encode_message("D", [data]))
    decoder = MessageDecoder()
    decoder.feed(wire[:100])
    assert decoder.next_message() is None
    pos, message = 100, None
    while message is None:
        window = decoder.payload_window()
        assert window is not None and len(window) <= len(data)
        with window:
            count = min(len(window), len(wire) - pos, 700_000)
            window[:count] = wire[pos:pos + count]
            decoder.commit(count)
        pos += count
        decoder.feed(b"")  # a feed between windows must not trip over a released view
        message = decoder.next_message()
    assert pos == len(wire) and bytes(message.payload) == data
