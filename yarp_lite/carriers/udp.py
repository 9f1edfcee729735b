"""The ``udp`` carrier: the tcp handshake, then messages as datagrams.

The sender connects over TCP and sends ``YA 61 1e 00 00 RP`` and its name;
the receiver opens a UDP socket and answers with its number; both then drop
the TCP connection.  Messages are the tcp index + payload cut into datagrams
by :mod:`yarp_lite.carriers.datagram`.  There are no replies and no
acknowledgements; a lost datagram loses its whole message, nothing more.
"""

from __future__ import annotations

import socket
import time
from typing import List, Union

from yarp_lite.bottle import Bottle
from yarp_lite.carriers.base import Incoming, MessageSource
from yarp_lite.carriers.binary import BinaryCarrier
from yarp_lite.carriers.datagram import MAX_DATAGRAM, DatagramAssembler, pack_message
from yarp_lite.errors import LocalProtocolError, NetworkError
from yarp_lite.framing import MessageDecoder, expect_yarp_number, yarp_number
from yarp_lite.stream import Address, Stream

Buffer = Union[bytes, bytearray, memoryview]
_SPECIFIER_BASE = 7777
#: YARP waits ~1 ms after a nearly full datagram so receivers keep up; so do we.
_PACING_SECONDS = 0.001


class UdpCarrier(BinaryCarrier):
    name = "udp"
    header = yarp_number(_SPECIFIER_BASE)
    supports_reply = False
    connectionless = True

    def expect_header_reply(self, stream: Stream) -> Stream:
        port = expect_yarp_number(stream.read_exact(8), f"{stream.where}: udp header reply")
        host = stream.remote_address[0]
        stream.close()
        return DatagramStream.connect(host, port)

    def respond_to_header(self, stream: Stream, sender: str, local_port: int) -> Stream:
        datagrams = DatagramStream.bind(stream.local_address[0])
        stream.write(yarp_number(datagrams.local_address[1]))
        stream.close()
        return datagrams

    def read_reply(self, stream: Stream) -> Bottle:
        raise LocalProtocolError("the udp carrier cannot carry replies (try tcp or text_ack)")

    def receiver(self, stream: Stream, where: str, max_message: int) -> MessageSource:
        return DatagramMessageSource(stream, where, max_message)


class DatagramStream(Stream):
    """One end of a udp connection, with the Stream interface the carriers use."""

    def __init__(self, sock: socket.socket, where: str) -> None:
        self.sock = sock
        self.where = where
        self._pending: List[Buffer] = []
        self._closed = False

    @classmethod
    def connect(cls, host: str, port: int) -> "DatagramStream":
        try:
            sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            sock.connect((host, port))
        except OSError as exc:
            raise NetworkError(f"cannot open udp connection to {host}:{port}: {exc}") from exc
        return cls(sock, f"udp to {host}:{port}")

    @classmethod
    def bind(cls, host: str) -> "DatagramStream":
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4 * 1024 * 1024)
        except OSError:
            pass
        sock.bind((host, 0))
        return cls(sock, f"udp on {host}:{sock.getsockname()[1]}")

    def write(self, *chunks: Buffer) -> None:
        self._pending.extend(chunks)

    def flush(self) -> None:
        chunks, self._pending = self._pending, []
        try:
            for datagram in pack_message(chunks):
                self.sock.send(datagram)
                if len(datagram) > MAX_DATAGRAM * 3 // 4:
                    time.sleep(_PACING_SECONDS)
        except OSError as exc:
            # Datagrams to a vanished receiver fail with ECONNREFUSED; report it.
            raise NetworkError(f"{self.where}: send failed: {exc}") from exc

    def receive_datagram(self) -> bytes:
        try:
            data = self.sock.recv(65536)
        except OSError as exc:
            raise NetworkError(f"{self.where}: receive failed: {exc}") from exc
        if self._closed:
            raise NetworkError(f"{self.where}: stream closed")
        return data

    def read_exact(self, count: int) -> bytes:
        raise LocalProtocolError("a udp stream is read datagram by datagram")

    def read_some(self) -> bytes:
        return self.receive_datagram()

    def read_line(self, limit: int = 0) -> str:
        raise LocalProtocolError("a udp stream carries no text")

    def unread(self, data: bytes) -> None:
        raise LocalProtocolError("a udp stream cannot push data back")

    def close(self) -> None:
        if not self._closed:
            self._closed = True
            try:
                # Wake a reader blocked in recv with an empty "wake up" datagram.
                wake = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
                wake.sendto(b"\0\0\0\0\xff\xff\xff\xff", self.sock.getsockname())
                wake.close()
            except OSError:
                pass
            self.sock.close()

    @property
    def local_address(self) -> Address:
        return self.sock.getsockname()[:2]

    @property
    def remote_address(self) -> Address:
        try:
            return self.sock.getpeername()[:2]
        except OSError:
            return ("", 0)


class DatagramMessageSource(MessageSource):
    """Reassembles messages from datagrams; incomplete ones are dropped whole."""

    def __init__(self, stream: Stream, where: str, max_message: int) -> None:
        if not isinstance(stream, DatagramStream):
            raise LocalProtocolError("udp messages need a datagram stream")
        self.stream = stream
        self.where = where
        self.assembler = DatagramAssembler()
        self.decoder = MessageDecoder(where, max_message)

    def next(self) -> Incoming:
        while True:
            body, restart = self.assembler.accept(self.stream.receive_datagram())
            if restart:
                self.decoder.reset()
            if body is None:
                continue
            self.decoder.feed(body)
            try:
                message = self.decoder.next_message()
            except Exception:
                self.decoder.reset()
                self.assembler.message_done()
                continue
            if message is not None:
                self.assembler.message_done()
                self.decoder.reset()
                return Incoming(message.command, message.text, binary=message.payload,
                                where=self.where)

    @property
    def dropped(self) -> int:
        return self.assembler.dropped
