"""Shared machinery of the binary carriers (tcp, fast_tcp, udp).

They differ only in their magic bytes, acknowledgements and the stream under
them; messages are the same index + payload of :mod:`yarp_lite.framing`, and
replies are bare binary Bottles.
"""

from __future__ import annotations

from typing import Optional

from yarp_lite.bottle import Bottle
from yarp_lite.carriers.base import Carrier, Incoming, MessageSource, Payload
from yarp_lite.errors import NeedMoreData, RemoteProtocolError
from yarp_lite.framing import (DEFAULT_MAX_MESSAGE, MessageDecoder, decode_reply_prefix,
                               encode_message, encode_sender_name, expect_yarp_number,
                               sender_name_length, decode_sender_name, yarp_number)
from yarp_lite.stream import Stream

#: Payloads bigger than this are received straight into their final buffer.
_DIRECT_RECEIVE = 16384


class BinaryCarrier(Carrier):
    """A carrier speaking YARP's binary connection protocol."""

    def send_header(self, stream: Stream, sender: str) -> None:
        stream.write(self.header, encode_sender_name(sender))

    def expect_header_reply(self, stream: Stream) -> Stream:
        expect_yarp_number(stream.read_exact(8), f"{stream.where}: header reply")
        return stream

    def expect_sender(self, stream: Stream) -> str:
        length = sender_name_length(stream.read_exact(4))
        return decode_sender_name(stream.read_exact(length))

    def respond_to_header(self, stream: Stream, sender: str, local_port: int) -> Stream:
        stream.write(yarp_number(local_port))
        return stream

    def write_message(self, stream: Stream, command: str, payload: Optional[Payload]) -> None:
        stream.write(*encode_message(command, payload.binary() if payload else ()))
        stream.flush()

    def read_reply(self, stream: Stream) -> Bottle:
        return read_binary_bottle(stream)

    def receiver(self, stream: Stream, where: str, max_message: int) -> MessageSource:
        return BinaryMessageSource(stream, where, max_message)

    def reply_chunks(self, reply: Payload) -> list:
        return list(reply.binary())


class BinaryMessageSource(MessageSource):
    """Feeds a :class:`MessageDecoder` from a stream."""

    def __init__(self, stream: Stream, where: str,
                 max_message: int = DEFAULT_MAX_MESSAGE) -> None:
        self.stream = stream
        self.where = where
        self.decoder = MessageDecoder(where, max_message)

    def next(self) -> Incoming:
        decoder = self.decoder
        while True:
            message = decoder.next_message()
            if message is not None:
                return Incoming(message.command, message.text, binary=message.payload,
                                where=self.where)
            window = decoder.payload_window()
            if window is not None and len(window) > _DIRECT_RECEIVE:
                with window:  # released before the decoder may grow its buffer again
                    self.stream.read_into(window)
                    decoder.commit(len(window))
            else:
                if window is not None:
                    window.release()
                decoder.feed(self.stream.read_some())

    def more_waiting(self) -> bool:
        # What the last read brought (a reader that is behind reads many messages at
        # once); not the socket itself, a system call per message.
        return self.decoder.buffered > 0


def read_binary_bottle(stream: Stream, limit: int = DEFAULT_MAX_MESSAGE) -> Bottle:
    """Read one self-delimiting binary Bottle (a reply has no length prefix)."""
    buffer = stream.read_some()
    while True:
        try:
            bottle, used = decode_reply_prefix(buffer, f"{stream.where}: reply")
        except NeedMoreData:
            if len(buffer) > limit:
                raise RemoteProtocolError(f"reply longer than {limit} bytes", stream.where)
            buffer += stream.read_some()
            continue
        if used < len(buffer):
            stream.unread(buffer[used:])  # the acknowledgement, usually
        return bottle


def read_binary_ack(stream: Stream) -> None:
    length = expect_yarp_number(stream.read_exact(8), f"{stream.where}: acknowledgement")
    if length < 0:
        raise RemoteProtocolError(f"negative acknowledgement length {length}", stream.where)
    if length:
        stream.read_exact(min(length, DEFAULT_MAX_MESSAGE))
