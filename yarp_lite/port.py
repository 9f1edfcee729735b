"""Ports: named endpoints that register, accept connections, send and receive.

Theory of operation
-------------------
A port owns a listening TCP socket registered with the name server, and three parts,
each in a module of its own:

* its inputs (:mod:`yarp_lite.port_inputs`): the listener, and a thread per accepted
  connection that reads it and answers admin and port commands;
* its delivery (:mod:`yarp_lite.delivery`): where received data goes -- a callback,
  a blocking :meth:`Port.read`, or (:class:`~yarp_lite.buffered_port.BufferedPort`) a
  buffer;
* its outputs (:mod:`yarp_lite.port_outputs`): the connections it opened, which
  :meth:`Port.write` sends on from the calling thread; a broken output is dropped and
  logged, never raised at the writer.  A port told to :meth:`Port.hold_for_late_readers`
  keeps its recent messages and hands each new output what its reader has not taken
  (:mod:`yarp_lite.held`); real YARP ports hold nothing.

A peer's bytes never take a port down: a protocol violation closes that one
connection with a log line naming the peer and the problem.  While a port is
open, a :class:`~yarp_lite.registration.RegistrationKeeper` checks every few seconds
that the name server still knows it, and registers it again after a name server
restart.
"""

from __future__ import annotations

import errno
import logging
import socket
import threading
import time
from typing import Callable, Dict, List, Optional, Sequence, Tuple, Union

from yarp_lite import auth
from yarp_lite.admin import Route
from yarp_lite.bottle import Bottle
from yarp_lite.carriers import SUPPORTED, BottlePayload, Payload
from yarp_lite.connection import REFUSED_RETRY
from yarp_lite.contact import Contact, apply_environment, check_port_name
from yarp_lite.delivery import Delivery, Reader, ReaderDelivery, Reply
from yarp_lite.errors import LocalProtocolError, NetworkError, YarpError
from yarp_lite.framing import DEFAULT_MAX_MESSAGE
from yarp_lite.held import HeldMessages
from yarp_lite.nameclient import NameClient
from yarp_lite.port_inputs import Inputs
from yarp_lite.port_outputs import Outputs, close_detached
from yarp_lite.registration import RegistrationKeeper

log = logging.getLogger("yarp_lite.port")


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
        return self._port.outputs.add(target)

    def remove_output(self, target: str) -> bool:
        return self._port.remove_output(target)

    def remove_input(self, source: str) -> bool:
        return self._port.remove_input(source)

    def properties(self) -> Dict[str, object]:
        return self._port.properties

    def admin_fallback(self, command: Bottle) -> Optional[Bottle]:
        handler = self._port.admin_reader
        return Bottle(handler(command) or []) if handler is not None else None


