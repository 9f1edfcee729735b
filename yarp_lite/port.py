"""Ports: named endpoints that register, accept connections, send and receive.

Theory of operation
-------------------
A port owns a listening TCP socket registered with the name server.  The
listener thread accepts connections; each accepted connection gets its own
input thread, which authenticates the peer when the port found a key in
``auth.conf`` as it opened (:mod:`yarp_lite.auth`, 2 s at most, so a silent
peer only holds its own thread), reads the 8-byte carrier magic, lets the
carrier finish the handshake, then loops over messages:

* data (``d``/``D``) goes to the port's owner through :meth:`Port._deliver`
  (a callback, a blocking :meth:`Port.read`, or a subclass's buffer);
* admin Bottles (``a``) and port commands (``/x``, ``!x``, ``~x``, ``*``, ``q``)
  are answered by :mod:`yarp_lite.admin`;
* the reply (if the sender asked for one) and the acknowledgement leave
  together in one write.

Outputs are :class:`~yarp_lite.connection.OutgoingConnection`s the port
initiated (on request of its owner, a ``yarp connect``, or the name server
restoring a persistent connection).  :meth:`Port.write` sends on all of them
from the calling thread; a broken output is dropped and logged, never raised
at the writer.  A port told to :meth:`Port.hold_for_late_readers` keeps its
recent messages and hands each new output what its reader has not taken
(:mod:`yarp_lite.held`); real YARP ports hold nothing.

A peer's bytes never take a port down: a protocol violation closes that one
connection with a log line naming the peer and the problem.  While a port is
open, :class:`RegistrationKeeper` checks every few seconds that the name
server still knows it, and registers it again after a name server restart.
"""

from __future__ import annotations

import contextlib
import errno
import itertools
import logging
import socket
import threading
import time
from collections import OrderedDict
from typing import Callable, Dict, Iterator, List, Optional, Sequence, Tuple, Union

from yarp_lite import admin, auth
from yarp_lite.admin import Route
from yarp_lite.bottle import Bottle
from yarp_lite.bursts import Burst
from yarp_lite.carriers import (PROTOCOL_NOT_FOUND, SUPPORTED, BottlePayload, Carrier,
                                Incoming, Payload, carrier_base_name, carrier_for_header,
                                send_period)
from yarp_lite.connection import REFUSED_RETRY, OutgoingConnection
from yarp_lite.contact import Contact, apply_environment, check_port_name
from yarp_lite.errors import (AuthenticationError, LocalProtocolError, NetworkError,
                              RemoteProtocolError, YarpError)
from yarp_lite.framing import DEFAULT_MAX_MESSAGE
from yarp_lite.held import Held, HeldMessages, HoldPolicy
from yarp_lite.nameclient import NameClient
from yarp_lite.stream import SocketStream, Stream, authenticate

log = logging.getLogger("yarp_lite.port")

Reply = Optional[Union[Bottle, Sequence]]
#: accept() failures that pass: out of descriptors or memory, a connection aborted early.
_ACCEPT_TRANSIENT = {errno.EMFILE, errno.ENFILE, errno.ENOBUFS, errno.ENOMEM,
                     errno.ECONNABORTED, errno.EPROTO}
Reader = Callable[[Bottle], Reply]
#: Accepted connections that have not yet said who they are (authentication and carrier
#: header) kept at most; past it the oldest is closed to let the newest in.  A held flood of
#: silent connections otherwise filled all of a port's inputs, each waiting out its own
#: handshake, and a real client queued behind the flood in the listen backlog: a name
#: server beside two CPU burners did not answer for 20 s (fc27 of 2026-11-28).  A real
#: client introduces itself in milliseconds, so only the silent are ever the oldest.
MAX_INTRODUCING = 64


def _rooted(name: str) -> bool:
    return name.startswith("/")


