"""The ``text`` and ``text_ack`` carriers: YARP you can type in a terminal.

``CONNECT <name>`` (or ``CONNACK``) opens the connection; the receiver greets
``Welcome <name>``.  A message is a command line (``d``, ``*``, ``/port``...)
followed, for data, by the Bottle in text form.  ``text_ack`` also reads the
greeting, carries replies, and acknowledges each message with ``<ACK>``.
"""

from __future__ import annotations

from typing import Optional, Sequence

from yarp_lite.bottle import Bottle
from yarp_lite.bottle_text import parse
from yarp_lite.carriers.base import (Carrier, MessageSource, Payload, TextMessageSource,
                                     read_text_bottle, require_text, text_line)
from yarp_lite.stream import Stream
from yarp_lite.framing import is_data_command


class TextCarrier(Carrier):
    name = "text"
    header = b"CONNECT "
    text_mode = True
    supports_reply = False

    def send_header(self, stream: Stream, sender: str) -> None:
        stream.write(self.header + text_line(sender))

    def expect_header_reply(self, stream: Stream) -> Stream:
        if self.requires_ack:
            stream.read_line()  # "Welcome <name>", ignored as YARP ignores it
        return stream

    def expect_sender(self, stream: Stream) -> str:
        return stream.read_line()

    def respond_to_header(self, stream: Stream, sender: str, local_port: int) -> Stream:
        stream.write(text_line(f"Welcome {sender}"))
        return stream

    def write_message(self, stream: Stream, command: str, payload: Optional[Payload]) -> None:
        if is_data_command(command):
            stream.write(text_line(command) + text_line(require_text(payload, self.name)))
        else:
            stream.write(text_line(command))

    def read_reply(self, stream: Stream) -> Bottle:
        return parse(read_text_bottle(stream))

    def receiver(self, stream: Stream, where: str, max_message: int) -> MessageSource:
        return TextMessageSource(stream, where)

    def reply_chunks(self, reply: Payload) -> list:
        return [text_line(reply.text())]

    def text_response(self, lines: Sequence[str]) -> bytes:
        return b"".join(text_line(line) for line in lines)


class TextAckCarrier(TextCarrier):
    name = "text_ack"
    header = b"CONNACK "
    requires_ack = True
    supports_reply = True

    def read_ack(self, stream: Stream) -> None:
        stream.read_line()  # "<ACK>"

    def ack_chunk(self) -> bytes:
        return b"<ACK>\r\n"
