"""The TCP channel's frames: pure functions and an incremental decoder over bytes.

Theory of operation
-------------------
Everything one side has to say during a period T travels in one frame::

    frame  := varint(len(body)) body crc16(body)[2, big endian]
    body   := flags [varint ack] [varint seq] entry*
    entry  := id head [varint length] payload
    head   := kind << 5 | DELTA << 4 | length (0..14; 15 = a varint length follows)

``id`` is the 8-bit id from the configuration -- the only header a message
keeps -- and ``kind`` which of that module's flows it is (switch, command,
status, warning...).  A status of a few bytes therefore costs 2 bytes of
framing, where YARP spends 30 and ROS more.

Reliable entries (pilot commands, warnings) are numbered: ``seq`` is the number
of the first reliable entry in the frame, the others follow in order.
``ack`` tells the peer the highest number accepted so far, so it can forget
what it journalled.  A connection opens with a HELLO from each side (protocol
version, side, a fingerprint of the configuration, the journal's session) and
a RESUME (the highest number already accepted from that session): the sender
resends everything after it, so nothing is lost or repeated across reconnects.

The CRC catches what TCP does not (a confused peer, a corrupting middlebox); a
frame that fails it, or any other check, raises :class:`BridgeProtocolError`
and the connection is dropped -- reconnecting is cheap and loses nothing.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field
from enum import IntFlag
from typing import List, Optional, Tuple, Union

from bridge.errors import BridgeProtocolError, BridgeUsageError, NeedMoreData
from bridge.wire import Buffer, crc16, get_varint, put_varint, take

PROTOCOL_VERSION = 1
DEFAULT_MAX_FRAME = 4 << 20
MAX_KIND = 7
_CRC = struct.Struct(">H")


class Flags(IntFlag):
    ACK = 0x01
    SEQ = 0x02
    HELLO = 0x04
    RESUME = 0x08


_KNOWN_FLAGS = int(Flags.ACK | Flags.SEQ | Flags.HELLO | Flags.RESUME)


@dataclass(frozen=True)
class Entry:
    id: int
    kind: int
    payload: bytes
    delta: bool = False


@dataclass(frozen=True)
class DataFrame:
    entries: Tuple[Entry, ...] = ()
    ack: Optional[int] = None
    seq: Optional[int] = None


@dataclass(frozen=True)
class Hello:
    side: str             # "robot" or "pilot"
    fingerprint: bytes    # 8 bytes: both sides must run the same configuration
    session: int          # 64-bit id of the sender's journal
    version: int = PROTOCOL_VERSION


@dataclass(frozen=True)
class Resume:
    accepted: int         # highest reliable number already accepted from the peer's session


Frame = Union[DataFrame, Hello, Resume]
_SIDES = {"robot": 0x72, "pilot": 0x70}
_SIDE_NAMES = {code: name for name, code in _SIDES.items()}


def _wrap(body: bytes) -> bytes:
    out = bytearray()
    put_varint(out, len(body))
    out += body
    out += _CRC.pack(crc16(body))
    return bytes(out)


def entry_bytes(entry: Entry) -> bytes:
    """One entry's encoding (so a sender can measure it before committing)."""
    if not 0 <= entry.id <= 255 or not 0 <= entry.kind <= MAX_KIND:
        raise BridgeUsageError(f"entry id {entry.id} kind {entry.kind} out of range")
    length = len(entry.payload)
    head = entry.kind << 5 | (0x10 if entry.delta else 0) | min(length, 15)
    out = bytearray((entry.id, head))
    if length >= 15:
        put_varint(out, length)
    out += entry.payload
    return bytes(out)


def encode_data(entries: Tuple[Entry, ...] = (), ack: Optional[int] = None,
                seq: Optional[int] = None, encoded: Optional[List[bytes]] = None) -> bytes:
    """A data frame; ``encoded`` may hold the entries already through :func:`entry_bytes`."""
    flags = (Flags.ACK if ack is not None else 0) | (Flags.SEQ if seq is not None else 0)
    body = bytearray((flags,))
    if ack is not None:
        put_varint(body, ack)
    if seq is not None:
        put_varint(body, seq)
    for chunk in encoded if encoded is not None else (entry_bytes(e) for e in entries):
        body += chunk
    return _wrap(bytes(body))