class Port:
    """A YARP port: open it under a name, connect it, write and read Bottles.

    ``reader``, if given, is called in the receiving thread with each Bottle
    (and, with ``reader_wants_source``, the sending port's name as second
    argument); what it returns is the reply sent back when the sender asked
    for one.  Without it, :meth:`read` blocks until a message arrives.
    ``delivery`` replaces both (:mod:`yarp_lite.delivery`: a BufferedPort's buffer);
    ``keeper`` keeps the port registered (the process's own by default).
    """

    def __init__(self, name: Optional[str] = None, *, reader: Optional[Reader] = None,
                 nameclient: Optional[NameClient] = None, timeout: Optional[float] = None,
                 max_message: int = DEFAULT_MAX_MESSAGE, rpc: bool = False,
                 register: bool = True, reader_wants_source: bool = False,
                 delivery: Optional[Delivery] = None,
                 keeper: Optional[RegistrationKeeper] = None) -> None:
        if delivery is not None and (reader is not None or reader_wants_source):
            raise ValueError("a port takes a reader or a delivery, not both")
        self.nameclient = nameclient or NameClient()
        self.admin_reader: Optional[Callable[[Bottle], Reply]] = None
        self.timeout = timeout
        self.max_message = max_message
        self.rpc = rpc
        self.register = register
        self.keeper = keeper or RegistrationKeeper.instance()
        self.name = ""
        self.address = Contact()
        self.properties: Dict[str, object] = {}
        #: The key accepted connections must prove (read from auth.conf at open).
        self.credentials = auth.DISABLED
        self.admin_view = _AdminView(self)
        self.delivery: Delivery = delivery if delivery is not None else \
            ReaderDelivery(lambda: self.name, reader, reader_wants_source)
        self.inputs = Inputs(self)
        self.outputs = Outputs(self)
        self._open = False
        self._opening = threading.Lock()     # open and close, one at a time
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
        with self._opening:
            return self._open_locked(name, host, socket_number, wait)

    def _open_locked(self, name: str, host: str, socket_number: int,
                     wait: Optional[float]) -> "Port":
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
        self.name, self.address = contact.name, contact
        self._open = True
        if isinstance(self.delivery, ReaderDelivery):
            self.delivery.reopen()
        self.inputs.listen(listener)
        if self.register:
            try:
                self.nameclient.describe_port(self.name)
                self.nameclient.announce(self.name)
            except NetworkError as exc:
                log.warning("%s: could not describe the port to the name server: %s",
                            self.name, exc)
            self.keeper.add(self)
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
        with self._opening:
            if not self._open:
                return
            self._open = False
            outputs = self.outputs.detach_all()     # no write reaches them from now on
        self.keeper.remove(self)
        if self.register:
            try:
                self.nameclient.unregister(self.name)
            except YarpError as exc:
                log.debug("%s: unregister failed: %s", self.name, exc)
        self.inputs.stop_listening()
        self.delivery.close()
        close_detached(outputs)
        self.inputs.close()

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
        self.outputs.hold(count, max_age)

    @property
    def held(self) -> Optional[HeldMessages]:
        """What the port keeps for readers that connect later (None: nothing, as YARP)."""
        return self.outputs.held

    # -- connections ---------------------------------------------------------------

    def add_output(self, target: str, carrier: str = "", quiet: bool = False) -> bool:
        """Connect this port's output to ``target`` (``/name`` or ``udp://name``).

        ``quiet`` is for callers that retry on their own: a failure is not
        logged, and a refused connection is not retried either (a loop over
        many stale registrations would otherwise wait on each of them).
        """
        ok, message = self.outputs.add(f"{carrier}:/{target}" if carrier else target,
                                       only_if_needed=True,
                                       retry_refused=0.0 if quiet else REFUSED_RETRY)
        if not ok and not quiet:
            log.warning("%s", message)
        return ok

    def remove_output(self, target: str, quiet: bool = False) -> bool:
        return self.outputs.remove(target, quiet)

    def remove_input(self, source: str) -> bool:
        return self.inputs.remove(source)

    def drop_closed_outputs(self) -> None:
        """Drop every output whose reader has closed its end (one non-blocking look at each
        socket): for a writer that asks :attr:`output_count` before writing and must not
        take a gone reader for a live one, nor leave its socket open."""
        self.outputs.drop_closed()

    def input_routes(self) -> List[Route]:
        return self.inputs.routes()

    def output_routes(self) -> List[Route]:
        """The live output connections (one whose reader has gone is left out)."""
        return self.outputs.routes()

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
        return bool(self.outputs)

    def wait_for_inputs(self, count: int = 1, timeout: float = 10.0) -> bool:
        return self.inputs.wait_for(count, timeout)

    @property
    def max_inputs(self) -> int:
        """Connections kept at most; past it new ones are refused (a flood)."""
        return self.inputs.max_inputs

    @max_inputs.setter
    def max_inputs(self, count: int) -> None:
        self.inputs.max_inputs = count

    # -- writing -----------------------------------------------------------------

    @property
    def skipped_writes(self) -> int:
        """Writes skipped for a connection still busy (``write(..., skip_busy=True)``)."""
        return self.outputs.skipped_writes

    def write(self, bottle: Union[Bottle, Sequence, Payload], envelope: str = "", *,
              skip_busy: bool = False) -> bool:
        """Send to every output; False if any output failed (and was dropped).

        ``envelope`` travels beside the data, as YARP's ``Port::setEnvelope``
        sends it (a Stamp is ``"count time"``); readers see it as ``envelope``.
        ``skip_busy`` (a stream where only the newest matters): never wait for a
        reader's acknowledgement, and skip a connection still waiting for one
        (:attr:`skipped_writes` counts them), or one whose reader asked for fewer messages
        (``+period.S``: :meth:`yarp_lite.port_outputs.OutputUnit.due`).
        """
        payload = bottle if isinstance(bottle, Payload) else BottlePayload(bottle)
        return self.outputs.write(payload, f"D {envelope}" if envelope else "D", skip_busy)

    def write_with_reply(self, bottle: Union[Bottle, Sequence],
                         timeout: Optional[float] = None) -> Optional[Bottle]:
        """Send to the first output and wait for its reply (YARP's write(b, reply))."""
        return self.outputs.request(bottle if isinstance(bottle, Bottle) else Bottle(bottle),
                                    timeout if timeout is not None else self.timeout)

    # -- reading -----------------------------------------------------------------

    @property
    def envelope(self) -> str:
        """The envelope of the message read or delivered last (YARP's ``getEnvelope``)."""
        return self.delivery.envelope

    @envelope.setter
    def envelope(self, value: str) -> None:
        self.delivery.envelope = value

    @property
    def reader(self) -> Optional[Reader]:
        """The callback each received Bottle goes to (None: :meth:`read` takes them)."""
        return self.delivery.reader if isinstance(self.delivery, ReaderDelivery) else None

    @reader.setter
    def reader(self, reader: Optional[Reader]) -> None:
        if not isinstance(self.delivery, ReaderDelivery):
            raise LocalProtocolError(f"{self.name} delivers to "
                                     f"{type(self.delivery).__name__}, not to a reader")
        self.delivery.reader = reader

    def read(self, timeout: Optional[float] = None, will_reply: bool = False) -> Optional[Bottle]:
        """Wait for the next Bottle; None on timeout or close.

        With ``will_reply``, the sender is held until :meth:`reply`.
        """
        if not isinstance(self.delivery, ReaderDelivery):
            raise LocalProtocolError(f"{self.name} delivers to "
                                     f"{type(self.delivery).__name__}; read() is unused")
        return self.delivery.read(timeout, will_reply)

    def reply(self, bottle: Union[Bottle, Sequence]) -> bool:
        """Answer the message taken by ``read(will_reply=True)``; False if none waits."""
        if not isinstance(self.delivery, ReaderDelivery):
            return False
        return self.delivery.reply(bottle if isinstance(bottle, Bottle) else Bottle(bottle))

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.name or '(closed)'}>"


__all__ = ["Port", "Reader", "SUPPORTED"]
