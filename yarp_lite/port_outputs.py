"""A port's outputs: the connections it opened to readers, and each write's way to them.

Theory of operation
-------------------
An output is an :class:`~yarp_lite.connection.OutgoingConnection` the port initiated
(on its owner's request, a ``yarp connect``, or the name server restoring a
persistent connection), kept by the reader's port name: a new connection to the same
reader replaces the old one.  :meth:`Outputs.write` sends on every output from the
calling thread; a broken output is dropped and logged, never raised at the writer.

Held messages (:mod:`yarp_lite.held`): a port told to hold them keeps its recent
messages, and a new output is first handed those its reader has not taken; writes to
that output wait at its gate meanwhile, so the reader sees every message in the order
written.

Queries (:meth:`Outputs.routes`) change nothing: an output whose reader has gone is
left out of them, and dropped by the next write or connection.
"""

from __future__ import annotations

import logging
import threading
import time
from typing import Dict, List, Optional, Protocol, Tuple

from yarp_lite.admin import Route
from yarp_lite.bottle import Bottle
from yarp_lite.carriers import BottlePayload, Payload, carrier_base_name, send_period
from yarp_lite.connection import REFUSED_RETRY, OutgoingConnection
from yarp_lite.contact import Contact
from yarp_lite.errors import AuthenticationError, LocalProtocolError, NetworkError, YarpError
from yarp_lite.held import Held, HeldMessages, HoldPolicy
from yarp_lite.nameclient import NameClient

log = logging.getLogger("yarp_lite.port")


def rooted(name: str) -> bool:
    """Whether ``name`` is a port's (``/...``), not a tool's like ``admin``."""
    return name.startswith("/")


class OutputUnit:
    """One output connection, its route, and the reader's rate."""

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

    def send(self, command: str, payload: Payload, timeout: Optional[float],
             skip_busy: bool) -> bool:
        """One message, after any held messages this output is still being handed; False
        when skipped (``skip_busy`` and the connection still waiting for an acknowledgement)."""
        if not skip_busy:
            with self.gate:
                self.connection.send(command, payload, timeout=timeout)
            return True
        if not self.gate.acquire(blocking=False):
            return False
        try:
            return self.connection.send_unless_busy(command, payload)
        finally:
            self.gate.release()


class OutputOwner(Protocol):
    """What the outputs need of their port (:class:`yarp_lite.port.Port`)."""

    name: str
    nameclient: NameClient
    timeout: Optional[float]
    rpc: bool

    @property
    def is_open(self) -> bool: ...


