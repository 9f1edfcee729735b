"""A port's inputs: the listener, and a thread per accepted connection that reads it.

Theory of operation
-------------------
:class:`Inputs` accepts connections on the port's listening socket; each gets an
:class:`InputUnit` and its own thread, which authenticates the peer when the port
found a key in ``auth.conf`` as it opened (:mod:`yarp_lite.auth`, 2 s at most, so a
silent peer only holds its own thread), reads the 8-byte carrier magic, lets the
carrier finish the handshake, then loops over messages, each handled by the entry of
:data:`HANDLERS` for its command:

* data (``d``/``D``) goes to the port's :class:`~yarp_lite.delivery.Delivery`;
* admin Bottles (``a``) and port commands (``/x``, ``!x``, ``~x``, ``*``, ``?``, ``h``)
  are answered by :mod:`yarp_lite.admin`;
* ``q`` ends the connection;
* the reply (if the sender asked for one) and the acknowledgement leave together in
  one write.

A peer's bytes never take a port down: a protocol violation closes that one
connection with a log line naming the peer and the problem.  A flood of connections
that never introduce themselves evicts its own oldest (:data:`MAX_INTRODUCING`), and
past :attr:`Inputs.max_inputs` new connections are refused.
"""

from __future__ import annotations

import errno
import itertools
import logging
import socket
import threading
import time
from collections import OrderedDict
from typing import Callable, Dict, List, Optional, Protocol, Tuple

from yarp_lite import admin, auth
from yarp_lite.admin import Route
from yarp_lite.bottle import Bottle
from yarp_lite.bursts import Burst
from yarp_lite.carriers import PROTOCOL_NOT_FOUND, BottlePayload, Carrier, Incoming, Payload, \
    carrier_for_header
from yarp_lite.contact import Contact
from yarp_lite.delivery import Delivery
from yarp_lite.errors import NetworkError, RemoteProtocolError, YarpError
from yarp_lite.port_outputs import rooted
from yarp_lite.stream import SocketStream, Stream, authenticate

log = logging.getLogger("yarp_lite.port")

#: accept() failures that pass: out of descriptors or memory, a connection aborted early.
_ACCEPT_TRANSIENT = {errno.EMFILE, errno.ENFILE, errno.ENOBUFS, errno.ENOMEM,
                     errno.ECONNABORTED, errno.EPROTO}
#: Accepted connections that have not yet said who they are (authentication and carrier
#: header) kept at most; past it the oldest is closed to let the newest in.  A held flood of
#: silent connections otherwise filled all of a port's inputs, each waiting out its own
#: handshake, and a real client queued behind the flood in the listen backlog: a name
#: server beside two CPU burners did not answer for 20 s (fc27 of 2026-11-28).  A real
#: client introduces itself in milliseconds, so only the silent are ever the oldest.
MAX_INTRODUCING = 64

#: What one message asks of its input: the chunks to write back, and whether to go on.
Handled = Tuple[List, bool]


class InputOwner(Protocol):
    """What the inputs need of their port (:class:`yarp_lite.port.Port`)."""

    name: str
    address: Contact
    credentials: auth.AuthConfig
    max_message: int
    admin_view: admin.PortState
    delivery: Delivery

    @property
    def is_open(self) -> bool: ...


