"""UDP datagrams: round trips, the size limit, and every kind of bad datagram."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from bridge.errors import BridgeProtocolError, BridgeUsageError
from bridge.wire import datagrams
from bridge.wire.datagrams import MAX_DATAGRAM, MAX_INNER, Datagram
from bridge.wire.link import DatagramOpener, DatagramSealer
from codec_helpers import FUZZ


@st.composite
def valid(draw):
    parts = draw(st.integers(1, 5000))
    group = draw(st.integers(1, 32))
    repair = draw(st.booleans())
    index = draw(st.integers(0, (parts - 1) // group)) if repair else \
        draw(st.integers(0, parts - 1))
    return Datagram(draw(st.integers(0, 255)), draw(st.integers(0, 7)),
                    draw(st.integers(0, 2 ** 32 - 1)), parts, group, index,
                    draw(st.binary(max_size=datagrams.BODY_BUDGET)),
                    draw(st.integers(0, 127)) if repair else -1)


KEY = bytes(range(32))


@FUZZ
@given(valid())
def test_round_trip_within_one_ethernet_frame_once_sealed(datagram):
    wire = datagrams.encode(datagram)
    sealer = DatagramSealer(KEY)
    sealer.counter = 2 ** 35 - 1  # the largest counter the seal's budget allows for
    sealed = sealer.seal(wire)
    assert len(sealed) <= MAX_DATAGRAM
    assert datagrams.decode(wire) == datagram


@FUZZ
@given(st.binary(max_size=1600))
def test_any_bytes_decode_to_a_datagram_it_can_write_or_raise_the_peer_error(data):
    try:
        datagram = datagrams.decode(data)
    except BridgeProtocolError:
        return
    assert datagrams.decode(datagrams.encode(datagram)) == datagram
    assert datagram.body == bytes(data)[len(data) - len(datagram.body):]


@pytest.mark.parametrize("data", [b"", b"\x00" * 7, b"\xff" * 40, bytes(range(30))])
def test_plain_garbage_raises_the_peer_error(data):
    with pytest.raises(BridgeProtocolError):
        datagrams.decode(data)


@FUZZ
@given(valid(), st.data())
def test_a_flipped_byte_is_caught_by_the_seal(datagram, data):
    opener = DatagramOpener()
    opener.install(KEY)
    wire = bytearray(DatagramSealer(KEY).seal(datagrams.encode(datagram)))
    index = data.draw(st.integers(0, len(wire) - 1))
    wire[index] ^= data.draw(st.integers(1, 255))
    with pytest.raises(BridgeProtocolError):
        datagrams.decode(opener.open(bytes(wire)))


@pytest.mark.parametrize("datagram, problem", [
    (Datagram(1, 0, 5, 3, 3, 3, b""), "part 3 of a 3-part"),
    (Datagram(1, 0, 5, 3, 3, 1, b"", 0), "does not exist"),
])
def test_inconsistent_headers_are_named(datagram, problem):
    with pytest.raises(BridgeProtocolError, match=problem):
        datagrams.decode(datagrams.encode(datagram))


def test_oversized_input_is_refused_both_ways():
    with pytest.raises(BridgeUsageError, match="seal"):
        datagrams.encode(Datagram(1, 0, 1, 1, 1, 0, bytes(MAX_INNER)))
    with pytest.raises(BridgeProtocolError, match="exceeds"):
        datagrams.decode(bytes([datagrams.MAGIC]) + bytes(MAX_INNER))


# -- loss reports ---------------------------------------------------------------------------


@FUZZ
@given(st.integers(0, 2 ** 63 - 1), st.integers(0, 2 ** 63 - 1))
def test_a_report_round_trips(a, b):
    report = datagrams.Report(received=min(a, b), expected=max(a, b))
    wire = datagrams.encode_report(report)
    assert datagrams.is_report(wire) and not datagrams.is_report(
        datagrams.encode(Datagram(1, 0, 1, 1, 1, 0, b"x")))
    assert datagrams.decode_report(wire) == report
    for cut in range(len(wire)):   # every prefix is refused, none is misread
        with pytest.raises(BridgeProtocolError):
            datagrams.decode_report(wire[:cut])


@FUZZ
@given(st.binary(max_size=40))
def test_report_garbage_raises_the_peer_error(data):
    try:
        report = datagrams.decode_report(bytes([datagrams.REPORT_MAGIC]) + data)
    except BridgeProtocolError:
        return
    assert 0 <= report.received <= report.expected


@pytest.mark.parametrize("wire, problem", [
    (b"\xb8\x05\x06", "6 received of 5 expected"),
    (b"\xb8\x05\x04\x00", "1 bytes after its totals"),
    (b"\xb8\x05", "received truncated"),
    (b"\xb7\x05\x04", "not 0xb8"),
    (b"\xb8" + b"\xff" * 11, "longer than"),
])
def test_bad_reports_are_named(wire, problem):
    with pytest.raises(BridgeProtocolError, match=problem):
        datagrams.decode_report(wire)


def test_a_report_cannot_claim_more_received_than_expected():
    with pytest.raises(BridgeUsageError):
        datagrams.encode_report(datagrams.Report(received=3, expected=2))
