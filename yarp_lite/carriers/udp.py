"""The ``udp`` carrier: the tcp handshake, then messages as datagrams.

The sender connects over TCP and sends ``YA 61 1e 00 00 RP`` and its name;
the receiver opens a UDP socket and answers with its number; both then drop
the TCP connection.  Messages are the tcp index + payload cut into datagrams
by :mod:`yarp_lite.carriers.datagram`.  There are no replies and no
acknowledgements; a lost datagram loses its whole message, nothing more.

Nothing tells a udp sender that its message was refused, so the receiving
side keeps the account (:attr:`DatagramMessageSource.counters`): datagrams
lost, messages that broke the protocol (a :class:`RemoteProtocolError`,
dropped) and messages our own code failed on (a bug: logged with its
traceback, dropped).  Either kind of failure costs one message, never the
connection -- a dropped udp input would silence the stream for good without
the sender ever knowing -- and is logged once per burst: the first, then the
10th, 100th ... naming the sender and what was wrong.
"""

from __future__ import annotations

import logging
import socket
import time
from dataclasses import dataclass
from typing import List, Tuple, Union

from yarp_lite.bottle import Bottle
from yarp_lite.carriers.base import Incoming, MessageSource
from yarp_lite.carriers.binary import BinaryCarrier
from yarp_lite.carriers.datagram import MAX_DATAGRAM, DatagramAssembler, pack_message
from yarp_lite.bursts import Burst
from yarp_lite.errors import LocalProtocolError, NetworkError, RemoteProtocolError
from yarp_lite.framing import MessageDecoder, expect_yarp_number, yarp_number
from yarp_lite.stream import Address, Stream

log = logging.getLogger("yarp_lite.carriers.udp")

Buffer = Union[bytes, bytearray, memoryview]
_SPECIFIER_BASE = 7777
#: YARP waits ~1 ms after a nearly full datagram so receivers keep up; so do we.
_PACING_SECONDS = 0.001
#: A burst of failures ends after this many seconds without one; the next is logged at once.


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
        datagrams = DatagramStream.bind(stream.local_address[0], sender)
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
        sock.settimeout(None)  # blocking whatever the process default (see SocketStream)
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
    def bind(cls, host: str, sender: str = "") -> "DatagramStream":
        """The receiving end; ``sender`` (the port named in the handshake) names it in logs."""
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4 * 1024 * 1024)
        except OSError:
            pass  # the kernel's default buffer still receives, with less slack
        sock.bind((host, 0))
        origin = f"udp from {sender} " if sender else "udp "
        return cls(sock, f"{origin}on {host}:{sock.getsockname()[1]}")

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

    def receive_datagram(self) -> Tuple[bytes, Address]:
        """The next datagram and the address it came from (which a log may need to name)."""
        try:
            data, origin = self.sock.recvfrom(65536)
        except OSError as exc:
            raise NetworkError(f"{self.where}: receive failed: {exc}") from exc
        if self._closed:
            raise NetworkError(f"{self.where}: stream closed")
        return data, origin[:2]

    def read_exact(self, count: int) -> bytes:
        raise LocalProtocolError("a udp stream is read datagram by datagram")

    def read_some(self) -> bytes:
        return self.receive_datagram()[0]

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
            except OSError as exc:
                log.info("%s: cannot wake a reader on close (%s): it stays blocked "
                         "until a datagram comes", self.where, exc)
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


@dataclass(frozen=True)
class InputCounters:
    """What one udp input lost, and why (a snapshot)."""

    #: Messages delivered to the port.
    messages: int = 0
    #: Datagrams dropped by the reassembly (lost, corrupt, out of order, truncated).
    dropped_datagrams: int = 0
    #: Whole messages that broke the protocol (the peer's fault), dropped.
    malformed: int = 0
    #: Messages our decoding failed on with an unexpected exception (our bug), dropped.
    failures: int = 0


class DatagramMessageSource(MessageSource):
    """Reassembles messages from datagrams; incomplete or broken ones are dropped whole."""

    def __init__(self, stream: Stream, where: str, max_message: int) -> None:
        if not isinstance(stream, DatagramStream):
            raise LocalProtocolError("udp messages need a datagram stream")
        self.stream = stream
        self.where = where
        self.assembler = DatagramAssembler()
        self.decoder = MessageDecoder(where, max_message)
        self.messages = 0
        self.malformed = 0
        self.failures = 0
        self._malformed_burst = Burst()
        self._failure_burst = Burst()

    def next(self) -> Incoming:
        while True:
            datagram, origin = self.stream.receive_datagram()
            body, restart = self.assembler.accept(datagram)
            if restart:
                self.decoder.reset()
            if body is None:
                continue
            self.decoder.feed(body)
            try:
                message = self.decoder.next_message()
            except RemoteProtocolError as exc:
                self._discard()
                self.malformed += 1
                if self._malformed_burst.record():
                    log.warning("%s (datagram from %s:%d); message dropped, %s",
                                exc, *origin, self._tally(self._malformed_burst, self.malformed,
                                                        "malformed"))
                continue
            except Exception:  # our bug: seen (traceback) and counted, costs this message only
                self._discard()
                self.failures += 1
                if self._failure_burst.record():
                    log.exception("%s: failed to decode a message (datagram from %s:%d); "
                                  "message dropped, %s", self.where, *origin,
                                  self._tally(self._failure_burst, self.failures, "failures"))
                continue
            if message is not None:
                self._discard()
                self.messages += 1
                return Incoming(message.command, message.text, binary=message.payload,
                                where=self.where)

    def _discard(self) -> None:
        """Forget the current message, finished or not; the next starts at datagram 0."""
        self.assembler.message_done()
        self.decoder.reset()

    def _tally(self, burst: Burst, total: int, kind: str) -> str:
        return (f"{burst.count} in this burst, {total} {kind} and {self.messages} delivered "
                f"on this connection")

    @property
    def counters(self) -> InputCounters:
        return InputCounters(self.messages, self.assembler.dropped, self.malformed,
                             self.failures)

    @property
    def dropped(self) -> int:
        return self.assembler.dropped