class _InputUnit:
    """One accepted connection and the thread reading it."""

    _ids = itertools.count(1)

    def __init__(self, port: "Port", sock: socket.socket) -> None:
        self.port = port
        self.id = next(self._ids)
        self.stream: Stream = SocketStream(sock, f"{port.name} input #{self.id}")
        self.route = Route("", port.name, "")
        self.carrier: Optional[Carrier] = None
        self.closing = False
        self.introduced = False     # the handshake is done: a peer that said who it is
        self.thread = threading.Thread(target=self._run, daemon=True,
                                       name=f"{port.name} input #{self.id}")

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
            source = self.carrier.receiver(self.stream, self.stream.where, port.max_message)
            latest_only = port._latest_only
            while not self.closing:
                message = source.next()
                data = message.command in ("d", "D") and not message.wants_reply
                if latest_only and data and source.more_waiting():
                    port._superseded(message)   # a newer one is already here: not decoded
                    ack = self.carrier.ack_chunk()
                    if ack:
                        self.stream.write(ack)
                    continue
                if not self._handle(message):
                    break
                if latest_only and data and port._min_interval:
                    port._pace()                # what comes meanwhile waits in the socket
        except RemoteProtocolError as exc:
            log.warning("%s: dropping connection from %s: %s", port.name,
                        self.route.source or self.stream.remote_address, exc)
        except NetworkError as exc:
            log.debug("%s: input from %s ended: %s", port.name, self.route.source, exc)
        except Exception:  # a bug must not kill the port, but must be seen
            log.exception("%s: unexpected error on input from %s", port.name, self.route.source)
        finally:
            self.stream.close()
            port._input_finished(self)

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
        port._input_started(self)
        return True

    def _handle(self, message: Incoming) -> bool:
        """Process one message; False when the connection should close."""
        port, carrier = self.port, self.carrier
        command = message.command
        chunks: List = []
        keep_going = True
        if command in ("d", "D"):
            try:
                reply = port._deliver(message, self)
            except YarpError:
                raise
            except Exception:  # the owner's callback failed: its bug, not the peer's
                log.exception("%s: reader failed on a message from %s; message dropped, "
                              "connection kept", port.name, self.route.source)
                reply = None
            if message.wants_reply:
                if not isinstance(reply, Payload):
                    reply = BottlePayload(reply if reply is not None else Bottle())
                chunks += carrier.reply_chunks(reply)
        elif command == "a":
            reply = admin.admin(port._admin_view, message.bottle())
            chunks += carrier.reply_chunks(BottlePayload(reply))
        elif command == "q":
            keep_going = False
        elif command in ("/", "!", "~", "*", "?", "h"):
            lines = admin.port_command(port._admin_view, message.text)
            if carrier.text_mode:
                chunks.append(carrier.text_response(lines))
        elif carrier.text_mode:
            chunks.append(carrier.text_response(admin.NOT_UNDERSTOOD))
        ack = carrier.ack_chunk()
        if ack:
            chunks.append(ack)
        if chunks:
            self.stream.write(*chunks)
        return keep_going


class _OutputUnit:
    __slots__ = ("connection", "route", "spec", "gate", "period", "next_due")

    def __init__(self, connection: OutgoingConnection, route: Route, spec: str,
                 period: float = 0.0) -> None:
        self.connection = connection
        self.route = route
        self.spec = spec
        #: The reader's ``+period.S`` (0: every message); ``next_due`` its next send.
        self.period = period
        self.next_due = 0.0
        #: held by a new connection until its held messages are handed over: later writes
        #: wait behind them, so the reader sees every message in the order written
        self.gate = threading.Lock()

    def due(self, now: float) -> bool:
        """Whether a stream's message written ``now`` goes to this output: every one without
        a period, else about one per period on average (each at most a quarter of a period
        early, so a 500 Hz stream read at 250 Hz is sent every other message, not every
        third when the writer's ticks jitter)."""
        if not self.period:
            return True
        if now < self.next_due - self.period / 4:
            return False
        late = now - self.next_due
        self.next_due = now + self.period if late > self.period else self.next_due + self.period
        return True


class _AdminView:
    """The :class:`yarp_lite.admin.PortState` face of a port."""

    def __init__(self, port: "Port") -> None:
        self._port = port

    @property
    def name(self) -> str:
        return self._port.name

    def address(self) -> Contact:
        return self._port.address

    def input_routes(self) -> List[Route]:
        return self._port.input_routes()

    def output_routes(self) -> List[Route]:
        return self._port.output_routes()

    def add_output(self, target: str) -> Tuple[bool, str]:
        return self._port._add_output(target)

    def remove_output(self, target: str) -> bool:
        return self._port.remove_output(target)

    def remove_input(self, source: str) -> bool:
        return self._port.remove_input(source)

    def properties(self) -> Dict[str, object]:
        return self._port.properties

    def admin_fallback(self, command: Bottle) -> Optional[Bottle]:
        handler = self._port.admin_reader
        return Bottle(handler(command) or []) if handler is not None else None


