"""The YARP connection protocol as pure functions over bytes.

Theory of operation
-------------------
``doc/yarp_protocol.dox`` splits a connection into phases: *header* (8 magic
bytes naming the carrier, then the sender's port name), *header reply*, then
for every message *index*, *payload* and *acknowledgement*.  This module holds
the carrier-independent pieces of the binary carriers (tcp, fast_tcp, udp):

* ``YA <int32> RP`` numbers, used for the carrier magic, the header reply (a
  socket number), the index header and the acknowledgement;
* the index: ``YA 0a 00 00 00 RP``, then ``[nblocks, 1, ff x 8]``, one int32
  length per block, and one int32 reply length (always 0);
* the port command that opens every payload: 8 bytes
  ``[len:int32, '~', ch, 0, 1]`` where ``ch`` is ``d`` (data, reply wanted),
  ``D`` (data, no reply), ``a`` (administrative data) or NUL, in which case a
  NUL-terminated command string (``/port``, ``!/port``, ``*``, ``q``...)
  follows.

:class:`MessageDecoder` turns a byte stream into :class:`Message` events.  It
owns no socket: the port feeds it what ``recv`` returned and asks for the next
event; a half-arrived message is never half-consumed, and any violation raises
:class:`RemoteProtocolError` saying which field was wrong.

Limits, so a peer cannot make a port hold unbounded memory: a message (the
sum of its index's blocks) is at most ``max_message`` bytes
(:data:`DEFAULT_MAX_MESSAGE`, 256 MiB, unless the port sets its own; the
payload buffer is allocated when the index announces it, so this is also
what one connection can make the port allocate), an index lists at most
:data:`MAX_BLOCKS` blocks, and a sender name is at most
:data:`MAX_SENDER_NAME` bytes.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from typing import Optional, Sequence, Union

from yarp_lite.errors import NeedMoreData, RemoteProtocolError

_S32 = struct.Struct("<i")
_INDEX_HEADER_LENGTH = 10
#: Largest payload accepted from a peer unless a port raises it.
DEFAULT_MAX_MESSAGE = 256 * 1024 * 1024
#: First allocation for a payload; the buffer doubles as the payload arrives.
INITIAL_PAYLOAD = 1 << 20
#: Most blocks an index can list (its count is a single byte).
MAX_BLOCKS = 255

Buffer = Union[bytes, bytearray, memoryview]


# --------------------------------------------------------------------------
# YA..RP numbers


def yarp_number(value: int) -> bytes:
    """``YA`` + little-endian int32 + ``RP`` (``AbstractCarrier::createYarpNumber``)."""
    return b"YA" + _S32.pack(value) + b"RP"


def parse_yarp_number(data: Buffer) -> Optional[int]:
    """The int32 inside an 8-byte ``YA..RP`` number, or None if it is not one."""
    if len(data) != 8 or data[0:2] != b"YA" or data[6:8] != b"RP":
        return None
    return _S32.unpack_from(data, 2)[0]


def expect_yarp_number(data: Buffer, what: str) -> int:
    value = parse_yarp_number(data)
    if value is None:
        raise RemoteProtocolError(f"expected a YA..RP number, got {bytes(data)!r}", what)
    return value


# --------------------------------------------------------------------------
# Sender name (tcp, fast_tcp, udp headers)


def encode_sender_name(name: str) -> bytes:
    """int32 length (including the NUL) + name + NUL."""
    raw = name.encode("utf-8", "surrogateescape")
    return _S32.pack(len(raw) + 1) + raw + b"\0"


#: Longest sender name read from a connection header (YARP clamps it the same way).
MAX_SENDER_NAME = 1000


def sender_name_length(prefix: Buffer) -> int:
    """Bytes the name occupies after its 4-byte length, clamped as YARP clamps it."""
    if len(prefix) < 4:
        raise NeedMoreData(f"sender name length needs 4 bytes, got {len(prefix)}",
                           "connection header")
    declared = _S32.unpack_from(prefix, 0)[0]
    return min(max(declared, 1), MAX_SENDER_NAME)


def decode_sender_name(raw: Buffer) -> str:
    text = bytes(raw).split(b"\0", 1)[0]
    return text.decode("utf-8", "surrogateescape")


# --------------------------------------------------------------------------
# Index, port command, acknowledgement


_INDEX_ONE = struct.Struct("<8s10sii")
_INDEX_TWO = struct.Struct("<8s10siii")
_INDEX_HEAD = b"YA\x0a\x00\x00\x00RP"


def encode_index(block_lengths: Sequence[int]) -> bytes:
    """The index announcing the payload blocks (``defaultSendIndex``)."""
    count = len(block_lengths)
    if count == 2:
        return _INDEX_TWO.pack(_INDEX_HEAD, b"\x02\x01" + b"\xff" * 8, block_lengths[0],
                               block_lengths[1], 0)
    if count == 1:
        return _INDEX_ONE.pack(_INDEX_HEAD, b"\x01\x01" + b"\xff" * 8, block_lengths[0], 0)
    if count > MAX_BLOCKS:
        raise ValueError(f"{len(block_lengths)} blocks do not fit in a YARP index")
    return b"".join((yarp_number(_INDEX_HEADER_LENGTH),
                     bytes((len(block_lengths), 1)), b"\xff" * 8,
                     struct.pack(f"<{len(block_lengths)}i", *block_lengths),
                     _S32.pack(0)))


DATA_REPLY = b"\0\0\0\0~d\0\x01"       # data, the sender waits for a reply
DATA_NO_REPLY = b"\0\0\0\0~D\0\x01"    # data, no reply wanted
ADMIN_DATA = b"\0\0\0\0~a\0\x01"       # data for the port itself (admin protocol)


def encode_port_command(text: str) -> bytes:
    """A textual port command such as ``/read``, ``!/read``, ``*`` or ``q``."""
    raw = text.encode("utf-8", "surrogateescape") + b"\0"
    return _S32.pack(len(raw)) + b"~\0\0\x01" + raw


def encode_ack(extra: bytes = b"") -> bytes:
    return yarp_number(len(extra)) + extra


ACK = encode_ack()


@dataclass(frozen=True)
class Message:
    """One message received on a binary connection.

    ``command`` is the port command character: ``d``/``D`` for data (``D``
    means the sender wants no reply), ``a`` for admin data, or the first
    character of a textual command (``/``, ``!``, ``~``, ``*``, ``q``...).
    ``text`` is the full textual command; ``payload`` the bytes after it.
    """

    command: str
    text: str
    payload: Buffer

    @property
    def wants_reply(self) -> bool:
        return wants_reply(self.command)

    @property
    def envelope(self) -> str:
        return envelope_of(self.command, self.text)


def wants_reply(command: str) -> bool:
    """Data sent with ``d`` (or admin data) expects a reply; ``D`` does not."""
    return command in ("d", "a")


def envelope_of(command: str, text: str) -> str:
    """The envelope of ``d <envelope>`` / ``D <envelope>`` data, if any."""
    return text[2:] if command in ("d", "D") and len(text) > 2 else ""


def parse_payload(payload: Buffer, where: str = "payload") -> Message:
    """Split a message payload into its port command and the user data."""
    view = memoryview(payload)
    if len(view) < 8:
        raise RemoteProtocolError(f"payload of {len(view)} bytes has no port command", where)
    if view[4] != 0x7E:  # '~'
        raise RemoteProtocolError(f"port command header {bytes(view[:8])!r} lacks '~'", where)
    ch = view[5]
    if ch != 0:
        return Message(chr(ch), chr(ch), view[8:])
    end = bytes(view[8:]).find(b"\0")
    if end < 0:
        raise RemoteProtocolError("port command text is not NUL-terminated", where)
    text = bytes(view[8:8 + end]).decode("utf-8", "surrogateescape")
    # "d <envelope>" is data with an envelope; anything else is a command.
    return Message(text[:1] if text else "\0", text, view[8 + end + 1:])


# --------------------------------------------------------------------------
# Incremental decoding


class MessageDecoder:
    """Bytes in, :class:`Message` events out, for tcp-family connections.

    Usage: ``decoder.feed(data)``, then call :meth:`next_message` until it
    returns None (more bytes needed).  State only advances when a whole index
    or payload is present, so feeding one byte at a time gives the same events
    as feeding everything at once.

    For big payloads the socket layer may skip :meth:`feed`: once the index is
    parsed, :meth:`payload_window` exposes the unfilled part of the payload
    buffer, the caller ``recv_into``-s it and calls :meth:`commit`, so a 1 MB
    message is copied once, from the kernel into its final buffer.

    The payload buffer grows as bytes arrive (doubling from
    :data:`INITIAL_PAYLOAD`), never to more than what the index announced: an
    index alone, 26 bytes, cannot make a port allocate ``max_message`` bytes.
    A caller must release a window before asking for the next one.
    """

    def __init__(self, where: str = "connection", max_message: int = DEFAULT_MAX_MESSAGE) -> None:
        self.where = where
        self.max_message = max_message
        self._buffer = bytearray()
        self._start = 0
        self._payload: Optional[bytearray] = None
        self._length = 0          # what the index announced for the current payload
        self._filled = 0

    def _make_room(self, wanted: int) -> None:
        """Grow the payload buffer to hold ``wanted`` bytes (doubling, capped)."""
        assert self._payload is not None
        size = len(self._payload)
        if wanted <= size:
            return
        new_size = min(self._length, max(wanted, size * 2))
        self._payload.extend(bytes(new_size - size))

    def feed(self, data: Buffer) -> None:
        if self._payload is not None and self._filled < self._length:
            take = min(len(data), self._length - self._filled)
            self._make_room(self._filled + take)
            self._payload[self._filled:self._filled + take] = data[:take]
            self._filled += take
            data = data[take:]
        if len(data):
            self._buffer += data

    @property
    def buffered(self) -> int:
        return len(self._buffer) - self._start

    @property
    def idle(self) -> bool:
        """True between messages (nothing partially received)."""
        return self._payload is None and self.buffered == 0

    def payload_window(self) -> Optional[memoryview]:
        """The unfilled tail of the payload buffer (grown if full), or None outside one."""
        if self._payload is None or self._filled >= self._length:
            return None
        self._make_room(self._filled + 1)
        return memoryview(self._payload)[self._filled:]

    def commit(self, count: int) -> None:
        """Record that ``count`` bytes were written into :meth:`payload_window`."""
        self._filled += count

    def reset(self) -> None:
        """Forget everything partial (after a lost datagram, for instance)."""
        self._buffer.clear()
        self._start = 0
        self._payload = None
        self._length = 0
        self._filled = 0

    def next_message(self) -> Optional[Message]:
        if self._payload is None:
            length = self._parse_index()
            if length is None:
                return None
            take = min(length, self.buffered)
            self._payload = bytearray(min(length, max(take, INITIAL_PAYLOAD)))
            self._length = length
            self._payload[:take] = self._buffer[self._start:self._start + take]
            self._consume(take)
            self._filled = take
        if self._filled < self._length:
            return None
        payload, self._payload, self._filled, self._length = self._payload, None, 0, 0
        return parse_payload(payload, self.where)

    def _parse_index(self) -> Optional[int]:
        buf, start = self._buffer, self._start
        if len(buf) - start < 8 + _INDEX_HEADER_LENGTH:
            self._check_partial_header()
            return None
        header = expect_yarp_number(buf[start:start + 8], f"{self.where}: index header")
        if header != _INDEX_HEADER_LENGTH:
            raise RemoteProtocolError(f"index header announces {header} bytes, expected 10",
                                      self.where)
        in_blocks, out_blocks = buf[start + 8], buf[start + 9]
        lengths_at = start + 8 + _INDEX_HEADER_LENGTH
        count = in_blocks + out_blocks
        if len(buf) - lengths_at < 4 * count:
            return None
        lengths = struct.unpack_from(f"<{count}i", buf, lengths_at)
        if any(length < 0 for length in lengths):
            raise RemoteProtocolError(f"negative block length in index {lengths}", self.where)
        total = sum(lengths)
        if total > self.max_message:
            raise RemoteProtocolError(
                f"message of {total} bytes exceeds the {self.max_message}-byte limit", self.where)
        self._consume(8 + _INDEX_HEADER_LENGTH + 4 * count)
        return total

    def _check_partial_header(self) -> None:
        """Reject garbage as soon as the first bytes cannot start an index."""
        head = bytes(self._buffer[self._start:self._start + 2])
        if head and not b"YA".startswith(head):
            raise RemoteProtocolError(f"expected an index header, got {head!r}", self.where)

    def _consume(self, count: int) -> None:
        self._start += count
        if self._start == len(self._buffer):
            self._buffer.clear()
            self._start = 0
        elif self._start > 65536 and self._start * 2 > len(self._buffer):
            del self._buffer[:self._start]
            self._start = 0


def decode_reply_prefix(buffer: Buffer, where: str = "reply"):
    """Decode a binary reply Bottle at the start of ``buffer``.

    Returns ``(bottle, consumed)``; raises :class:`NeedMoreData` if the buffer
    is a correct but incomplete prefix.
    """
    from yarp_lite.bottle import decode_prefix

    return decode_prefix(buffer if isinstance(buffer, (bytes, memoryview)) else bytes(buffer),
                         0, where)


__all__ = ["yarp_number", "parse_yarp_number", "encode_sender_name", "encode_index",
           "encode_port_command", "encode_ack", "parse_payload", "MessageDecoder", "Message",
           "NeedMoreData", "DATA_REPLY", "DATA_NO_REPLY", "ADMIN_DATA", "ACK"]


def is_data_command(command: str) -> bool:
    """``d``/``D``/``a``, or data with an envelope: ``d <envelope>``/``D <envelope>``."""
    return command in ("d", "D", "a") or command[:2] in ("d ", "D ")


def command_header(command: str) -> bytes:
    """The bytes that open a payload for a data command or a textual command.

    Data with an envelope (a timestamp, say) travels as the textual command
    ``D <envelope>``, as YARP's PortCoreOutputUnit sends it.
    """
    if command == "d":
        return DATA_REPLY
    if command == "D":
        return DATA_NO_REPLY
    if command == "a":
        return ADMIN_DATA
    return encode_port_command(command)


def encode_message(command: str, chunks: Sequence[Buffer] = ()) -> list:
    """Index + payload for one message, as the buffers to send in order.

    Data gets two index blocks (the 8-byte command header, then the data) and a
    textual command one block, exactly as YARP's BufferedConnectionWriter
    groups them, so the index bytes match real YARP's.
    """
    head = command_header(command)
    data_length = sum(len(chunk) if type(chunk) is bytes else memoryview(chunk).nbytes
                      for chunk in chunks)
    if is_data_command(command):
        return [encode_index([len(head), data_length]), head, *chunks]
    return [encode_index([len(head) + data_length]), head, *chunks]
