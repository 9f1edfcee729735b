"""The UDP channel: perception and fast streams, where late data is worthless.

Theory of operation
-------------------
Each flow keeps only its newest message waiting (latest-only, as the TCP
channel's streams).  The sender thread turns a message into datagrams with the
flow's codec -- standalone tiles for images and clouds, plain slices for
anything else -- adds Reed-Solomon repair datagrams when the flow asks for them (a
fixed repair fraction, or as many as the loss the receiver reports needs:
:mod:`bridge.transport.adaptive_fec`), and sends them round-robin across flows, paced to ``rate``
bits per second (IP and UDP headers included) so a slow link's shaper does not
drop our bursts.

Message numbers are millisecond timestamps (strictly increasing per flow, mod
2**32): the receiver rebuilds by them, as the paper rebuilt by timestamp, and
they keep increasing when the sender restarts.  The receiver accepts datagrams
only from the peer's address, collects the parts of each message, repairs what
it can, and publishes a message as soon as every part is there, or ``gather``
seconds (the paper's delta-t, 0.4 s) after its first part: a tiled message
then goes out with its missing regions blank or NaN, a sliced one is counted
lost.  A datagram for a message older than the last one published is stale
and dropped.  Every finished message is counted in the receiver's
:class:`~bridge.transport.adaptive_fec.LossMeter`, whose totals go back to the sender
every half second as a report datagram.

On the wire every datagram is sealed by the link (:mod:`bridge.wire.link`): a
counter and an authentication tag with the UDP key the TCP handshake derived.
The channel sends nothing before the first handshake, and drops what fails
the tag or the replay window; every drop is counted by reason
(:mod:`bridge.transport.drops`).
"""

from __future__ import annotations

import logging
import socket
import threading
import time
from collections import deque
from dataclasses import dataclass, field, fields
from typing import Any, Callable, Deque, Dict, List, Optional, Protocol, Set, Tuple

from bridge.errors import BridgeError, BridgeProtocolError
from bridge.flows import Carriage, FlowKey, Route
from bridge.transport import drops
from bridge.transport.adaptive_fec import (REPORT_INTERVAL, FecAdapter, LossMeter,
                                           copies_needed)
from bridge.transport.drops import DropLedger, Reason
from bridge.transport.link_budget import LinkBudget, datagram_bytes
from bridge.transport.nursery import Nursery
from bridge.wire import datagrams, fec, tiles
from bridge.wire.datagrams import BODY_BUDGET, Datagram
from bridge.wire.link import SEAL_OVERHEAD, DatagramOpener, DatagramSealer

log = logging.getLogger("bridge.udp")

IP_UDP_OVERHEAD = 28
MAX_PARTS = 20000
MAX_GROUP = 32
MAX_PENDING_MESSAGES = 8


class UdpCodec(Protocol):
    """How one flow's messages become datagram bodies and back."""

    tiled: bool

    def encode(self, value: Any) -> List[bytes]:
        """Tile bodies (tiled) or the whole message as one bytes object (sliced)."""

    def decode(self, data: Any, completeness: float) -> Any:
        """A :class:`~bridge.wire.tiles.Canvas` (tiled) or the message bytes (sliced)."""


@dataclass(frozen=True)
class UdpRoute(Route):
    """A flow's :class:`~bridge.flows.Route` with the codec of its values (:meth:`of`)."""

    codec: Optional[UdpCodec] = None

    @classmethod
    def of(cls, route: Route, codec: UdpCodec) -> "UdpRoute":
        return cls(**{f.name: getattr(route, f.name) for f in fields(route)}, codec=codec)


@dataclass
class FlowStats:
    sent: int = 0
    complete: int = 0
    partial: int = 0
    lost: int = 0
    superseded: int = 0
    completeness_sum: float = 0.0
    repaired: int = 0
    repairs_sent: int = 0
    #: datagrams that came again (a flow sent as copies, bridge.transport.copies): not a
    #: loss, no drop
    repeats: int = 0

    @property
    def mean_completeness(self) -> float:
        published = self.complete + self.partial
        delivered = self.completeness_sum + self.complete
        return delivered / (published + self.lost) if published + self.lost else 0.0