def encode_hello(hello: Hello) -> bytes:
    if len(hello.fingerprint) != 8:
        raise BridgeUsageError("a configuration fingerprint is 8 bytes")
    body = bytes((Flags.HELLO, hello.version, _SIDES[hello.side])) + hello.fingerprint + \
        struct.pack(">Q", hello.session)
    return _wrap(body)


def encode_resume(resume: Resume) -> bytes:
    body = bytearray((Flags.RESUME,))
    put_varint(body, resume.accepted)
    return _wrap(bytes(body))


def _parse_body(body: bytes) -> Frame:
    if not body:
        raise BridgeProtocolError("empty frame")
    flags = body[0]
    if flags & ~_KNOWN_FLAGS:
        raise BridgeProtocolError(f"frame flags {flags:#04x} have unknown bits")
    if flags & Flags.HELLO:
        if flags != Flags.HELLO or len(body) != 19:
            raise BridgeProtocolError(f"malformed HELLO ({len(body)} bytes, flags {flags:#x})")
        side = _SIDE_NAMES.get(body[2])
        if side is None:
            raise BridgeProtocolError(f"HELLO names an unknown side {body[2]:#x}")
        return Hello(side, body[3:11], struct.unpack(">Q", body[11:19])[0], body[1])
    pos = 1
    try:
        if flags & Flags.RESUME:
            if flags != Flags.RESUME:
                raise BridgeProtocolError(f"RESUME with other flags {flags:#x}")
            accepted, pos = get_varint(body, pos, "accepted")
            if pos != len(body):
                raise BridgeProtocolError("bytes after RESUME")
            return Resume(accepted)
        ack = seq = None
        if flags & Flags.ACK:
            ack, pos = get_varint(body, pos, "ack")
        if flags & Flags.SEQ:
            seq, pos = get_varint(body, pos, "seq")
        entries = []
        while pos < len(body):
            if pos + 2 > len(body):
                raise BridgeProtocolError(f"entry header cut at byte {pos}")
            ident, head = body[pos], body[pos + 1]
            pos += 2
            length = head & 0x0F
            if length == 15:
                length, pos = get_varint(body, pos, "entry length")
                if length < 15:
                    raise BridgeProtocolError(f"entry length {length} needlessly escaped")
            payload, pos = take(body, pos, length, f"entry {ident}")
            entries.append(Entry(ident, head >> 5, payload, bool(head & 0x10)))
    except NeedMoreData as exc:
        raise BridgeProtocolError(f"frame truncated inside: {exc}") from None
    return DataFrame(tuple(entries), ack, seq)


def decode(frame: Buffer) -> Frame:
    """Decode exactly one whole frame."""
    decoder = FrameDecoder()
    frames = decoder.feed(frame)
    if len(frames) != 1 or decoder.pending:
        raise BridgeProtocolError(f"expected one frame, got {len(frames)} and "
                                  f"{decoder.pending} extra bytes")
    return frames[0]


@dataclass
class FrameDecoder:
    """Feed bytes as they arrive; get whole frames.  Never half-consumes a frame."""

    max_frame: int = DEFAULT_MAX_FRAME
    _buffer: bytearray = field(default_factory=bytearray)

    @property
    def pending(self) -> int:
        return len(self._buffer)

    def feed(self, data: Buffer) -> List[Frame]:
        self._buffer += data
        frames: List[Frame] = []
        while True:
            frame = self._next()
            if frame is None:
                return frames
            frames.append(frame)

    def _next(self) -> Optional[Frame]:
        buf = self._buffer
        try:
            length, pos = get_varint(buf, 0, "frame length")
        except NeedMoreData:
            return None
        if length > self.max_frame:
            raise BridgeProtocolError(f"declared frame length {length} exceeds the "
                                      f"{self.max_frame}-byte limit")
        if len(buf) < pos + length + 2:
            return None
        body = bytes(buf[pos:pos + length])
        (expected,) = _CRC.unpack_from(buf, pos + length)
        del buf[:pos + length + 2]
        if crc16(body) != expected:
            raise BridgeProtocolError(f"frame of {length} bytes fails its CRC")
        return _parse_body(body)
