"""udp framing: checksums, numbering, and losing exactly one message per lost datagram."""

from __future__ import annotations

import struct
import zlib

from hypothesis import given
from hypothesis import strategies as st

from codec_helpers import FUZZ
from yarp_lite.carriers.datagram import (MAX_DATAGRAM, DatagramAssembler, pack_message,
                                         unpack_datagram)


def test_prefix_is_crc32_and_number():
    datagram = pack_message([b"hello"])[0]
    crc, number = struct.unpack_from("<ii", datagram)
    assert number == 0 and crc == struct.unpack("<i", struct.pack("<I", zlib.crc32(b"hello")))[0]


def test_large_message_is_split_at_yarps_limit():
    data = bytes(range(256)) * 1000
    datagrams = pack_message([data])
    assert all(len(d) <= MAX_DATAGRAM for d in datagrams)
    assert [unpack_datagram(d)[0] for d in datagrams] == list(range(len(datagrams)))
    assert b"".join(unpack_datagram(d)[1] for d in datagrams) == data


def _assemble(datagrams):
    assembler, stream, restarts = DatagramAssembler(), [], 0
    for datagram in datagrams:
        body, restart = assembler.accept(datagram)
        if restart:
            stream.clear()
            restarts += 1
        if body is not None:
            stream.append(body)
    return b"".join(stream), restarts, assembler.dropped


def test_in_order_datagrams_reassemble():
    data = b"x" * 200000
    assert _assemble(pack_message([data]))[0] == data


def test_a_lost_datagram_drops_the_partial_message_and_the_next_one_survives():
    first = pack_message([b"a" * 150000])
    second = pack_message([b"b" * 100])
    stream, restarts, dropped = _assemble([first[0], first[2], *second])
    assert stream == b"b" * 100 and restarts >= 1


def test_corrupted_and_wake_up_datagrams_are_ignored():
    good = pack_message([b"payload"])[0]
    corrupt = good[:-1] + bytes([good[-1] ^ 0xFF])
    wake = struct.pack("<ii", 0, -1)
    assembler = DatagramAssembler()
    assert assembler.accept(corrupt)[0] is None and assembler.dropped == 1
    assert assembler.accept(wake) == (None, False)
    assert assembler.accept(b"short") == (None, False)
    assert assembler.accept(good)[0] == b"payload"


@FUZZ
@given(st.lists(st.binary(max_size=64), max_size=20))
def test_assembler_never_raises(datagrams):
    _assemble(datagrams)
