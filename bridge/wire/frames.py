"""The TCP channel's frames: pure functions and an incremental splitter over bytes.

Theory of operation
-------------------
Everything one side has to say during a period T travels in one frame::

    frame  := varint(len(body)) body trailer
    body   := flags [varint ack] [varint seq] [presence] [varint clock] entry*   (data)
            | HELLO version side fingerprint[8] session[8] nonce[16] keyed
            | AUTH proof[16]
            | RESUME varint(accepted)
    entry  := id head [varint length] payload
    presence := varint(n) (id kinds)*n        ids increasing; kinds: bit k = kind k
    head   := kind << 5 | DELTA << 4 | length (0..14; 15 = a varint length follows)

``id`` is the 8-bit id from the configuration -- the only header a message
keeps -- and ``kind`` which of that module's flows it is (switch, command,
status, warning...).  A status of a few bytes therefore costs 2 bytes of
framing, where YARP spends 30 and ROS more.

Reliable entries (pilot commands, warnings) are numbered: ``seq`` is the number
of the first reliable entry in the frame, the others follow in order.
``ack`` tells the peer the highest number accepted so far, so it can forget
what it journalled.  ``presence`` (sent on a new connection and when it changes)
lists which flows have the module's end connected on the sender's side, so the
receiver shows a module's stand-in ports only while the module exists
(:mod:`bridge.gym.presence`).  ``clock`` is the sender's monotonic clock in ms (modulo
2**28) when the frame left: the receiver tells from it how late a frame came
(:mod:`bridge.wire.transit`).  A connection opens with HELLO and AUTH from each side and
a RESUME (the highest number already accepted from the peer's journal
session): the sender resends everything after it, so nothing is lost or
repeated across reconnects.

The ``trailer`` is the link's business (:mod:`bridge.wire.link`): none on HELLO and
AUTH, an 8-byte authentication tag on every later frame.  This module only
splits the stream into ``(body, trailer)`` records -- never half-consuming one
-- and encodes and parses bodies; any violation raises
:class:`BridgeProtocolError` naming the field.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field
from enum import IntFlag
from typing import FrozenSet, Iterable, List, Optional, Tuple, Union

from bridge.errors import BridgeProtocolError, BridgeUsageError, NeedMoreData
from bridge.flows import FlowKey
from bridge.wire.varint import Buffer, get_varint, put_varint, take

PROTOCOL_VERSION = 4
DEFAULT_MAX_FRAME = 4 << 20
#: Frames of the handshake are tiny; a bigger one is refused before it is buffered.
MAX_HANDSHAKE_FRAME = 64
MAX_KIND = 7
NONCE_SIZE = 16
PROOF_SIZE = 16
_HELLO = struct.Struct(">BBB8sQ16sB")


class Flags(IntFlag):
    ACK = 0x01
    SEQ = 0x02
    HELLO = 0x04
    RESUME = 0x08
    AUTH = 0x10
    PRESENCE = 0x20
    CLOCK = 0x40


_KNOWN_FLAGS = int(Flags.ACK | Flags.SEQ | Flags.HELLO | Flags.RESUME | Flags.AUTH |
                   Flags.PRESENCE | Flags.CLOCK)
#: The clock field wraps at this (:data:`bridge.wire.transit.MODULUS`).
CLOCK_MODULUS = 1 << 28

#: Which flows are present: ``(id, kind)`` pairs.
Presence = FrozenSet[FlowKey]


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
    presence: Optional[Presence] = None
    #: the sender's monotonic clock, ms modulo :data:`CLOCK_MODULUS`, when it left
    clock: Optional[int] = None


@dataclass(frozen=True)
class Hello:
    side: str             # "robot" or "pilot"
    fingerprint: bytes    # 8 bytes: both sides must run the same configuration
    session: int          # 64-bit id of the sender's journal
    nonce: bytes = bytes(NONCE_SIZE)   # fresh for every connection
    keyed: bool = True    # False: the sender runs without a key (--no-auth)
    version: int = PROTOCOL_VERSION


@dataclass(frozen=True)
class Auth:
    proof: bytes          # 16 bytes: the sender knows the key and saw both HELLOs


@dataclass(frozen=True)
class Resume:
    accepted: int         # highest reliable number already accepted from the peer's session


Frame = Union[DataFrame, Hello, Auth, Resume]
_SIDES = {"robot": 0x72, "pilot": 0x70}
_SIDE_NAMES = {code: name for name, code in _SIDES.items()}


def wrap(body: bytes, trailer: bytes = b"") -> bytes:
    """One frame on the wire: the body's length, the body, the link's trailer."""
    out = bytearray()
    put_varint(out, len(body))
    out += body
    out += trailer
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


def data_body(entries: Iterable[Entry] = (), ack: Optional[int] = None,
              seq: Optional[int] = None, encoded: Optional[List[bytes]] = None,
              presence: Optional[Presence] = None, clock: Optional[int] = None) -> bytes:
    """A data frame's body; ``encoded`` may hold entries already through :func:`entry_bytes`."""
    flags = (Flags.ACK if ack is not None else 0) | (Flags.SEQ if seq is not None else 0) | \
        (Flags.PRESENCE if presence is not None else 0) | \
        (Flags.CLOCK if clock is not None else 0)
    body = bytearray((flags,))
    if ack is not None:
        put_varint(body, ack)
    if seq is not None:
        put_varint(body, seq)
    if presence is not None:
        body += presence_bytes(presence)
    if clock is not None:
        if not 0 <= clock < CLOCK_MODULUS:
            raise BridgeUsageError(f"frame clock {clock} outside 0..{CLOCK_MODULUS - 1}")
        put_varint(body, clock)
    for chunk in encoded if encoded is not None else (entry_bytes(e) for e in entries):
        body += chunk
    return bytes(body)