class InputUnit:
    """One accepted connection and the thread reading it."""

    _ids = itertools.count(1)

    def __init__(self, inputs: "Inputs", sock: socket.socket) -> None:
        self.inputs = inputs
        self.port = inputs.port
        self.id = next(self._ids)
        self.stream: Stream = SocketStream(sock, f"{self.port.name} input #{self.id}")
        self.route = Route("", self.port.name, "")
        self.carrier: Optional[Carrier] = None
        self.closing = False
        self.introduced = False     # the handshake is done: a peer that said who it is
        self.thread = threading.Thread(target=self._run, daemon=True,
                                       name=f"{self.port.name} input #{self.id}")

    @property
    def remote_host(self) -> str:
        address = self.stream.remote_address
        return address[0] if address else ""

    def start(self) -> None:
        self.thread.start()

    def close(self) -> None:
        self.closing = True
        self.stream.close()

    def _run(self) -> None:
        port = self.port
        try:
            if not self._handshake():
                return
            source = self.carrier.receiver(self.stream, self.stream.where,  # type: ignore
                                           port.max_message)
            delivery = port.delivery
            while not self.closing:
                message = source.next()
                data = message.command in ("d", "D") and not message.wants_reply
                if data and delivery.latest_only and source.more_waiting():
                    delivery.superseded(message)   # a newer one is already here: not decoded
                    ack = self.carrier.ack_chunk()  # type: ignore[union-attr]
                    if ack:
                        self.stream.write(ack)
                    continue
                if not self._handle(message):
                    break
                if data:
                    delivery.pace()             # what comes meanwhile waits in the socket
        except RemoteProtocolError as exc:
            log.warning("%s: dropping connection from %s: %s", port.name,
                        self.route.source or self.stream.remote_address, exc)
        except NetworkError as exc:
            log.debug("%s: input from %s ended: %s", port.name, self.route.source, exc)
        except Exception:  # a bug must not kill the port, but must be seen
            log.exception("%s: unexpected error on input from %s", port.name, self.route.source)
        finally:
            self.stream.close()
            self.inputs.finished(self)

    def _handshake(self) -> bool:
        port = self.port
        if isinstance(self.stream, SocketStream):
            authenticate(self.stream, auth.Role.ACCEPTOR, port.credentials)
        header = self.stream.read_exact(8)
        carrier = carrier_for_header(header)
        if carrier is None:
            log.warning("%s: unknown protocol from %s (first bytes %r), hanging up",
                        port.name, self.stream.remote_address, header)
            self.stream.write(PROTOCOL_NOT_FOUND)
            return False
        self.carrier = carrier
        sender = carrier.expect_sender(self.stream)
        self.stream = carrier.respond_to_header(self.stream, sender, port.address.port)
        self.route = Route(sender, port.name, carrier.name, carrier.connectionless)
        self.introduced = True
        self.inputs.started(self)
        return True

    def _handle(self, message: Incoming) -> bool:
        """Process one message; False when the connection should close."""
        handler = HANDLERS.get(message.command, InputUnit._not_understood)
        chunks, keep_going = handler(self, message)
        ack = self.carrier.ack_chunk()   # type: ignore[union-attr]
        if ack:
            chunks.append(ack)
        if chunks:
            self.stream.write(*chunks)
        return keep_going

    def _data(self, message: Incoming) -> Handled:
        try:
            reply = self.port.delivery.deliver(message, self)
        except YarpError:
            raise
        except Exception:  # the owner's callback failed: its bug, not the peer's
            log.exception("%s: reader failed on a message from %s; message dropped, "
                          "connection kept", self.port.name, self.route.source)
            reply = None
        if not message.wants_reply:
            return [], True
        if reply is None and not self.port.is_open:
            return [], False     # the port closed before anyone read it: no answer, hang up
        if not isinstance(reply, Payload):
            reply = BottlePayload(reply if reply is not None else Bottle())
        return list(self.carrier.reply_chunks(reply)), True   # type: ignore[union-attr]

    def _admin(self, message: Incoming) -> Handled:
        reply = admin.admin(self.port.admin_view, message.bottle())
        return list(self.carrier.reply_chunks(BottlePayload(reply))), True  # type: ignore

    def _port_command(self, message: Incoming) -> Handled:
        lines = admin.port_command(self.port.admin_view, message.text)
        carrier = self.carrier
        return ([carrier.text_response(lines)] if carrier.text_mode else [], True)  # type: ignore

    def _quit(self, message: Incoming) -> Handled:
        return [], False

    def _not_understood(self, message: Incoming) -> Handled:
        carrier = self.carrier
        return ([carrier.text_response(admin.NOT_UNDERSTOOD)]  # type: ignore[union-attr]
                if carrier.text_mode else [], True)          # type: ignore[union-attr]


#: An input's handling of each message command; any other is not understood.
HANDLERS: Dict[str, Callable[[InputUnit, Incoming], Handled]] = {
    "d": InputUnit._data, "D": InputUnit._data, "a": InputUnit._admin, "q": InputUnit._quit,
    **{command: InputUnit._port_command for command in ("/", "!", "~", "*", "?", "h")}}