class _Handoff:
    """Rendezvous between input threads and a blocking :meth:`Port.read`.

    Like YARP's port adapter, a message waits until its reader takes it (so a
    plain Port never buffers), and a reader that promised a reply holds the
    sender until :meth:`Port.reply`.
    """

    def __init__(self) -> None:
        self.cond = threading.Condition()
        self.serial = threading.Lock()
        self.item: Optional[Tuple[Incoming, Route]] = None
        self.taken = False
        self.readers = 0
        self.reply_wanted = False
        self.reply_value: Optional[Bottle] = None
        self.reply_ready = False
        self.closed = False

    def offer(self, message: Incoming, route: Route) -> Optional[Bottle]:
        with self.serial:
            with self.cond:
                if self.closed:
                    return None
                self.item, self.taken = (message, route), False
                self.reply_ready, self.reply_value, self.reply_wanted = False, None, False
                self.cond.notify_all()
                # One wake-up: when the reader took it (no reply promised), or replied.
                while not self.closed and not (
                        self.taken and (not self.reply_wanted or self.reply_ready)):
                    self.cond.wait()
                return self.reply_value

    def take(self, timeout: Optional[float], will_reply: bool) -> Optional[Tuple[Incoming, Route]]:
        deadline = None if timeout is None else time.monotonic() + timeout
        with self.cond:
            self.readers += 1
            try:
                while (self.item is None or self.taken) and not self.closed:
                    remaining = None if deadline is None else deadline - time.monotonic()
                    if remaining is not None and remaining <= 0:
                        return None
                    self.cond.wait(remaining)
                if self.closed:
                    return None
                item = self.item
                self.taken = True
                self.item = None
                self.reply_wanted = will_reply and item[0].wants_reply
                if not self.reply_wanted:  # a promised reply wakes the sender instead
                    self.cond.notify_all()
                return item
            finally:
                self.readers -= 1

    def give_reply(self, reply: Optional[Bottle]) -> bool:
        with self.cond:
            if not self.reply_wanted or self.reply_ready:
                return False
            self.reply_value, self.reply_ready = reply, True
            self.cond.notify_all()
            return True

    def close(self) -> None:
        with self.cond:
            self.closed = True
            self.cond.notify_all()