@dataclass
class UdpStats:
    datagrams_out: int = 0
    datagrams_in: int = 0
    bytes_out: int = 0
    bytes_in: int = 0
    send_errors: int = 0
    #: exceptions that are our bugs (logged with their traceback), not the peer's
    internal_errors: int = 0
    #: datagram bytes sent per 8-bit id (IP/UDP headers not included)
    bytes_by_id: Dict[int, int] = field(default_factory=dict)
    flows: Dict[str, FlowStats] = field(default_factory=dict)
    #: data datagram loss the peer reports for what we send (-1: no report yet)
    peer_loss: float = -1.0
    #: the loss adaptive repairs are sized for now
    fec_loss_bound: float = 0.0
    #: data datagram loss we measure on what we receive
    loss: float = 0.0


@dataclass
class _Partial:
    first: float
    parts: int
    group: int
    data: Dict[int, bytes] = field(default_factory=dict)
    repairs: Dict[int, Dict[int, bytes]] = field(default_factory=dict)
    repaired: int = 0
    raw: Set[int] = field(default_factory=set)   # data parts that came off the wire


_is_newer = drops.is_newer


def message_datagrams(route: UdpRoute, message: int, bodies: List[bytes],
                      repairs: Optional[Callable[[int], int]] = None) -> List[bytes]:
    """The datagrams of one message: data parts, each group followed by its repairs
    (``repairs(k)`` of them for a group of ``k``; by default the route's fixed fraction)."""
    parts = len(bodies)
    if parts == 0:
        return []
    if parts > MAX_PARTS:
        raise BridgeError(f"{route.label}: message needs {parts} datagrams "
                          f"(limit {MAX_PARTS})")
    group = min(parts, MAX_GROUP)
    out = []
    for start in range(0, parts, group):
        chunk = bodies[start:start + group]
        for offset, body in enumerate(chunk):
            out.append(datagrams.encode(Datagram(route.key.id, route.key.kind, message, parts,
                                                 group, start + offset, body)))
        count = repairs(len(chunk)) if repairs else fec.repair_count(len(chunk), route.fec)
        for row, repair in enumerate(fec.encode(chunk, count)):
            out.append(datagrams.encode(Datagram(route.key.id, route.key.kind, message, parts,
                                                 group, start // group, repair, row)))
    return out


def slice_message(data: bytes) -> List[bytes]:
    return [data[i:i + BODY_BUDGET] for i in range(0, max(len(data), 1), BODY_BUDGET)]


class Reassembler:
    """Receiving half, sans-IO: feed datagrams and the clock, get finished messages."""

    def __init__(self, routes: Dict[FlowKey, UdpRoute], gather: float, stats: UdpStats,
                 ledger: Optional[DropLedger] = None,
                 loss: Optional[LossMeter] = None) -> None:
        self.routes = routes
        self.gather = gather
        self.stats = stats
        self.drops = ledger if ledger is not None else DropLedger("UDP channel", log)
        self.loss = loss if loss is not None else LossMeter()
        self._partials: Dict[FlowKey, Dict[int, _Partial]] = {}
        self._last: Dict[FlowKey, int] = {}
        # the message of each flow counted last, and its parts that came off the wire
        self._counted: Dict[FlowKey, Tuple[int, Set[int]]] = {}

    def feed(self, raw: bytes, now: float) -> List[Tuple[FlowKey, Any]]:
        try:
            datagram = datagrams.decode(raw)
        except BridgeProtocolError as exc:
            self.drops.peer_error(exc, "datagram")
            return []
        key = FlowKey(datagram.id, datagram.kind)
        route = self.routes.get(key)
        if route is None:
            self.drops.drop(Reason.UNKNOWN_ID, f"datagram id {datagram.id} kind {datagram.kind}")
            return []
        if datagram.parts > MAX_PARTS:
            self.drops.drop(Reason.MALFORMED, f"{route.label}: {datagram.parts} parts "
                                              f"(limit {MAX_PARTS})")
            return []
        if not _is_newer(datagram.message, self._last.get(key)):
            counted = self._counted.get(key)
            if not datagram.is_repair and counted is not None and \
                    datagram.message == counted[0]:
                if datagram.index not in counted[1]:
                    counted[1].add(datagram.index)
                    self.loss.late()     # arrived after its message was given up: not lost
                elif route.copied:       # a copy of a part that came: what copies are for
                    self._flow(route).repeats += 1
                    return []
            self.drops.drop(Reason.STALE, f"{route.label} message {datagram.message}")
            return []
        pending = self._partials.setdefault(key, {})
        partial = pending.get(datagram.message)
        if partial is None:
            if len(pending) >= MAX_PENDING_MESSAGES:
                oldest = min(pending, key=lambda m: pending[m].first)
                self._finish(key, oldest, pending.pop(oldest))
            partial = pending[datagram.message] = _Partial(now, datagram.parts, datagram.group)
        elif (partial.parts, partial.group) != (datagram.parts, datagram.group):
            self.drops.drop(Reason.MALFORMED, f"{route.label} message {datagram.message}: "
                                              f"{datagram.parts} parts in groups of "
                                              f"{datagram.group}, earlier parts said "
                                              f"{partial.parts}/{partial.group}")
            return []
        if datagram.is_repair:
            partial.repairs.setdefault(datagram.index, {})[datagram.repair_row] = datagram.body
            self._repair(partial, datagram.index)
        elif datagram.index in partial.raw:          # a copy (or replay) of a part that came
            self._flow(route).repeats += 1
            return []
        else:
            partial.data[datagram.index] = datagram.body
            partial.raw.add(datagram.index)
            self._repair(partial, datagram.index // partial.group)
        if len(partial.data) == partial.parts:
            del pending[datagram.message]
            return self._finish(key, datagram.message, partial)
        return []

    def _flow(self, route: UdpRoute) -> FlowStats:
        return self.stats.flows.setdefault(route.label, FlowStats())

    def _repair(self, partial: _Partial, group_index: int) -> None:
        repairs = partial.repairs.get(group_index)
        if not repairs:
            return
        start = group_index * partial.group
        k = min(partial.group, partial.parts - start)
        have = {i - start: partial.data[i] for i in range(start, start + k) if i in partial.data}
        if len(have) == k or len(have) + len(repairs) < k:
            return
        try:
            recovered = fec.recover(k, have, repairs)
        except BridgeProtocolError as exc:
            self.drops.peer_error(exc, "repair")
            partial.repairs.pop(group_index, None)
            return
        for index, body in recovered.items():
            partial.data[start + index] = body
        partial.repaired += len(recovered)

    def expire(self, now: float) -> List[Tuple[FlowKey, Any]]:
        """Publish or drop messages whose gathering time is over."""
        out = []
        for key, pending in self._partials.items():
            for message in [m for m, p in pending.items() if now - p.first >= self.gather]:
                out.extend(self._finish(key, message, pending.pop(message)))
        return out

    def _finish(self, key: FlowKey, message: int, partial: _Partial) -> List[Tuple[FlowKey, Any]]:
        route = self.routes[key]
        flow = self._flow(route)
        flow.repaired += partial.repaired
        self.loss.record(len(partial.raw), partial.parts)
        self._counted[key] = (message, partial.raw)
        self.stats.loss = round(self.loss.loss, 4)
        if not _is_newer(message, self._last.get(key)):
            flow.superseded += 1
            return []
        complete = len(partial.data) == partial.parts
        if route.codec.tiled:
            canvas = self._paint(partial)
            if canvas is None:
                flow.lost += 1
                return []
            try:
                value = route.codec.decode(canvas, canvas.completeness)
            except BridgeProtocolError as exc:
                self.drops.peer_error(exc, route.label)
                flow.lost += 1
                return []
            completeness = canvas.completeness
        else:
            if not complete:
                flow.lost += 1
                return []
            data = b"".join(partial.data[i] for i in range(partial.parts))
            try:
                value = route.codec.decode(data, 1.0)
            except BridgeProtocolError as exc:
                self.drops.peer_error(exc, route.label)
                return []
            completeness = 1.0
        self._last[key] = message
        for stale in [m for m in self._partials.get(key, {}) if not _is_newer(m, message)]:
            self._partials[key].pop(stale)
            flow.superseded += 1
        if completeness >= 1.0:
            flow.complete += 1
        else:
            flow.partial += 1
            flow.completeness_sum += completeness
        return [(key, value)]

    def _paint(self, partial: _Partial) -> Optional[tiles.Canvas]:
        canvas = None
        for index in sorted(partial.data):
            try:
                tile, codec = tiles.decode_tile(partial.data[index])
                if canvas is None:
                    canvas = tiles.Canvas(tile.header, tile.meta, partial.parts)
                canvas.paste(tile, codec)
            except BridgeProtocolError as exc:
                self.drops.peer_error(exc, "tile")
        return canvas


class UdpChannel:
    """Socket, pacing and threads around :func:`message_datagrams` and :class:`Reassembler`."""

    def __init__(self, *, peer: str, port: int, peer_port: int, routes: List[UdpRoute],
                 gather: float, on_message: Callable[[FlowKey, Any], None],
                 rate: Optional[float] = None, bind_host: str = "",
                 budget: Optional[LinkBudget] = None) -> None:
        self.peer = peer
        self.port = port
        self.peer_port = peer_port
        self.routes = {route.key: route for route in routes}
        self.rate = rate
        #: the radio's queue, shared with the TCP channel: paced datagrams wait for room
        self.budget = budget
        self.on_message = on_message
        self.stats = UdpStats()
        self.drops = DropLedger("UDP channel", log)
        self.loss_meter = LossMeter()
        self.adapter = FecAdapter(rate)
        #: the loss on the way in, over the same window: a radio loses both ways alike, and
        #: a stop's copies tell the peer nothing of the loss (a lost one is never missed)
        self.loss_in = FecAdapter()
        self.reassembler = Reassembler(self.routes, gather, self.stats, self.drops,
                                       self.loss_meter)
        self._next_report = 0.0
        self.opener = DatagramOpener()
        self._sealer: Optional[DatagramSealer] = None
        self._seal_lock = threading.Lock()   # the send loop and send_now() seal in turn
        self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4 << 20)
        self._sock.bind((bind_host, port))
        self._sock.settimeout(0.05)
        self._slots: Dict[FlowKey, Any] = {}
        self._queues: Dict[FlowKey, Deque[bytes]] = {}
        self._last_message: Dict[FlowKey, int] = {}
        self._cond = threading.Condition()
        self._stopping = threading.Event()
        self._nursery = Nursery()
        self._peer_ips = self._resolve()
        self._tokens = 0.0
        self._token_time = time.monotonic()

    def _resolve(self) -> set:
        try:
            return {info[4][0] for info in socket.getaddrinfo(self.peer, None, socket.AF_INET)}
        except OSError:
            return set()

    def start(self) -> None:
        self._nursery.start_soon(self._send_loop, "udp send")
        self._nursery.start_soon(self._receive_loop, "udp receive")
        log.info("UDP channel on port %d, peer %s:%d%s", self.port, self.peer, self.peer_port,
                 f", paced at {self.rate / 1000:.0f} kbit/s" if self.rate else "")

    def stop(self) -> None:
        self._stopping.set()
        with self._cond:
            self._cond.notify_all()
        self._nursery.join()
        self._sock.close()

    def set_keys(self, event: str, send_key: bytes, receive_key: bytes) -> None:
        """Keys from the TCP handshake (:meth:`bridge.transport.tcp_channel.TcpListener.keys`).

        ``offered``: the peer may already send with ``receive_key``; ``installed``:
        the peer proved the key, so we send with ``send_key`` from now on.
        """
        if event == "offered":
            self.opener.offer(receive_key)
            return
        self.opener.install(receive_key)
        with self._cond:
            if self._sealer is None or self._sealer.key != send_key:
                self._sealer = DatagramSealer(send_key)
            self._cond.notify_all()

    def post(self, key: FlowKey, value: Any) -> None:
        """The newest message of a flow; an older one not yet started is replaced."""
        with self._cond:
            self._slots[key] = value
            self._cond.notify_all()

    def send_now(self, key: FlowKey, value: Any, copies: int, again: bool = False) -> int:
        """``value`` as ``copies`` copies of one message, sent from this thread ahead of the
        paced queue (the stop-all: small, rare, and worth more than any image).  The
        receiver takes the first copy and drops the others as repeats of the message it
        has.  ``again``: a resending of what already went.  Returns the datagrams sent (0
        before the handshake: nothing leaves unsealed)."""
        route = self.routes[key]
        full = self.budget is not None and self.budget.full(time.monotonic())
        if full and (route.carriage is not Carriage.URGENT or again):
            # Copies are insurance against loss; the TCP frame carries the message anyway.
            # Queued behind a full radio they only delay what comes next -- the next stop
            # among it.  A command's or status's copies, or a resending (the last sending
            # is still in the radio's queue), are not sent.
            self.drops.drop(Reason.COPY_SKIPPED, f"{route.label}: the radio's queue is full"
                            + (" (a resending)" if again else ""), copies)
            return 0
        with self._cond:
            number = self._next_message_number(key)
        encoded = slice_message(route.codec.encode(value))
        inner = message_datagrams(route, number, encoded)
        if route.carriage is Carriage.URGENT:
            # A stop or its acknowledgement: as many copies as the link's loss needs for one
            # to arrive (30 %: 6), as far as the radio has room for them -- one when full.
            wanted = copies_needed(max(self.adapter.loss_bound(), self.loss_in.loss_bound()),
                                   copies)
            copies = wanted
            if self.budget is not None:
                room = self.budget.limit - self.budget.queued(time.monotonic())
                size = sum(datagram_bytes(len(body) + SEAL_OVERHEAD) for body in inner)
                copies = max(1, min(wanted, int(room // size)))
            if copies < wanted:
                self.drops.drop(Reason.COPY_SKIPPED, f"{route.label}: room in the radio's "
                                                     f"queue for {copies} of {wanted} copies",
                                wanted - copies)
        sent = 0
        for _ in range(copies):
            for body in inner:
                with self._seal_lock:
                    if self._sealer is None:
                        return sent
                    datagram = self._sealer.seal(body)
                if self._sendto(key, datagram):
                    sent += 1
        return sent

    # -- sending -----------------------------------------------------------------------

    def _next_message_number(self, key: FlowKey) -> int:
        now_ms = int(time.time() * 1000) & 0xFFFFFFFF
        last = self._last_message.get(key)
        number = now_ms if last is None or _is_newer(now_ms, last) else (last + 1) & 0xFFFFFFFF
        self._last_message[key] = number
        return number

    def _refill(self) -> None:
        """Turn waiting messages into datagram queues for flows that are idle."""
        with self._cond:
            ready = [(key, self._slots.pop(key)) for key in list(self._slots)
                     if not self._queues.get(key)]
        for key, value in ready:
            route = self.routes[key]
            now = time.monotonic()
            repairs = (lambda k: self.adapter.repairs(k, now)) if route.fec_auto else None
            try:
                encoded = route.codec.encode(value)
                bodies = encoded if route.codec.tiled else slice_message(encoded)
                queue = message_datagrams(route, self._next_message_number(key), bodies,
                                          repairs)
            except BridgeError as exc:
                self.drops.last_error = str(exc)
                log.error("UDP channel: cannot send on %s: %s", route.label, exc)
                continue
            self.adapter.note_sent(sum(len(body) for body in bodies), now)
            self._queues[key] = deque(queue)
            flow = self.stats.flows.setdefault(route.label, FlowStats())
            flow.sent += 1
            flow.repairs_sent += len(queue) - len(bodies)
            self.stats.fec_loss_bound = round(self.adapter.loss_bound(), 4)

    def _pace(self, size: int) -> None:
        if not self.rate:
            return
        bytes_per_second = self.rate / 8
        burst = max(4 * 1500, bytes_per_second * 0.02)
        while not self._stopping.is_set():
            now = time.monotonic()
            self._tokens = min(burst, self._tokens + (now - self._token_time) * bytes_per_second)
            self._token_time = now
            if self._tokens >= size:
                self._tokens -= size
                return
            time.sleep((size - self._tokens) / bytes_per_second)

    def _send(self, key: Optional[FlowKey], inner: bytes) -> None:
        with self._seal_lock:
            datagram = self._sealer.seal(inner)
        self._pace(len(datagram) + IP_UDP_OVERHEAD)
        self._wait_for_room(datagram_bytes(len(datagram)))
        self._sendto(key, datagram)

    def _wait_for_room(self, size: int) -> None:
        """A paced datagram waits until the radio's queue has room for it (the stop-all's
        copies, sent by :meth:`send_now`, never wait)."""
        while self.budget is not None and not self._stopping.is_set():
            wait = self.budget.wait_for(size, time.monotonic())
            if wait <= 0:
                return
            self._stopping.wait(wait)

    def _sendto(self, key: Optional[FlowKey], datagram: bytes) -> bool:
        try:
            self._sock.sendto(datagram, (self.peer, self.peer_port))
        except OSError as exc:  # no route while the link is down: that datagram is lost
            self.stats.send_errors += 1
            self.drops.last_error = f"send: {exc.strerror or exc}"
            return False
        if self.budget is not None:
            self.budget.spend(datagram_bytes(len(datagram)), time.monotonic())
        self.stats.datagrams_out += 1
        self.stats.bytes_out += len(datagram)
        if key is not None:
            self.stats.bytes_by_id[key.id] = self.stats.bytes_by_id.get(key.id, 0) + \
                len(datagram)
        return True

    def _report(self) -> None:
        """Tell the sender what arrived (every :data:`REPORT_INTERVAL`, if anything did)."""
        now = time.monotonic()
        if now < self._next_report:
            return
        self._next_report = now + REPORT_INTERVAL
        report = self.loss_meter.report()
        if report is not None:
            self.loss_in.on_report(report, now)
        if report is not None:
            self._send(None, datagrams.encode_report(report))

    def _send_loop(self) -> None:
        while not self._stopping.is_set():
            if self._sealer is None:  # no handshake yet: nothing may leave unsealed
                with self._cond:
                    self._cond.wait(0.5)
                continue
            try:
                self._send_round()
            except Exception:  # noqa: BLE001 -- our bug: seen and counted, the thread lives
                self.stats.internal_errors += 1
                log.exception("UDP channel: sending failed (a bug); going on")
                self._stopping.wait(0.1)

    def _send_round(self) -> None:
        """The loss report when due, then one datagram of each flow that has some."""
        self._report()
        self._refill()
        active = [key for key, queue in self._queues.items() if queue]
        if not active:
            with self._cond:
                if not self._slots and not self._stopping.is_set():
                    self._cond.wait(0.5)
            return
        for key in active:
            self._send(key, self._queues[key].popleft())

    # -- receiving ---------------------------------------------------------------------

    def _guarded(self, step: Callable[..., List[Tuple[FlowKey, Any]]], *args: Any
                 ) -> List[Tuple[FlowKey, Any]]:
        """Run a reassembly step; a bug in it is logged and counted, the thread lives on."""
        try:
            return step(*args)
        except Exception:  # noqa: BLE001 -- our bug: seen and counted, never silent
            self.stats.internal_errors += 1
            log.exception("UDP channel: reassembly failed (a bug); the datagram is lost")
            return []

    def _on_report(self, inner: bytes, now: float) -> None:
        try:
            report = datagrams.decode_report(inner)
        except BridgeProtocolError as exc:
            self.drops.peer_error(exc, "loss report")
            return
        self.adapter.on_report(report, now)
        seen = self.adapter.measured()
        if seen is not None and seen[1]:
            self.stats.peer_loss = round(seen[0] / seen[1], 4)

    def _receive_loop(self) -> None:
        next_sweep = time.monotonic()
        while not self._stopping.is_set():
            finished: List[Tuple[FlowKey, Any]] = []
            try:
                raw, (host, _) = self._sock.recvfrom(65536)
            except socket.timeout:
                raw = None
            except OSError:
                if self._stopping.is_set():
                    return
                raw = None
            now = time.monotonic()
            if raw is not None:
                self.stats.datagrams_in += 1
                self.stats.bytes_in += len(raw)
                if not drops.from_peer(host, self._peer_ips):
                    self.drops.drop(Reason.STRANGER, f"datagram from {host}")
                else:
                    try:
                        inner = self.opener.open(raw)
                    except BridgeProtocolError as exc:
                        self.drops.peer_error(exc, f"datagram from {host}")
                    else:
                        if datagrams.is_report(inner):
                            self._on_report(inner, now)
                        else:
                            finished.extend(self._guarded(self.reassembler.feed, inner, now))
            if now >= next_sweep:
                finished.extend(self._guarded(self.reassembler.expire, now))
                next_sweep = now + 0.02
            for key, value in finished:
                try:
                    self.on_message(key, value)
                except Exception:  # noqa: BLE001 -- a consumer's bug: seen and counted
                    self.stats.internal_errors += 1
                    log.exception("UDP channel: delivering %s failed (a bug)",
                                  self.routes[key].label)