class Inputs:
    """The inputs of ``port``: the accept loop, the live connections, their routes."""

    def __init__(self, port: InputOwner) -> None:
        self.port = port
        self._lock = threading.Lock()
        self._changed = threading.Condition(self._lock)
        self._units: Dict[int, InputUnit] = {}
        #: Accepted inputs not introduced yet, oldest first (see :data:`MAX_INTRODUCING`).
        self._introducing: "OrderedDict[int, InputUnit]" = OrderedDict()
        self.max_inputs = 512
        self._refused = Burst()
        self._evicted = Burst()
        self._accept_errors = Burst()
        self._listener: Optional[socket.socket] = None
        self._thread: Optional[threading.Thread] = None

    # -- queries -------------------------------------------------------------------------

    def routes(self) -> List[Route]:
        with self._lock:
            return [unit.route for unit in self._units.values() if unit.carrier is not None]

    def wait_for(self, count: int, timeout: float) -> bool:
        """Wait until ``count`` inputs have introduced themselves; False on timeout."""
        deadline = time.monotonic() + timeout
        with self._changed:
            while len([u for u in self._units.values() if u.carrier is not None]) < count:
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    return False
                self._changed.wait(remaining)
        return True

    # -- lifecycle -----------------------------------------------------------------------

    def listen(self, listener: socket.socket) -> None:
        """Accept on ``listener`` in a thread of its own."""
        self._listener = listener
        self._thread = threading.Thread(target=self._accept_loop, daemon=True,
                                        name=f"{self.port.name} listener")
        self._thread.start()

    def stop_listening(self) -> None:
        """Refuse new connections from now on (the port is closing)."""
        listener = self._listener
        if listener is not None:
            try:
                listener.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass  # already shut: close() below still releases it
            listener.close()

    def close(self) -> None:
        """Stop listening, close every input, and wait (a little) for their threads."""
        self.stop_listening()
        with self._lock:
            units = list(self._units.values())
        for unit in units:
            unit.close()
        current = threading.current_thread()
        if self._thread is not None and self._thread is not current:
            self._thread.join(timeout=2.0)
        for unit in units:
            if unit.thread is not current:
                unit.thread.join(timeout=2.0)

    def remove(self, source: str) -> bool:
        """Close the inputs from ``source``; False if there were none."""
        with self._lock:
            units = [unit for unit in self._units.values() if unit.route.source == source]
        for unit in units:
            unit.close()
        return bool(units)

    # -- accepting -----------------------------------------------------------------------

    def _accept_loop(self) -> None:
        port, listener = self.port, self._listener
        while port.is_open and listener is not None:
            try:
                sock, _ = listener.accept()
            except OSError as exc:
                if not port.is_open or exc.errno not in _ACCEPT_TRANSIENT:
                    break
                # Out of file descriptors (a flood): keep the listener, try again shortly.
                if self._accept_errors.record():
                    log.warning("%s: cannot accept connections: %s (%d in this burst)",
                                port.name, exc.strerror or exc, self._accept_errors.count)
                time.sleep(0.05)
                continue
            unit = self._admit(sock)
            if unit is not None:
                unit.start()
            elif not port.is_open:
                break

    def _admit(self, sock: socket.socket) -> Optional[InputUnit]:
        """An input for an accepted socket, or None (closed: the port closing, a flood)."""
        port = self.port
        with self._lock:
            if not port.is_open:
                sock.close()
                return None
            self._evict_the_oldest_silent()
            if len(self._units) >= self.max_inputs:
                # Flooded: keep serving the connections we have.
                sock.close()
                if self._refused.record():
                    log.warning("%s: %d connections refused, %d already open",
                                port.name, self._refused.count, len(self._units))
                return None
            try:
                unit = InputUnit(self, sock)
            except NetworkError as exc:  # the peer reset before we could look at it
                sock.close()
                log.debug("%s: a connection ended before it started: %s", port.name, exc)
                return None
            self._units[unit.id] = unit
            self._introducing[unit.id] = unit
            return unit

    def _evict_the_oldest_silent(self) -> None:
        """Make room for one more connection still to introduce itself (lock held)."""
        for unit_id, unit in list(self._introducing.items()):
            if unit.introduced or unit_id not in self._units:
                del self._introducing[unit_id]
        while len(self._introducing) >= MAX_INTRODUCING:
            _, oldest = self._introducing.popitem(last=False)
            oldest.close()
            if self._evicted.record():
                log.warning("%s: %d connections closed that had not said who they are while "
                            "newer ones came (a flood?); %d open", self.port.name,
                            self._evicted.count, len(self._units))

    def started(self, unit: InputUnit) -> None:
        """``unit``'s peer introduced itself."""
        route = unit.route
        if rooted(route.source):
            # As YARP: a new connection from the same source replaces old ones.
            with self._lock:
                stale = [other for other in self._units.values()
                         if other is not unit and other.route.source == route.source]
            for other in stale:
                other.close()
            log.info("Receiving input from %s to %s using %s", route.source, route.target,
                     route.carrier)
        with self._changed:
            self._changed.notify_all()

    def finished(self, unit: InputUnit) -> None:
        """``unit``'s thread ends."""
        with self._changed:
            self._units.pop(unit.id, None)
            self._changed.notify_all()
        if unit.carrier is not None and rooted(unit.route.source) and self.port.is_open:
            log.info("Removing input from %s to %s", unit.route.source, unit.route.target)
