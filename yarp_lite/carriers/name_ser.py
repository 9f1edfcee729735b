"""The ``name_ser`` carrier: how YARP tools talk to the name server in plain text.

A client sends ``NAME_SERVER <command>\\n``: the first 8 bytes double as the
carrier magic (``NAME_SER``) and ``VER `` follows.  Every further command on
the same connection repeats the ``NAME_SERVER `` prefix.  Commands are text
Bottles without quotes; replies are text lines (the name server's "old"
format ending in ``*** end of message``).  No acknowledgements, no port
commands.
"""

from __future__ import annotations

from typing import Optional, Sequence

from yarp_lite.bottle import Bottle
from yarp_lite.bottle_text import parse
from yarp_lite.carriers.base import (Carrier, Incoming, MessageSource, Payload,
                                     read_text_bottle, require_text, text_line)
from yarp_lite.stream import Stream

PREFIX = b"NAME_SERVER "


class NameSerCarrier(Carrier):
    name = "name_ser"
    header = b"NAME_SER"
    text_mode = True
    can_escape = False

    def __init__(self) -> None:
        self._first = True

    def send_header(self, stream: Stream, sender: str) -> None:
        stream.write(self.header)

    def write_message(self, stream: Stream, command: str, payload: Optional[Payload]) -> None:
        text = require_text(payload, self.name).replace('"', "")
        prefix = b"VER " if self._first else PREFIX
        self._first = False
        stream.write(prefix + text_line(text))

    def read_reply(self, stream: Stream) -> Bottle:
        return parse(read_text_bottle(stream))

    def expect_sender(self, stream: Stream) -> str:
        return "anon"

    def receiver(self, stream: Stream, where: str, max_message: int) -> MessageSource:
        return NameSerMessageSource(stream, where)

    def reply_chunks(self, reply: Payload) -> list:
        return [text_line(reply.text())]

    def text_response(self, lines: Sequence[str]) -> bytes:
        return b"".join(text_line(line) for line in lines)


class NameSerMessageSource(MessageSource):
    """Each line is one command; the ``VER `` / ``NAME_SERVER `` prefixes are dropped."""

    def __init__(self, stream: Stream, where: str) -> None:
        self.stream = stream
        self.where = where
        self._prefix = b"VER "

    def next(self) -> Incoming:
        head = b""
        while len(head) < len(self._prefix) and self._prefix.startswith(head):
            head += self.stream.read_some()
        if head.startswith(self._prefix):
            head = head[len(self._prefix):]
        self.stream.unread(head)
        self._prefix = PREFIX
        return Incoming("d", "d", text_data=read_text_bottle(self.stream), where=self.where)
