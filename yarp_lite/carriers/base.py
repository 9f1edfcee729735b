"""What every carrier provides, and the message types they carry.

A carrier decides how one connection looks on the wire: the 8 magic bytes,
how the sender names itself, whether the receiver answers the header,
whether messages are binary or text, and whether each one is acknowledged.
Everything above (ports, the name server) only talks to this interface, so a
connection's carrier is chosen per connection by name (``udp://read``), as in
YARP.

The carriers are thin: they drive a :class:`~yarp_lite.stream.Stream` with
the pure codecs in :mod:`yarp_lite.framing`, :mod:`yarp_lite.bottle`,
:mod:`yarp_lite.bottle_text` and :mod:`yarp_lite.carriers.datagram`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar, List, Optional, Sequence, Union

from yarp_lite.bottle import Bottle, decode, encode_chunks
from yarp_lite.bottle_text import format_bottle, is_complete, parse
from yarp_lite.errors import LocalProtocolError, RemoteProtocolError, YarpError
from yarp_lite.framing import envelope_of, wants_reply
from yarp_lite.stream import Stream

Buffer = Union[bytes, bytearray, memoryview]


class Payload:
    """User data of one message, rendered lazily in the form a carrier needs."""

    def binary(self) -> List[Buffer]:
        raise NotImplementedError

    def text(self) -> str:
        raise NotImplementedError

    def bottle(self) -> Bottle:
        raise NotImplementedError


class BottlePayload(Payload):
    """A Bottle; encoded at most once per form, however many outputs it goes to."""

    __slots__ = ("_bottle", "_binary", "_text")

    def __init__(self, bottle: Sequence) -> None:
        self._bottle = bottle if isinstance(bottle, Bottle) else Bottle(bottle)
        self._binary: Optional[List[Buffer]] = None
        self._text: Optional[str] = None

    def binary(self) -> List[Buffer]:
        if self._binary is None:
            self._binary = encode_chunks(self._bottle)
        return self._binary

    def text(self) -> str:
        if self._text is None:
            self._text = format_bottle(self._bottle)
        return self._text

    def bottle(self) -> Bottle:
        return self._bottle


class RawPayload(Payload):
    """Pre-encoded binary data (e.g. a Bottle encoded elsewhere, or an image)."""

    __slots__ = ("_chunks",)

    def __init__(self, *chunks: Buffer) -> None:
        self._chunks = list(chunks)

    def binary(self) -> List[Buffer]:
        return self._chunks

    def text(self) -> str:
        return format_bottle(self.bottle())

    def bottle(self) -> Bottle:
        return decode(b"".join(bytes(chunk) for chunk in self._chunks))


@dataclass
class Incoming:
    """One message as a port receives it, whatever the carrier.

    ``command`` is ``d``/``D`` (data with/without reply), ``a`` (admin data)
    or a port command character (``/``, ``!``, ``~``, ``*``, ``q``, ``?``...)
    with its full ``text``.  Data comes as ``binary`` bytes or ``text``;
    :meth:`bottle` decodes either.
    """

    command: str
    text: str = ""
    binary: Optional[Buffer] = None
    text_data: Optional[str] = None
    where: str = "connection"
    _bottle: Optional[Bottle] = field(default=None, repr=False)

    @property
    def wants_reply(self) -> bool:
        return wants_reply(self.command)

    @property
    def envelope(self) -> str:
        return envelope_of(self.command, self.text)

    def bottle(self) -> Bottle:
        if self._bottle is None:
            if self.binary is not None:
                self._bottle = decode(self.binary, self.where)
            else:
                self._bottle = parse(self.text_data or "")
        return self._bottle


class Carrier:
    """Base carrier: subclasses set the class attributes and the stream rituals."""

    name: ClassVar[str] = ""
    header: ClassVar[bytes] = b""
    text_mode: ClassVar[bool] = False
    requires_ack: ClassVar[bool] = False
    supports_reply: ClassVar[bool] = True
    can_escape: ClassVar[bool] = True
    connectionless: ClassVar[bool] = False

    # -- sender side ---------------------------------------------------------

    def send_header(self, stream: Stream, sender: str) -> None:
        raise NotImplementedError

    def expect_header_reply(self, stream: Stream) -> Stream:
        """Read the receiver's answer; return the stream to use from now on."""
        return stream

    def write_message(self, stream: Stream, command: str, payload: Optional[Payload]) -> None:
        raise NotImplementedError

    def read_reply(self, stream: Stream) -> Bottle:
        raise NotImplementedError

    def read_ack(self, stream: Stream) -> None:
        """Wait for the receiver's acknowledgement, if this carrier has one."""

    # -- receiver side -------------------------------------------------------

    def expect_sender(self, stream: Stream) -> str:
        raise NotImplementedError

    def respond_to_header(self, stream: Stream, sender: str, local_port: int) -> Stream:
        return stream

    def receiver(self, stream: Stream, where: str, max_message: int) -> "MessageSource":
        raise NotImplementedError

    def reply_chunks(self, reply: Payload) -> List[Buffer]:
        """The bytes of a reply (sent together with the acknowledgement)."""
        raise NotImplementedError

    def ack_chunk(self) -> bytes:
        """The acknowledgement that closes each received message, if any."""
        return b""

    def text_response(self, lines: Sequence[str]) -> bytes:
        """Human-readable answers to port commands; only text carriers send them."""
        return b""


