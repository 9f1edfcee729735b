"""UDP datagrams: round trips, the size limit, and every kind of bad datagram."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from bridge import datagrams
from bridge.datagrams import MAX_DATAGRAM, MAX_INNER, Datagram
from bridge.link import DatagramOpener, DatagramSealer
from bridge.errors import BridgeProtocolError, BridgeUsageError
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
def test_garbage_raises_the_peer_error(data):
    try:
        datagrams.decode(data)
    except BridgeProtocolError:
        pass


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
