"""The UDP channel's datagrams: one part of one message, self-describing.

Theory of operation
-------------------
A message on a UDP channel (an image, a point cloud, a Bottle, a robot state)
is cut into ``parts`` datagrams of at most :data:`MAX_DATAGRAM` bytes, the UDP
payload of a 1500-byte Ethernet frame, so IP never fragments them::

    datagram := 0xB7 id flags varint(message) varint(parts) varint(group)
                varint(index) [varint(row) if REPAIR] body
    flags    := kind (bits 0-2) | REPAIR (bit 3)

``message`` numbers the messages of one channel, in order: the receiver
rebuilds by it and drops replays and stragglers.  Data parts are numbered
``index`` 0..parts-1; with forward error correction every ``group`` data parts
are followed by repair datagrams (``index`` = the group, ``row`` = the repair
row, see :mod:`bridge.wire.fec`).  What a data body holds depends on the channel:
a standalone tile (:mod:`bridge.wire.tiles`) or a plain slice of the message.

The receiving side answers with reports (:class:`Report`, for
:mod:`bridge.transport.adaptive_fec`): how many data datagrams it expected and received
so far, totals that only grow::

    report   := 0xB8 varint(expected) varint(received)

On the wire every datagram is sealed by the link (:mod:`bridge.wire.link`: a
counter and an authentication tag, which also catch corrupted bytes), so the
budget for a body leaves room for the seal.
"""

from __future__ import annotations

from dataclasses import dataclass

from bridge.errors import BridgeProtocolError, BridgeUsageError, NeedMoreData
from bridge.wire.link import SEAL_OVERHEAD
from bridge.wire.varint import Buffer, get_varint, put_varint

MAGIC = 0xB7
REPORT_MAGIC = 0xB8
MAX_DATAGRAM = 1472           # 1500 - 20 (IPv4) - 8 (UDP)
REPAIR = 0x08
#: Room left for a body after the largest header and the link's seal.
MAX_HEADER = 3 + 5 + 3 + 2 + 3 + 2
MAX_INNER = MAX_DATAGRAM - SEAL_OVERHEAD
BODY_BUDGET = MAX_INNER - MAX_HEADER


@dataclass(frozen=True)
class Datagram:
    id: int
    kind: int
    message: int
    parts: int
    group: int
    index: int
    body: bytes
    repair_row: int = -1      # >= 0 for a repair datagram

    @property
    def is_repair(self) -> bool:
        return self.repair_row >= 0


def encode(datagram: Datagram) -> bytes:
    if not 0 <= datagram.id <= 255 or not 0 <= datagram.kind <= 7:
        raise BridgeUsageError(f"datagram id {datagram.id} kind {datagram.kind} out of range")
    out = bytearray((MAGIC, datagram.id, datagram.kind | (REPAIR if datagram.is_repair else 0)))
    put_varint(out, datagram.message)
    put_varint(out, datagram.parts)
    put_varint(out, datagram.group)
    put_varint(out, datagram.index)
    if datagram.is_repair:
        put_varint(out, datagram.repair_row)
    out += datagram.body
    if len(out) > MAX_INNER:
        raise BridgeUsageError(f"datagram of {len(out)} bytes exceeds {MAX_INNER} (the link's "
                               f"seal takes the rest of {MAX_DATAGRAM})")
    return bytes(out)


def decode(data: Buffer) -> Datagram:
    """One datagram, or :class:`BridgeProtocolError` naming what is wrong with it."""
    if len(data) < 7:
        raise BridgeProtocolError(f"datagram of {len(data)} bytes is too short")
    if len(data) > MAX_INNER:
        raise BridgeProtocolError(f"datagram of {len(data)} bytes exceeds {MAX_INNER}")
    if data[0] != MAGIC:
        raise BridgeProtocolError(f"datagram starts with {data[0]:#04x}, not {MAGIC:#04x}")
    flags = data[2]
    if flags & ~(0x07 | REPAIR):
        raise BridgeProtocolError(f"datagram flags {flags:#04x} have unknown bits")
    view = bytes(data)
    try:
        message, pos = get_varint(view, 3, "message")
        parts, pos = get_varint(view, pos, "parts")
        group, pos = get_varint(view, pos, "group")
        index, pos = get_varint(view, pos, "index")
        row = -1
        if flags & REPAIR:
            row, pos = get_varint(view, pos, "repair row")
    except NeedMoreData as exc:
        raise BridgeProtocolError(f"datagram header truncated: {exc}") from None
    if parts == 0 or parts > 65535:
        raise BridgeProtocolError(f"datagram claims {parts} parts")
    if group == 0 or group > 127:
        raise BridgeProtocolError(f"FEC group of {group}")
    if flags & REPAIR:
        if index * group >= parts or row > 127:
            raise BridgeProtocolError(f"repair row {row} of group {index} does not exist")
    elif index >= parts:
        raise BridgeProtocolError(f"part {index} of a {parts}-part message")
    return Datagram(data[1], flags & 0x07, message, parts, group, index, view[pos:], row)


@dataclass(frozen=True)
class Report:
    """The receiver's totals of data datagrams: those it expected, those that arrived."""

    received: int
    expected: int


def is_report(data: Buffer) -> bool:
    return len(data) > 0 and data[0] == REPORT_MAGIC


def encode_report(report: Report) -> bytes:
    if not 0 <= report.received <= report.expected:
        raise BridgeUsageError(f"report of {report.received} received of {report.expected}")
    out = bytearray((REPORT_MAGIC,))
    put_varint(out, report.expected)
    put_varint(out, report.received)
    return bytes(out)


def decode_report(data: Buffer) -> Report:
    """One report, or :class:`BridgeProtocolError` naming what is wrong with it."""
    view = bytes(data)
    if not view or view[0] != REPORT_MAGIC:
        raise BridgeProtocolError(f"report starts with {view[:1].hex() or 'nothing'}, "
                                  f"not {REPORT_MAGIC:#04x}")
    try:
        expected, pos = get_varint(view, 1, "expected")
        received, pos = get_varint(view, pos, "received")
    except NeedMoreData as exc:
        raise BridgeProtocolError(f"report truncated: {exc}") from None
    if pos != len(view):
        raise BridgeProtocolError(f"report has {len(view) - pos} bytes after its totals")
    if received > expected:
        raise BridgeProtocolError(f"report says {received} received of {expected} expected")
    return Report(received=received, expected=expected)