class MessageSource:
    """Receiver-side reader of successive :class:`Incoming` messages."""

    def next(self) -> Incoming:
        raise NotImplementedError

    def more_waiting(self) -> bool:
        """Whether bytes of a further message have already arrived (a reader that is
        behind can then skip decoding this one)."""
        return False


class TextMessageSource(MessageSource):
    """Reads text-mode messages: a command line, then a Bottle in text form."""

    def __init__(self, stream: Stream, where: str, escape: bool = True) -> None:
        self.stream = stream
        self.where = where
        self.escape = escape

    def next(self) -> Incoming:
        if not self.escape:
            return Incoming("d", "d", text_data=read_text_bottle(self.stream), where=self.where)
        line = self.stream.read_line()
        command = line[:1] if line else "\0"
        if command in ("d", "D", "a"):
            return Incoming(command, line, text_data=read_text_bottle(self.stream),
                            where=self.where)
        return Incoming(command, line, where=self.where)


#: A text Bottle continued over several lines: at most this many lines and characters
#: (one line alone may be MAX_LINE long); each new line rescans the text, so both are small.
MAX_CONTINUATION_LINES = 256
MAX_CONTINUED_TEXT = 64 * 1024


def read_text_bottle(stream: Stream) -> str:
    """Read the lines of one text Bottle (``BottleImpl::read`` in text mode)."""
    text = stream.read_line()
    lines = 1
    while text:
        if text.endswith("\\"):
            text = text[:-1]
        elif is_complete(text):
            break
        else:
            text += "\n"
        if lines >= MAX_CONTINUATION_LINES or len(text) > MAX_CONTINUED_TEXT:
            raise RemoteProtocolError(
                f"text Bottle continued over {lines} lines and {len(text)} characters "
                f"(limits {MAX_CONTINUATION_LINES} and {MAX_CONTINUED_TEXT}; an unclosed list?)",
                stream.where)
        text += stream.read_line()
        lines += 1
    return text


def text_line(text: str) -> bytes:
    return (text + "\r\n").encode("utf-8", "surrogateescape")


def require_text(payload: Optional[Payload], carrier: str) -> str:
    if payload is None:
        return ""
    try:
        return payload.text()
    except (YarpError, ValueError) as exc:  # a raw binary payload that is not a Bottle
        raise LocalProtocolError(f"carrier {carrier} can only send Bottles: {exc}") from exc