class Port:
    """A YARP port: open it under a name, connect it, write and read Bottles.

    ``reader``, if given, is called in the receiving thread with each Bottle
    (and, with ``reader_wants_source``, the sending port's name as second
    argument); what it returns is the reply sent back when the sender asked
    for one.  Without it, :meth:`read` blocks until a message arrives.
    """

    #: A message that a newer one already waiting behind supersedes is skipped undecoded
    #: (a latest-only reader that fell behind catches up at once instead of working through
    #: the backlog in its socket: :class:`~yarp_lite.buffered_port.BufferedPort`).
    _latest_only = False
    #: Latest-only: the least time between two messages delivered from one connection.
    _min_interval = 0.0

    def _pace(self) -> None:
        """An input connection's wait after a delivery, under :attr:`_min_interval`."""
        time.sleep(self._min_interval)

    def __init__(self, name: Optional[str] = None, *, reader: Optional[Reader] = None,
                 nameclient: Optional[NameClient] = None, timeout: Optional[float] = None,
                 max_message: int = DEFAULT_MAX_MESSAGE, rpc: bool = False,
                 register: bool = True, reader_wants_source: bool = False) -> None:
        self.nameclient = nameclient or NameClient()
        self.reader = reader
        self.reader_wants_source = reader_wants_source
        self.admin_reader: Optional[Callable[[Bottle], Reply]] = None
        self.timeout = timeout
        self.max_message = max_message
        self.rpc = rpc
        self.register = register
        self.name = ""
        self.address = Contact()
        self.properties: Dict[str, object] = {}
        #: The key accepted connections must prove (read from auth.conf at open).
        self.credentials = auth.DISABLED
        self.envelope = ""
        #: Writes skipped for a connection still busy (``write(..., skip_busy=True)``).
        self.skipped_writes = 0
        self._admin_view = _AdminView(self)
        self._lock = threading.RLock()
        self._inputs: Dict[int, _InputUnit] = {}
        self._outputs: Dict[str, _OutputUnit] = {}
        self._listener: Optional[socket.socket] = None
        self.max_inputs = 512
        self._refused = Burst()
        self._evicted = Burst()
        #: Accepted inputs not introduced yet, oldest first (see :data:`MAX_INTRODUCING`).
        self._introducing: "OrderedDict[int, _InputUnit]" = OrderedDict()
        self._accept_errors = Burst()
        self._accept_thread: Optional[threading.Thread] = None
        self._handoff = _Handoff()
        self._used_for_read = reader is not None
        self._open = False
        self._closing = False
        self._input_events = threading.Condition(self._lock)
        #: what the port keeps for readers that connect later (None: nothing, as YARP)
        self.held: Optional[HeldMessages] = None
        if name is not None:
            self.open(name)

    # -- lifecycle ---------------------------------------------------------------

    def open(self, name: str = "...", host: str = "", socket_number: int = 0,
             wait: Optional[float] = None) -> "Port":
        """Register ``name`` (after ``YARP_RENAME_*``/``YARP_PORT_PREFIX``) and listen.

        ``wait`` (seconds, ``math.inf`` for ever) keeps trying while the name
        server is unreachable, saying so every few seconds, so programs can
        start before it.  ``host``/``socket_number`` pin the address of an
        unregistered port (the name server's own port is one).
        """
        if self._open:
            raise LocalProtocolError(f"port {self.name} is already open")
        name = check_port_name(apply_environment(name))
        if wait and self.register:
            self._wait_for_name_server(name, wait)
        self.credentials = auth.load(self.nameclient.environ)
        listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        listener.settimeout(None)   # accept blocks, whatever socket.setdefaulttimeout() says
        listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            if self.register:
                contact = self.nameclient.register(name)
                try:
                    listener.bind(("", contact.port))
                except OSError as exc:
                    if exc.errno != errno.EADDRINUSE:
                        raise
                    # Another name server handed out the same number: take a free one.
                    listener.bind(("", 0))
                    contact = self.nameclient.register(contact.name, "tcp", contact.host,
                                                       listener.getsockname()[1])
            else:
                listener.bind((host, socket_number))
                contact = Contact(name, "tcp", host or "127.0.0.1", listener.getsockname()[1])
            listener.listen(64)
        except OSError as exc:  # no socket to listen on: the machine's fault, not the caller's
            listener.close()
            raise NetworkError(f"{name}: cannot listen: {exc.strerror or exc}") from exc
        except BaseException:
            listener.close()
            raise
        self.name, self.address, self._listener = contact.name, contact, listener
        self._open, self._closing = True, False
        self._handoff = _Handoff()
        self._accept_thread = threading.Thread(target=self._accept_loop, daemon=True,
                                               name=f"{self.name} listener")
        self._accept_thread.start()
        if self.register:
            try:
                self.nameclient.describe_port(self.name)
                self.nameclient.announce(self.name)
            except NetworkError as exc:
                log.warning("%s: could not describe the port to the name server: %s",
                            self.name, exc)
            RegistrationKeeper.instance().add(self)
        log.info("Port %s active at %s", self.name, self.address.uri())
        return self

    def _wait_for_name_server(self, name: str, wait: float) -> None:
        deadline = time.monotonic() + wait
        announced = 0.0
        while not self.nameclient.ping():
            now = time.monotonic()
            if now > deadline:
                raise NetworkError(f"{name}: no name server for namespace "
                                   f"{self.nameclient.namespace} after {wait:g} s")
            if now - announced > 5.0:
                try:
                    where = self.nameclient.server_address()
                    place = f"{where.host}:{where.port}"
                except NetworkError:
                    place = "(no yarp.conf yet)"
                log.info("%s: waiting for the name server %s at %s", name,
                         self.nameclient.namespace, place)
                announced = now
            time.sleep(0.5)

    def close(self) -> None:
        """Unregister, drop every connection (saying goodbye on outputs) and stop."""
        with self._lock:
            if not self._open:
                return
            self._open, self._closing = False, True
            inputs = list(self._inputs.values())
            outputs = list(self._outputs.values())
            self._outputs.clear()
        RegistrationKeeper.instance().remove(self)
        if self.register:
            try:
                self.nameclient.unregister(self.name)
            except YarpError as exc:
                log.debug("%s: unregister failed: %s", self.name, exc)
        listener = self._listener
        if listener is not None:
            try:
                listener.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass  # already shut: close() below still releases it
            listener.close()
        self._handoff.close()
        for output in outputs:
            self._log_output_removed(output)
            output.connection.close()
        for unit in inputs:
            unit.close()
        if self._accept_thread is not None and self._accept_thread is not threading.current_thread():
            self._accept_thread.join(timeout=2.0)
        for unit in inputs:
            if unit.thread is not threading.current_thread():
                unit.thread.join(timeout=2.0)

    def __enter__(self) -> "Port":
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    @property
    def is_open(self) -> bool:
        return self._open

    def hold_for_late_readers(self, count: int, max_age: float) -> None:
        """Keep the last ``count`` messages written, none older than ``max_age`` seconds,
        and send each new output connection first the ones its reader has not taken
        (:mod:`yarp_lite.held`): for messages that say something once, which a reader
        connecting (again) a moment after they were written must not miss.  The port
        keeps each written Bottle: do not change one after writing it."""
        with self._lock:
            self.held = HeldMessages(HoldPolicy(count, max_age))

    # -- connections ---------------------------------------------------------------

    def add_output(self, target: str, carrier: str = "", quiet: bool = False) -> bool:
        """Connect this port's output to ``target`` (``/name`` or ``udp://name``).

        ``quiet`` is for callers that retry on their own: a failure is not
        logged, and a refused connection is not retried either (a loop over
        many stale registrations would otherwise wait on each of them).
        """
        ok, message = self._add_output(f"{carrier}:/{target}" if carrier else target,
                                       only_if_needed=True,
                                       retry_refused=0.0 if quiet else REFUSED_RETRY)
        if not ok and not quiet:
            log.warning("%s", message)
        return ok

    def _add_output(self, spec: str, only_if_needed: bool = False,
                    retry_refused: float = REFUSED_RETRY) -> Tuple[bool, str]:
        """Connect to ``spec``; a connection to the same port is replaced.

        ``only_if_needed`` keeps an existing connection with the right carrier
        (``Port::addOutput``); the admin ``[add]`` and ``/port`` commands always
        reconnect, as in YARP, which also clears a connection to a dead peer.
        A refused connection is retried for ``retry_refused`` seconds: the
        target may have registered without listening yet.
        """
        requested = Contact.parse(spec)
        if self.rpc and self._outputs and requested.name not in self._outputs:
            return False, "RPC output already connected"
        try:
            address = requested if requested.host else self.nameclient.query(requested.name)
        except AuthenticationError as exc:
            return False, f"Cannot connect to {spec}: {exc}"
        except NetworkError:
            address = None
        if address is None or not address.valid:
            return False, f"Do not know how to connect to {spec}"
        carrier = requested.carrier or address.carrier or "tcp"
        try:
            period = send_period(carrier)
        except LocalProtocolError as exc:
            return False, f"Cannot connect to {spec}: {exc}"
        self._remove_closed_outputs()
        existing = self._outputs.get(address.name)
        if only_if_needed and existing is not None and \
                existing.route.carrier == carrier_base_name(carrier) and existing.period == period:
            return True, f"Desired connection already present from {self.name} to {spec}"
        self.remove_output(address.name, quiet=True)
        try:
            connection = OutgoingConnection.open(address, self.name, carrier,
                                                 timeout=self.timeout or 10.0,
                                                 retry_refused=retry_refused)
        except AuthenticationError as exc:
            return False, f"Cannot connect to {spec}: {exc}"
        except YarpError as exc:
            log.debug("%s: cannot connect to %s: %s", self.name, spec, exc)
            return False, f"Cannot connect to {spec}"
        route = Route(self.name, address.name, connection.carrier_name,
                      connection.carrier.connectionless)
        unit = _OutputUnit(connection, route, spec, period)
        with self._lock:
            if not self._open:
                connection.close()
                return False, f"Cannot connect to {spec}"
            self._outputs[address.name] = unit
            owed = self.held.owed(route.target) if self.held is not None else []
            if owed:
                unit.gate.acquire()     # a fresh lock: free; writes to it wait from now on
        if _rooted(route.target) and _rooted(route.source):
            log.info("Sending output from %s to %s using %s%s", route.source, route.target,
                     route.carrier, f" (about one message every {period:g} s of a stream)"
                     if period else "")
        if owed and not self._hand_over(unit, owed):
            return False, f"Cannot connect to {spec}: it left while taking held messages"
        return True, f"Added connection from {self.name} to {spec}"

    def _hand_over(self, unit: _OutputUnit, owed: List[Held]) -> bool:
        """Send a new output the held messages its reader has not taken, then let the
        writes waiting at its gate through; False (and the output dropped) if it failed."""
        target = unit.route.target
        try:
            for held in owed:
                unit.connection.send(held.command, held.payload, timeout=self.timeout)
                with self._lock:
                    self.held.handed(held, target)
            log.debug("%s: handed %d held message(s) to %s", self.name, len(owed), target)
            return True
        except YarpError as exc:
            log.info("%s: output to %s failed while taking held messages (%s); removing it",
                     self.name, target, exc)
            self._drop_output(unit)
            return False
        finally:
            unit.gate.release()

    def remove_output(self, target: str, quiet: bool = False) -> bool:
        target = Contact.parse(target).name or target
        with self._lock:
            unit = self._outputs.pop(target, None)
        if unit is None:
            return False
        if not quiet:
            self._log_output_removed(unit)
        if unit.connection.carrier.connectionless:
            # The receiver cannot see a udp sender leave: tell it out of band.
            threading.Thread(target=self._disconnect_input_remotely, args=(unit,),
                             daemon=True).start()
        unit.connection.close()
        return True

    def _disconnect_input_remotely(self, unit: _OutputUnit) -> None:
        try:
            contact = self.nameclient.query(unit.route.target)
            if contact is not None:
                connection = OutgoingConnection.open(contact, "admin", "text", timeout=2.0)
                connection.send_text_command(f"~{self.name}", timeout=1.0)
                connection.abort()
        except YarpError as exc:
            log.warning("%s: cannot tell %s this udp output is gone (%s); it may "
                        "still list the input", self.name, unit.route.target, exc)

    def remove_input(self, source: str) -> bool:
        with self._lock:
            units = [unit for unit in self._inputs.values() if unit.route.source == source]
        for unit in units:
            unit.close()
        return bool(units)

    def _log_output_removed(self, unit: _OutputUnit) -> None:
        if _rooted(unit.route.target) and _rooted(unit.route.source):
            log.info("Removing output from %s to %s", unit.route.source, unit.route.target)

    def input_routes(self) -> List[Route]:
        with self._lock:
            return [unit.route for unit in self._inputs.values() if unit.carrier is not None]

    def output_routes(self) -> List[Route]:
        """The live output connections (one whose reader has gone is removed first)."""
        self._remove_closed_outputs()
        with self._lock:
            return [unit.route for unit in self._outputs.values()]

    def _remove_closed_outputs(self) -> None:
        with self._lock:
            gone = [unit for unit in self._outputs.values() if unit.connection.peer_closed()]
        for unit in gone:
            self._drop_output(unit)

    @property
    def input_count(self) -> int:
        return len(self.input_routes())

    @property
    def output_count(self) -> int:
        return len(self.output_routes())

    @property
    def has_outputs(self) -> bool:
        """Whether any output is connected, without asking each socket whether its reader
        is still alive (:attr:`output_count` does): for a writer deciding every tick whether
        to encode at all.  A dead reader is found, and dropped, by the next write."""
        return bool(self._outputs)

    def wait_for_inputs(self, count: int = 1, timeout: float = 10.0) -> bool:
        deadline = time.monotonic() + timeout
        with self._input_events:
            while self.input_count < count:
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    return False
                self._input_events.wait(remaining)
        return True

    # -- writing -----------------------------------------------------------------

    def write(self, bottle: Union[Bottle, Sequence, Payload], envelope: str = "", *,
              skip_busy: bool = False) -> bool:
        """Send to every output; False if any output failed (and was dropped).

        ``envelope`` travels beside the data, as YARP's ``Port::setEnvelope``
        sends it (a Stamp is ``"count time"``); readers see it as ``envelope``.
        ``skip_busy`` (a stream where only the newest matters): never wait for a
        reader's acknowledgement, and skip a connection still waiting for one
        (:attr:`skipped_writes` counts them), or one whose reader asked for fewer messages
        (``+period.S``: :meth:`_OutputUnit.due`).
        """
        payload = bottle if isinstance(bottle, Payload) else BottlePayload(bottle)
        command = f"D {envelope}" if envelope else "D"
        with self._lock:
            outputs = list(self._outputs.values())
            held = self.held.written(command, payload) if self.held is not None else None
        all_ok = True
        now = time.monotonic() if skip_busy else 0.0
        for unit in outputs:
            if skip_busy and not unit.due(now):
                continue
            try:
                sent = self._send_to(unit, command, payload, skip_busy)
            except YarpError as exc:
                all_ok = False
                log.info("%s: output to %s failed (%s); removing it", self.name,
                         unit.route.target, exc)
                self._drop_output(unit)
                continue
            if not sent:
                self.skipped_writes += 1
            elif held is not None:
                with self._lock:
                    self.held.taken(held, unit.route.target)
        return all_ok

    def _send_to(self, unit: _OutputUnit, command: str, payload: Payload,
                 skip_busy: bool) -> bool:
        """One message to one output, after any held messages it is still being handed;
        False when skipped (``skip_busy`` and that output busy)."""
        if not skip_busy:
            with unit.gate:
                unit.connection.send(command, payload, timeout=self.timeout)
            return True
        if not unit.gate.acquire(blocking=False):
            return False
        try:
            return unit.connection.send_unless_busy(command, payload)
        finally:
            unit.gate.release()

    def write_with_reply(self, bottle: Union[Bottle, Sequence],
                         timeout: Optional[float] = None) -> Optional[Bottle]:
        """Send to the first output and wait for its reply (YARP's write(b, reply))."""
        with self._lock:
            outputs = list(self._outputs.values())
        if not outputs:
            return None
        unit = outputs[0]
        try:
            return unit.connection.send("d", BottlePayload(bottle), want_reply=True,
                                        timeout=timeout if timeout is not None else self.timeout)
        except YarpError as exc:
            log.info("%s: request to %s failed (%s); removing the connection", self.name,
                     unit.route.target, exc)
            self._drop_output(unit)
            raise

    def _drop_output(self, unit: _OutputUnit) -> None:
        with self._lock:
            removed = self._outputs.get(unit.route.target) is unit
            if removed:
                del self._outputs[unit.route.target]
        unit.connection.abort()
        if removed:
            self._log_output_removed(unit)

    # -- reading -----------------------------------------------------------------

    def read(self, timeout: Optional[float] = None, will_reply: bool = False) -> Optional[Bottle]:
        """Wait for the next Bottle; None on timeout or close.

        With ``will_reply``, the sender is held until :meth:`reply`.
        """
        if self.reader is not None:
            raise LocalProtocolError(f"{self.name} delivers to a callback; read() is unused")
        self._used_for_read = True
        item = self._handoff.take(timeout, will_reply)
        if item is None:
            return None
        message, _ = item
        self.envelope = message.envelope
        return message.bottle()

    def reply(self, bottle: Union[Bottle, Sequence]) -> bool:
        """Answer the message taken by ``read(will_reply=True)``."""
        return self._handoff.give_reply(bottle if isinstance(bottle, Bottle) else Bottle(bottle))

    def _superseded(self, message: Incoming) -> None:
        """A data message skipped for a newer one (latest-only ports count them)."""

    def _deliver(self, message: Incoming, unit: "_InputUnit") -> Union[None, Bottle, Payload]:
        """Hand one data message to the owner; return its reply, if any."""
        route = unit.route
        if message.envelope:
            self.envelope = message.envelope
        if self.reader is not None:
            reply = self.reader(message.bottle(), route.source) if self.reader_wants_source \
                else self.reader(message.bottle())
            if reply is None:
                return None
            return reply if isinstance(reply, Bottle) else Bottle(reply)
        if not self._used_for_read:
            log.debug("%s: nobody reads this port; dropping a message from %s",
                      self.name, route.source)
            return None
        return self._handoff.offer(message, route)

    # -- input bookkeeping -----------------------------------------------------------

    def _accept_loop(self) -> None:
        listener = self._listener
        while self._open and listener is not None:
            try:
                sock, _ = listener.accept()
            except OSError as exc:
                if not self._open or exc.errno not in _ACCEPT_TRANSIENT:
                    break
                # Out of file descriptors (a flood): keep the listener, try again shortly.
                if self._accept_errors.record():
                    log.warning("%s: cannot accept connections: %s (%d in this burst)",
                                self.name, exc.strerror or exc, self._accept_errors.count)
                time.sleep(0.05)
                continue
            with self._lock:
                if not self._open:
                    sock.close()
                    break
                self._evict_the_oldest_silent()
                if len(self._inputs) >= self.max_inputs:
                    # Flooded: keep serving the connections we have.
                    sock.close()
                    if self._refused.record():
                        log.warning("%s: %d connections refused, %d already open",
                                    self.name, self._refused.count, len(self._inputs))
                    continue
                try:
                    unit = _InputUnit(self, sock)
                except NetworkError as exc:  # the peer reset before we could look at it
                    sock.close()
                    log.debug("%s: a connection ended before it started: %s", self.name, exc)
                    continue
                self._inputs[unit.id] = unit
                self._introducing[unit.id] = unit
            unit.start()

    def _evict_the_oldest_silent(self) -> None:
        """Make room for one more connection still to introduce itself (lock held)."""
        for unit_id, unit in list(self._introducing.items()):
            if unit.introduced or unit_id not in self._inputs:
                del self._introducing[unit_id]
        while len(self._introducing) >= MAX_INTRODUCING:
            _, oldest = self._introducing.popitem(last=False)
            oldest.close()
            if self._evicted.record():
                log.warning("%s: %d connections closed that had not said who they are while "
                            "newer ones came (a flood?); %d open", self.name,
                            self._evicted.count, len(self._inputs))

    def _input_started(self, unit: _InputUnit) -> None:
        route = unit.route
        if _rooted(route.source):
            # As YARP: a new connection from the same source replaces old ones.
            with self._lock:
                stale = [other for other in self._inputs.values()
                         if other is not unit and other.route.source == route.source]
            for other in stale:
                other.close()
            log.info("Receiving input from %s to %s using %s", route.source, route.target,
                     route.carrier)
        with self._input_events:
            self._input_events.notify_all()

    def _input_finished(self, unit: _InputUnit) -> None:
        with self._lock:
            self._inputs.pop(unit.id, None)
            self._input_events.notify_all()
        if unit.carrier is not None and _rooted(unit.route.source) and not self._closing:
            log.info("Removing input from %s to %s", unit.route.source, unit.route.target)

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.name or '(closed)'}>"


