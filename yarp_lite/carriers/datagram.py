"""YARP's datagram framing for the udp carrier, as pure functions.

Theory of operation
-------------------
A udp connection carries the same index + payload byte stream as tcp, cut
into datagrams (``DgramTwoWayStream``).  Each datagram starts with 8 bytes:
the CRC-32 of the rest (zlib's polynomial, stored as int32) and the
datagram's number within its message (``pct``, from 0).  A message starts in
a fresh datagram and the sender flushes at its end, so datagrams never mix two
messages.  Datagrams are at most 65499 bytes including the 8-byte prefix.

The receiver checks CRC and number; the first bad one makes it drop the
partial message and wait for the next datagram numbered 0, which is what
makes a lost datagram cost exactly one message.  A datagram numbered -1 is
YARP's "wake up" packet and is ignored.

Both functions are total: any datagram is accepted, ignored or counted as
dropped, never an exception, and the assembler holds no bytes itself (the
message decoder behind it bounds the message, see :mod:`yarp_lite.framing`).
"""

from __future__ import annotations

import struct
import zlib
from typing import Iterable, List, Optional, Tuple, Union

Buffer = Union[bytes, bytearray, memoryview]

CRC_SIZE = 8
#: UDP_MAX_DATAGRAM_SIZE in DgramTwoWayStream.cpp: 65507 minus the CRC prefix.
MAX_DATAGRAM = 65507 - CRC_SIZE
WAKE_UP = -1

_PREFIX = struct.Struct("<ii")


def _crc(data: Buffer) -> int:
    value = zlib.crc32(data)
    return value - (1 << 32) if value >= (1 << 31) else value


def pack_message(chunks: Iterable[Buffer], max_datagram: int = MAX_DATAGRAM) -> List[bytes]:
    """Cut one message into numbered, checksummed datagrams."""
    room = max_datagram - CRC_SIZE
    data = b"".join(bytes(chunk) if not isinstance(chunk, bytes) else chunk for chunk in chunks)
    datagrams = []
    for number, start in enumerate(range(0, max(len(data), 1), room)):
        body = data[start:start + room]
        datagrams.append(_PREFIX.pack(_crc(body), number) + body)
    return datagrams


def unpack_datagram(datagram: Buffer) -> Optional[Tuple[int, bytes, bool]]:
    """Return ``(number, body, crc_ok)``, or None if it is too short to carry a prefix."""
    if len(datagram) < CRC_SIZE:
        return None
    crc, number = _PREFIX.unpack_from(datagram, 0)
    body = bytes(datagram[CRC_SIZE:])
    return number, body, crc == _crc(body)


class DatagramAssembler:
    """Turns received datagrams into the byte stream of whole messages.

    :meth:`accept` returns the bytes to append to the current message, or
    None when the datagram must be ignored.  When it returns ``restart=True``
    the caller must discard the partial message first.  Call
    :meth:`message_done` when the message decoder finished a message.
    """

    def __init__(self) -> None:
        self.expected = 0
        self.dropped = 0

    def accept(self, datagram: Buffer) -> Tuple[Optional[bytes], bool]:
        unpacked = unpack_datagram(datagram)
        if unpacked is None:
            self.dropped += 1
            return None, self.expected != 0
        number, body, crc_ok = unpacked
        if number == WAKE_UP:
            return None, False
        if crc_ok and number == self.expected:
            self.expected += 1
            return body, False
        restart = self.expected != 0
        self.dropped += 1
        if crc_ok and number == 0:
            # A new message started: the previous one lost its tail.
            self.expected = 1
            return body, True
        self.expected = 0
        return None, restart

    def message_done(self) -> None:
        self.expected = 0