def presence_bytes(presence: Presence) -> bytes:
    """``varint(n) (id kinds)*n``: one byte of kinds per module present."""
    kinds: dict = {}
    for key in presence:
        ident, kind = key.id, key.kind
        if not 0 <= ident <= 255 or not 0 <= kind <= MAX_KIND:
            raise BridgeUsageError(f"present flow id {ident} kind {kind} out of range")
        kinds[ident] = kinds.get(ident, 0) | 1 << kind
    out = bytearray()
    put_varint(out, len(kinds))
    for ident in sorted(kinds):
        out += bytes((ident, kinds[ident]))
    return bytes(out)


def _parse_presence(body: bytes, pos: int) -> Tuple[Presence, int]:
    count, pos = get_varint(body, pos, "presence count")
    if count > 256:
        raise BridgeProtocolError(f"presence lists {count} modules; ids have 8 bits")
    pairs, previous = [], -1
    for _ in range(count):
        pair, pos = take(body, pos, 2, "presence entry")
        ident, kinds = pair[0], pair[1]
        if ident <= previous:
            raise BridgeProtocolError(f"presence ids not increasing at id {ident}")
        if not kinds:
            raise BridgeProtocolError(f"presence lists id {ident} with no kind")
        previous = ident
        pairs += [FlowKey(ident, kind) for kind in range(MAX_KIND + 1) if kinds >> kind & 1]
    return frozenset(pairs), pos


def hello_body(hello: Hello) -> bytes:
    if len(hello.fingerprint) != 8:
        raise BridgeUsageError("a configuration fingerprint is 8 bytes")
    if len(hello.nonce) != NONCE_SIZE:
        raise BridgeUsageError(f"a HELLO nonce is {NONCE_SIZE} bytes")
    if hello.side not in _SIDES:
        raise BridgeUsageError(f"side must be robot or pilot, not {hello.side!r}")
    return _HELLO.pack(Flags.HELLO, hello.version, _SIDES[hello.side], hello.fingerprint,
                       hello.session, hello.nonce, int(hello.keyed))


def auth_body(auth: Auth) -> bytes:
    if len(auth.proof) != PROOF_SIZE:
        raise BridgeUsageError(f"an AUTH proof is {PROOF_SIZE} bytes")
    return bytes((Flags.AUTH,)) + auth.proof


def resume_body(resume: Resume) -> bytes:
    body = bytearray((Flags.RESUME,))
    put_varint(body, resume.accepted)
    return bytes(body)


def body_of(frame: Frame) -> bytes:
    """The body of any frame (the link adds length and trailer)."""
    if isinstance(frame, Hello):
        return hello_body(frame)
    if isinstance(frame, Auth):
        return auth_body(frame)
    if isinstance(frame, Resume):
        return resume_body(frame)
    return data_body(frame.entries, frame.ack, frame.seq, presence=frame.presence)