class Outputs:
    """The outputs of ``port``: connecting, dropping, writing, held messages."""

    def __init__(self, port: OutputOwner) -> None:
        self.port = port
        self._lock = threading.Lock()
        self._units: Dict[str, OutputUnit] = {}
        #: what the port keeps for readers that connect later (None: nothing, as YARP)
        self.held: Optional[HeldMessages] = None
        #: Writes skipped for a connection still busy (``write(..., skip_busy=True)``).
        self.skipped_writes = 0

    # -- queries (no side effects) ---------------------------------------------------

    def routes(self) -> List[Route]:
        """The live outputs' routes: one whose reader has gone is left out."""
        with self._lock:
            units = list(self._units.values())
        return [unit.route for unit in units if not unit.connection.peer_closed()]

    def __bool__(self) -> bool:
        """Whether any output is connected, without asking each socket whether its reader
        is alive: for a writer deciding every tick whether to encode at all."""
        return bool(self._units)

    # -- connecting --------------------------------------------------------------------

    def hold(self, count: int, max_age: float) -> None:
        with self._lock:
            self.held = HeldMessages(HoldPolicy(count, max_age))

    def add(self, spec: str, only_if_needed: bool = False,
            retry_refused: float = REFUSED_RETRY) -> Tuple[bool, str]:
        """Connect to ``spec``; a connection to the same port is replaced.

        ``only_if_needed`` keeps an existing connection with the right carrier
        (``Port::addOutput``); the admin ``[add]`` and ``/port`` commands always
        reconnect, as in YARP, which also clears a connection to a dead peer.
        A refused connection is retried for ``retry_refused`` seconds: the
        target may have registered without listening yet.
        """
        port = self.port
        requested = Contact.parse(spec)
        self.drop_closed()
        if port.rpc and self._units and requested.name not in self._units:
            return False, "RPC output already connected"
        try:
            address = requested if requested.host else port.nameclient.query(requested.name)
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
        existing = self._units.get(address.name)
        if only_if_needed and existing is not None and \
                existing.route.carrier == carrier_base_name(carrier) and existing.period == period:
            return True, f"Desired connection already present from {port.name} to {spec}"
        self.remove(address.name, quiet=True)
        try:
            connection = OutgoingConnection.open(address, port.name, carrier,
                                                 timeout=port.timeout or 10.0,
                                                 retry_refused=retry_refused)
        except AuthenticationError as exc:
            return False, f"Cannot connect to {spec}: {exc}"
        except YarpError as exc:
            log.debug("%s: cannot connect to %s: %s", port.name, spec, exc)
            return False, f"Cannot connect to {spec}"
        route = Route(port.name, address.name, connection.carrier_name,
                      connection.carrier.connectionless)
        unit = OutputUnit(connection, route, spec, period)
        with self._lock:
            if not port.is_open:
                connection.close()
                return False, f"Cannot connect to {spec}"
            self._units[address.name] = unit
            owed = self.held.owed(route.target) if self.held is not None else []
            if owed:
                unit.gate.acquire()     # a fresh lock: free; writes to it wait from now on
        if rooted(route.target) and rooted(route.source):
            log.info("Sending output from %s to %s using %s%s", route.source, route.target,
                     route.carrier, f" (about one message every {period:g} s of a stream)"
                     if period else "")
        if owed and not self._hand_over(unit, owed):
            return False, f"Cannot connect to {spec}: it left while taking held messages"
        return True, f"Added connection from {port.name} to {spec}"

    def _hand_over(self, unit: OutputUnit, owed: List[Held]) -> bool:
        """Send a new output the held messages its reader has not taken, then let the
        writes waiting at its gate through; False (and the output dropped) if it failed."""
        target = unit.route.target
        try:
            for held in owed:
                unit.connection.send(held.command, held.payload, timeout=self.port.timeout)
                with self._lock:
                    self.held.handed(held, target)   # type: ignore[union-attr]
            log.debug("%s: handed %d held message(s) to %s", self.port.name, len(owed), target)
            return True
        except YarpError as exc:
            log.info("%s: output to %s failed while taking held messages (%s); removing it",
                     self.port.name, target, exc)
            self.drop(unit)
            return False
        finally:
            unit.gate.release()

    def remove(self, target: str, quiet: bool = False) -> bool:
        """Close the output to ``target`` (saying goodbye); False if there was none."""
        target = Contact.parse(target).name or target
        with self._lock:
            unit = self._units.pop(target, None)
        if unit is None:
            return False
        if not quiet:
            _log_removed(unit)
        if unit.connection.carrier.connectionless:
            # The receiver cannot see a udp sender leave: tell it out of band.
            threading.Thread(target=self._disconnect_input_remotely, args=(unit,),
                             daemon=True, name=f"{self.port.name} udp goodbye").start()
        unit.connection.close()
        return True

    def _disconnect_input_remotely(self, unit: OutputUnit) -> None:
        port = self.port
        try:
            contact = port.nameclient.query(unit.route.target)
            if contact is not None:
                connection = OutgoingConnection.open(contact, "admin", "text", timeout=2.0)
                connection.send_text_command(f"~{port.name}", timeout=1.0)
                connection.abort()
        except YarpError as exc:
            log.warning("%s: cannot tell %s this udp output is gone (%s); it may "
                        "still list the input", port.name, unit.route.target, exc)

    def drop(self, unit: OutputUnit) -> None:
        """Abort a broken output (no goodbye: its reader is gone or misbehaved)."""
        with self._lock:
            removed = self._units.get(unit.route.target) is unit
            if removed:
                del self._units[unit.route.target]
        unit.connection.abort()
        if removed:
            _log_removed(unit)

    def drop_closed(self) -> None:
        """Drop every output whose reader has closed its end."""
        with self._lock:
            gone = [unit for unit in self._units.values() if unit.connection.peer_closed()]
        for unit in gone:
            self.drop(unit)

    def detach_all(self) -> List[OutputUnit]:
        """Every output, taken away at once (the port is closing: no write reaches them
        from now on); :func:`close_detached` says goodbye on them."""
        with self._lock:
            units = list(self._units.values())
            self._units.clear()
        return units

    # -- writing -----------------------------------------------------------------------

    def write(self, payload: Payload, command: str, skip_busy: bool) -> bool:
        """Send to every output; False if any output failed (and was dropped).  See
        :meth:`yarp_lite.port.Port.write`."""
        port = self.port
        with self._lock:
            units = list(self._units.values())
            held = self.held.written(command, payload) if self.held is not None else None
        all_ok = True
        now = time.monotonic() if skip_busy else 0.0
        for unit in units:
            if skip_busy and not unit.due(now):
                continue
            try:
                sent = unit.send(command, payload, port.timeout, skip_busy)
            except YarpError as exc:
                all_ok = False
                log.info("%s: output to %s failed (%s); removing it", port.name,
                         unit.route.target, exc)
                self.drop(unit)
                continue
            if not sent:
                self.skipped_writes += 1
            elif held is not None:
                with self._lock:
                    self.held.taken(held, unit.route.target)   # type: ignore[union-attr]
        return all_ok

    def request(self, bottle: Bottle, timeout: Optional[float]) -> Optional[Bottle]:
        """Send to the first output and wait for its reply (YARP's write(b, reply))."""
        with self._lock:
            units = list(self._units.values())
        if not units:
            return None
        unit = units[0]
        try:
            return unit.connection.send("d", BottlePayload(bottle), want_reply=True,
                                        timeout=timeout)
        except YarpError as exc:
            log.info("%s: request to %s failed (%s); removing the connection", self.port.name,
                     unit.route.target, exc)
            self.drop(unit)
            raise


def close_detached(units: List[OutputUnit]) -> None:
    """Close outputs taken by :meth:`Outputs.detach_all`, saying goodbye on each."""
    for unit in units:
        _log_removed(unit)
        unit.connection.close()


def _log_removed(unit: OutputUnit) -> None:
    if rooted(unit.route.target) and rooted(unit.route.source):
        log.info("Removing output from %s to %s", unit.route.source, unit.route.target)
