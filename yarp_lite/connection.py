"""The sending end of one connection: handshake, messages, replies, acknowledgements.

An :class:`OutgoingConnection` is what a port's output, an RPC client, the
name client and the ``yarp-lite`` tools all use to talk to a remote port.  It
is a thin layer: the carrier does the rituals, the stream does the I/O.  One
connection is used by one thread at a time (a lock makes that so).

:func:`open_stream` is YARP's ``TcpFace::write``, the one way yarp_lite opens
a TCP connection to a port or a name server: connect, then authenticate when
an ``auth.conf`` holds a key (:mod:`yarp_lite.auth`).
"""

from __future__ import annotations

import socket
import threading
from typing import Optional

from yarp_lite import auth
from yarp_lite.bottle import Bottle
from yarp_lite.carriers import Carrier, Payload, make_carrier
from yarp_lite.contact import Contact
from yarp_lite.errors import LocalProtocolError, NetworkError, RemoteProtocolError, YarpError
from yarp_lite.stream import SocketStream, Stream, authenticate

#: How long a refused connection to a registered port is retried, in seconds.
#: Real YARP registers a port before its socket listens, so a port that has
#: just appeared in the name server may refuse connections for a moment.
REFUSED_RETRY = 1.5


def open_stream(host: str, port: int, *, where: str, credentials: auth.AuthConfig,
                timeout: Optional[float] = 10.0, retry_refused: float = 0.0) -> SocketStream:
    """Connect to ``host:port`` and authenticate as the connecting side.

    ``retry_refused`` is passed to :meth:`SocketStream.connect`: only a
    refused connection is retried.  Authentication failures never are.
    """
    stream = SocketStream.connect(host, port, timeout=timeout, where=where,
                                  retry_refused=retry_refused)
    try:
        authenticate(stream, auth.Role.CONNECTOR, credentials)
    except YarpError:
        stream.close()
        raise
    return stream