def parse_body(body: bytes) -> Frame:
    """Decode one body; :class:`BridgeProtocolError` names what is wrong."""
    if not body:
        raise BridgeProtocolError("empty frame")
    flags = body[0]
    if flags & ~_KNOWN_FLAGS:
        raise BridgeProtocolError(f"frame flags {flags:#04x} have unknown bits")
    if flags & Flags.HELLO:
        return _parse_hello(body)
    if flags & Flags.AUTH:
        if flags != Flags.AUTH or len(body) != 1 + PROOF_SIZE:
            raise BridgeProtocolError(f"malformed AUTH ({len(body)} bytes, flags {flags:#x})")
        return Auth(bytes(body[1:]))
    pos = 1
    try:
        if flags & Flags.RESUME:
            if flags != Flags.RESUME:
                raise BridgeProtocolError(f"RESUME with other flags {flags:#x}")
            accepted, pos = get_varint(body, pos, "accepted")
            if pos != len(body):
                raise BridgeProtocolError("bytes after RESUME")
            return Resume(accepted)
        ack = seq = presence = clock = None
        if flags & Flags.ACK:
            ack, pos = get_varint(body, pos, "ack")
        if flags & Flags.SEQ:
            seq, pos = get_varint(body, pos, "seq")
        if flags & Flags.PRESENCE:
            presence, pos = _parse_presence(body, pos)
        if flags & Flags.CLOCK:
            clock, pos = get_varint(body, pos, "clock")
            if clock >= CLOCK_MODULUS:
                raise BridgeProtocolError(f"frame clock {clock} exceeds {CLOCK_MODULUS - 1}")
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
    return DataFrame(tuple(entries), ack, seq, presence, clock)


def _parse_hello(body: bytes) -> Hello:
    flags = body[0]
    if flags != Flags.HELLO or len(body) < 2:
        raise BridgeProtocolError(f"malformed HELLO ({len(body)} bytes, flags {flags:#x})")
    if body[1] != PROTOCOL_VERSION:
        # Checked first: a peer of another version has another HELLO layout.
        raise BridgeProtocolError(f"peer speaks bridge protocol {body[1]}, we speak "
                                  f"{PROTOCOL_VERSION}; run the same bridge on both sides")
    if len(body) != _HELLO.size:
        raise BridgeProtocolError(f"malformed HELLO ({len(body)} bytes, expected {_HELLO.size})")
    _, version, side_code, fingerprint, session, nonce, keyed = _HELLO.unpack(body)
    side = _SIDE_NAMES.get(side_code)
    if side is None:
        raise BridgeProtocolError(f"HELLO names an unknown side {side_code:#x}")
    if keyed not in (0, 1):
        raise BridgeProtocolError(f"HELLO key flag {keyed:#x} is neither 0 nor 1")
    return Hello(side, fingerprint, session, nonce, bool(keyed), version)


@dataclass
class FrameSplitter:
    """Feed bytes as they arrive; take whole ``(body, trailer)`` records.

    The caller says how long the next record's trailer is (it depends on the
    link's phase); a record is only removed from the buffer once it is whole.
    """

    max_frame: int = DEFAULT_MAX_FRAME
    _buffer: bytearray = field(default_factory=bytearray)

    @property
    def pending(self) -> int:
        return len(self._buffer)

    def feed(self, data: Buffer) -> None:
        self._buffer += data

    def next_record(self, trailer: int, max_frame: Optional[int] = None
                    ) -> Optional[Tuple[bytes, bytes]]:
        """The next ``(body, trailer)``, or None until more bytes arrive."""
        buf = self._buffer
        limit = self.max_frame if max_frame is None else max_frame
        try:
            length, pos = get_varint(buf, 0, "frame length")
        except NeedMoreData:
            return None
        if length > limit:
            raise BridgeProtocolError(f"declared frame length {length} exceeds the "
                                      f"{limit}-byte limit")
        end = pos + length + trailer
        if len(buf) < end:
            return None
        record = bytes(buf[pos:pos + length]), bytes(buf[pos + length:end])
        del buf[:end]
        return record