class RegistrationKeeper:
    """Re-registers open ports when the name server comes back.

    Real YARP ports stay unregistered after a name server restart; ours notice
    and register again at the same address, so persistent connections and
    lookups work without restarting the modules.  Noticing costs one ``query``
    per name server (not per port) every few seconds, for one of this process's
    ports in turn
    (a restarted server has lost them all, so one tells); only when that port is
    missing does a ``list`` find the others.  A ``list`` every period cost what
    the server holds: 53 kbit/s over the robot link for one pilot process in
    the direct topology (``bench/bench_bridge.py`` 1), and megabytes with 10 000
    ports.
    """

    _instance: Optional["RegistrationKeeper"] = None
    _instance_lock = threading.Lock()
    PERIOD = 2.0

    def __init__(self) -> None:
        self._ports: List[Port] = []
        self._lock = threading.Lock()
        self._wake = threading.Event()
        self._thread: Optional[threading.Thread] = None
        self._turn = 0  # which port the next check asks about
        self._round = threading.Lock()   # the background round vs held()
        self._holding = 0

    @classmethod
    def instance(cls) -> "RegistrationKeeper":
        with cls._instance_lock:
            if cls._instance is None:
                cls._instance = cls()
            return cls._instance

    def add(self, port: Port) -> None:
        with self._lock:
            self._ports.append(port)
            if self._thread is None or not self._thread.is_alive():
                self._thread = threading.Thread(target=self._run, daemon=True,
                                                name="yarp_lite registration keeper")
                self._thread.start()

    def remove(self, port: Port) -> None:
        with self._lock:
            if port in self._ports:
                self._ports.remove(port)

    def check_now(self) -> None:
        """Run one check soon (tests and tools use this instead of sleeping)."""
        self._wake.set()

    @contextlib.contextmanager
    def held(self) -> Iterator[None]:
        """No background round meanwhile (one under way ends first): for a caller that
        runs :meth:`check_all` itself and counts what one round asks."""
        with self._round:
            self._holding += 1
        try:
            yield
        finally:
            with self._round:
                self._holding -= 1

    def _run(self) -> None:
        while True:
            self._wake.wait(self.PERIOD)
            self._wake.clear()
            with self._round:
                if not self._holding:
                    self.check_all()

    def check_all(self) -> None:
        """One round: ask each name server about one of our ports; re-register if lost."""
        with self._lock:
            ports = [port for port in self._ports if port.is_open]
        by_server: Dict[object, List[Port]] = {}
        for port in ports:  # each port has its own client: one check per server
            by_server.setdefault(self._server_of(port), []).append(port)
        for group in by_server.values():
            self._check(group)

    @staticmethod
    def _server_of(port: Port) -> object:
        try:
            address = port.nameclient.server_address()
        except YarpError:
            return id(port.nameclient)  # none configured now: its own group, skipped
        return (address.host, address.port)

    def _check(self, ports: List[Port]) -> None:
        client = ports[0].nameclient
        self._turn += 1
        sentinel = ports[self._turn % len(ports)]
        try:
            found = client.query(sentinel.name)
            if found is not None and found.port == sentinel.address.port:
                return  # the server still knows us
            known = {contact.name: contact for contact in client.list()}
        except YarpError:
            return  # server down: try again next period
        for port in ports:
            current = known.get(port.name)
            if current is not None and current.port == port.address.port:
                continue
            if not port.is_open:
                continue
            try:
                client.register(port.name, "tcp", port.address.host, port.address.port)
                client.describe_port(port.name)
                client.announce(port.name)
                log.info("%s: registered again with the name server", port.name)
            except YarpError as exc:
                log.debug("%s: re-registration failed: %s", port.name, exc)


__all__ = ["Port", "RegistrationKeeper", "Reader", "SUPPORTED"]