class OutgoingConnection:
    """A connection we initiated to ``target`` (host/port known) with ``carrier``."""

    def __init__(self, carrier: Carrier, stream: Stream, sender: str, target: str) -> None:
        self.carrier = carrier
        self.stream = stream
        self.sender = sender
        self.target = target
        self.lock = threading.Lock()
        self.closed = False
        #: A message sent by :meth:`send_unless_busy` whose acknowledgement is not read yet.
        self._ack_owed = False

    @classmethod
    def open(cls, contact: Contact, sender: str, carrier: str = "",
             timeout: Optional[float] = 10.0, retry_refused: float = REFUSED_RETRY,
             credentials: Optional[auth.AuthConfig] = None) -> "OutgoingConnection":
        """Connect to ``contact`` and complete the header phase.

        A refused connection is retried for ``retry_refused`` seconds (see
        :data:`REFUSED_RETRY`; only ECONNREFUSED, never a timeout or an
        authentication failure); probes asking whether a port is alive *now*
        pass 0.  ``credentials`` default to what :func:`yarp_lite.auth.load`
        finds, looked up per connection as YARP does.
        """
        if not contact.valid or not contact.host:
            raise NetworkError(f"no address known for {contact.name or contact}")
        chosen = make_carrier(carrier or contact.carrier or "tcp")
        credentials = credentials if credentials is not None else auth.load()
        stream: Stream = open_stream(
            contact.host, contact.port, timeout=timeout, retry_refused=retry_refused,
            credentials=credentials,
            where=f"{chosen.name} {sender} -> {contact.name or contact.uri()}")
        try:
            if timeout:
                stream.set_timeout(timeout)
            chosen.send_header(stream, sender)
            try:
                stream = chosen.expect_header_reply(stream)
            except RemoteProtocolError as exc:
                raise auth.unexpected_answer(credentials, "", str(exc)) from exc
            if isinstance(stream, SocketStream):
                stream.set_timeout(None)
        except YarpError:
            stream.close()
            raise
        return cls(chosen, stream, sender, contact.name)

    @property
    def carrier_name(self) -> str:
        return self.carrier.name

    def send(self, command: str, payload: Optional[Payload] = None,
             want_reply: bool = False, timeout: Optional[float] = None) -> Optional[Bottle]:
        """Send one message; return the reply Bottle when ``want_reply``.

        ``command`` is ``d`` (data), ``a`` (admin data) or a port command such
        as ``/read`` or ``*``; data without a wanted reply goes as ``D``.
        """
        if self.closed:
            raise NetworkError(f"{self.stream.where}: connection closed")
        if want_reply and not self.carrier.supports_reply:
            raise LocalProtocolError(
                f"carrier {self.carrier.name} cannot carry replies (try tcp or text_ack)")
        if command[:1] == "d" and not want_reply:
            command = "D" + command[1:]
        with self.lock:
            if timeout is not None and isinstance(self.stream, SocketStream):
                self.stream.set_timeout(timeout)
            try:
                self._settle_ack()
                self.carrier.write_message(self.stream, command, payload)
                reply = self.carrier.read_reply(self.stream) if want_reply else None
                if self.carrier.requires_ack:
                    self.carrier.read_ack(self.stream)
            except YarpError:
                self.abort()
                raise
            finally:
                if timeout is not None and isinstance(self.stream, SocketStream) \
                        and not self.closed:
                    self.stream.set_timeout(None)
        return reply

    def send_unless_busy(self, command: str, payload: Payload) -> bool:
        """Send one data message without waiting for its acknowledgement; False, and
        nothing sent, while the reader has not acknowledged the previous one.

        YARP's non-strict writes skip a connection still busy with the previous
        message: one slow ``tcp`` reader (an acknowledgement per message) then
        cannot hold up a 500 Hz stream's other readers, nor the writer.
        """
        if self.closed:
            raise NetworkError(f"{self.stream.where}: connection closed")
        if not self.lock.acquire(blocking=False):
            return False
        try:
            if self._ack_owed:
                if not self.stream.readable_now():
                    return False
                self._settle_ack()
            self.carrier.write_message(self.stream, "D" + command[1:], payload)
            self._ack_owed = self.carrier.requires_ack
            return True
        except YarpError:
            self.abort()
            raise
        finally:
            self.lock.release()

    def _settle_ack(self) -> None:
        if self._ack_owed:
            self._ack_owed = False
            self.carrier.read_ack(self.stream)

    def send_text_command(self, command: str, timeout: float = 5.0) -> list:
        """Send a port command on a text connection and collect its answer lines."""
        with self.lock:
            self.carrier.write_message(self.stream, command, None)
            lines = []
            if isinstance(self.stream, SocketStream):
                self.stream.set_timeout(timeout)
                try:
                    while True:
                        line = self.stream.read_line()
                        if self.carrier.requires_ack and line == "<ACK>":
                            break
                        lines.append(line)
                except NetworkError:
                    pass  # an answer no <ACK> ends is ended by the timeout or hang-up
            return lines

    def peer_closed(self) -> bool:
        """Whether the peer has closed or reset this idle connection.

        A port learns that a reader died only when it next writes; until then
        ``[list] [out]`` would still name the dead reader, and a name server
        asking "already connected?" before reconnecting a persistent
        connection would leave it broken.  One non-blocking peek answers;
        a connection busy sending, or not over a socket, counts as alive.
        """
        if self.closed:
            return True
        if self.carrier.connectionless or not isinstance(self.stream, SocketStream) \
                or not self.lock.acquire(blocking=False):
            return False
        try:
            return self.stream.sock.recv(1, socket.MSG_PEEK | socket.MSG_DONTWAIT) == b""
        except (BlockingIOError, InterruptedError):
            return False
        except OSError:
            return True
        finally:
            self.lock.release()

    def abort(self) -> None:
        """Drop the connection without saying goodbye."""
        self.closed = True
        self.stream.close()

    def close(self) -> None:
        """Say ``q`` (when the carrier allows) and close."""
        if self.closed:
            return
        try:
            if self.carrier.can_escape and not self.carrier.connectionless:
                with self.lock:
                    self._settle_ack()
                    self.carrier.write_message(self.stream, "q", None)
                    if self.carrier.requires_ack:
                        self.stream.set_timeout(2.0) if isinstance(self.stream, SocketStream) \
                            else None
                        self.carrier.read_ack(self.stream)
        except YarpError:
            pass  # peer already gone: abort() below releases our end
        finally:
            self.abort()
