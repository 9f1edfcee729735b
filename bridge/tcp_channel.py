"""The TCP channel: commands, statuses and robot state between the two bridges.

Theory of operation
-------------------
One TCP connection joins the bridges; the robot side listens, the pilot side
dials (either can be chosen).  The connection goes through the phases of
:data:`PHASES`; every failure -- a reset, a CRC error, a silent peer for
``link_timeout`` seconds -- returns it to ``down`` and the dialer tries again
every second, forever.

Each connection speaks the link protocol of :mod:`bridge.link` (a sans-IO
:class:`~bridge.link.LinkConnection`): HELLO, mutual authentication with the
shared key, RESUME, then frames sealed with authentication tags.  This module
only moves its bytes.  A connection that fails authentication, or later sends
a frame whose tag is wrong, is dropped and counted (:mod:`bridge.drops`); on
the listening side each handshake runs in its own thread and an established
link is only replaced by a connection that has proved the key, so a stranger
can neither stall the listener nor push the real peer off.

The sender thread writes one frame per period T holding the newest value of
every streaming flow that changed (older ones are simply overwritten in their
slot), and writes at once whenever a reliable message is journalled or an ack
is owed.  A streaming value posted as an *event* (a module's status answering
a pilot's command, or with a new state: what the pilot waits to see) leaves at once
too, alone or with other events, at most once per :data:`EVENT_MIN_GAP` per
flow (later ones are coalesced in the slot), so a pilot's command shows its
effect within a round trip instead of the next period, and a robot standing
still sends exactly what the periodic frames send.  When a frame the pilot waits for
(events, reliable messages, presence) has left but the peer has not acknowledged
everything :data:`NUDGE_AFTER` (or a round trip plus :data:`DELAYED_ACK`) later, an
empty frame follows, up to :data:`NUDGES` times, the wait doubling: a lone lost segment
waits for TCP's retransmission timer (200 ms at least, doubling), while the peer's
selective acknowledgement of a later one makes the kernel resend it at once.  Bytes still
queued (a slow link) are not a loss: nothing follows them.
Reliable messages come from the :class:`~bridge.journal.Journal`:
after a reconnect the peer's RESUME says what it already has and the rest is
sent again, in order.  When the kernel still holds unsent bytes (the link is
slower than we write), the streaming part of a frame is held back rather than
queued, so the pilot sees fresh state instead of a backlog.

Streaming Bottles travel as deltas against the previous value sent on the same
connection (:mod:`bridge.compact`), robot state in the Table 1 codec
(:mod:`bridge.state_codec`); both restart from full values on every new
connection, so the two ends never disagree.  Which flows have their module
connected (:mod:`bridge.presence`) is said on each new connection and whenever
it changes.
"""

from __future__ import annotations

import fcntl
import hashlib
import logging
import math
import socket
import struct
import termios
import threading
import time
from dataclasses import dataclass, field
from typing import Any, Callable, Dict, List, Optional, Tuple

from bridge import compact, drops, frames
from bridge.drops import DropLedger, Reason
from bridge.errors import BridgeError, BridgeProtocolError
from bridge.expiry import aged_payload
from bridge.flows import FlowKey, Form, Route
from bridge.frames import DataFrame, Entry, Presence
from bridge.journal import Journal
from bridge.link import (FrameReceived, LinkConnection, LinkKey, LinkUp, PeerAuthenticated,
                         PeerHello)
from bridge.state_codec import StateDecoder, StateEncoder

log = logging.getLogger("bridge.tcp")



#: Connection phases and the events that move between them.
PHASES: Dict[str, Dict[str, str]] = {
    "down": {"connected": "handshake"},
    "handshake": {"hello_ok": "up", "failed": "down"},
    "up": {"failed": "down"},
}
MAX_RELIABLE_PER_FRAME = 256
#: Shortest time between two event sends of one flow; more frequent events wait (coalesced).
EVENT_MIN_GAP = 0.05
KEEPALIVE = 1.0
#: How long a receiver may delay its acknowledgement (Linux: 40 ms).
DELAYED_ACK = 0.04
#: Least seconds before an unacknowledged frame the pilot waits for is followed by an empty
#: one (a round trip plus :data:`DELAYED_ACK` on a slower link): far shorter than TCP's
#: retransmission timer.
NUDGE_AFTER = 0.05
#: Empty frames at most after one the pilot waits for (the wait doubling each time).
NUDGES = 3
#: Where ``struct tcp_info`` (linux/tcp.h) keeps ``tcpi_rtt``, in microseconds.
TCP_INFO_RTT_OFFSET = 68
#: Seconds a connection has to complete the handshake.
HANDSHAKE_TIMEOUT = 5.0
#: Handshakes run at once on the listening side; more connections are refused.
MAX_HANDSHAKES = 4
#: Called with ("offered" | "installed", our UDP sending key, our UDP receiving key).
KeysHook = Callable[[str, bytes, bytes], None]


@dataclass
class LinkStats:
    frames_out: int = 0
    frames_in: int = 0
    bytes_out: int = 0
    bytes_in: int = 0
    payload_out: int = 0
    payload_in: int = 0
    reliable_sent: int = 0
    reliable_accepted: int = 0
    connects: int = 0
    #: empty frames sent after one the pilot waits for that was not acknowledged in time
    nudges: int = 0
    #: exceptions that are our bugs (logged with their traceback), not the peer's
    internal_errors: int = 0
    last_error: str = ""
    #: payload plus entry header bytes sent, per 8-bit id (frame headers not included)
    bytes_by_id: Dict[int, int] = field(default_factory=dict)


def fingerprint(text: str) -> bytes:
    return hashlib.sha256(text.encode()).digest()[:8]


#: ``SIOCOUTQNSD`` (linux/sockios.h): bytes of a TCP socket not yet sent at all.
SIOCOUTQNSD = 0x894B


def _only_unacknowledged(sock: socket.socket) -> bool:
    """Has everything left, with some of it not yet acknowledged?  (Bytes still queued for
    a slow link are not a sign of loss, and an empty frame behind them would not help.)"""
    return _socket_queue(sock, SIOCOUTQNSD) == 0 and _unsent_bytes(sock) > 0


def _unsent_bytes(sock: socket.socket) -> int:
    """Bytes the kernel still holds for the peer, sent or not (unacknowledged)."""
    return _socket_queue(sock, termios.TIOCOUTQ)


def _socket_queue(sock: socket.socket, request: int) -> int:
    """A send-queue size the kernel reports for ``sock``; 0 once the socket is closed (the
    receive thread closes it when the peer dies: ``fileno()`` is then -1, which ``ioctl``
    refuses with a ValueError -- it was logged as a bug on every bridge restart)."""
    fd = sock.fileno()
    if fd < 0:
        return 0
    try:
        return struct.unpack("i", fcntl.ioctl(fd, request, b"\0\0\0\0"))[0]
    except OSError:
        return 0


@dataclass
class _Nudges:
    """When the send thread follows a frame the pilot waits for with an empty one."""

    at: float = math.inf
    gap: float = NUDGE_AFTER
    left: int = 0

    def awaited_frame_sent(self, now: float, round_trip: float = 0.0) -> None:
        """A frame the pilot waits for left at ``now`` on a link of ``round_trip`` s."""
        self.gap = max(NUDGE_AFTER, round_trip + DELAYED_ACK)
        self.at, self.left = now + self.gap, NUDGES

    def take(self, now: float, unacknowledged: bool) -> bool:
        """Is an empty frame to go now?  Called once ``now >= at``; plans the next one."""
        if not unacknowledged or self.left <= 0:
            self.at, self.left = math.inf, 0
            return False
        self.left -= 1
        self.gap *= 2
        self.at = now + self.gap if self.left > 0 else math.inf
        return True


@dataclass
class _Connection:
    sock: socket.socket
    peer: str
    link: LinkConnection
    session: int = 0
    sent_upto: int = 0
    ack_sent: int = -1
    last_rx: float = field(default_factory=time.monotonic)
    last_tx: float = 0.0
    sent_bottles: Dict[FlowKey, Any] = field(default_factory=dict)
    received_bottles: Dict[FlowKey, Any] = field(default_factory=dict)
    state_encoders: Dict[FlowKey, StateEncoder] = field(default_factory=dict)
    state_decoders: Dict[FlowKey, StateDecoder] = field(default_factory=dict)
    closed: bool = False
    #: data frames that came in the same read as the peer's last handshake message
    early_frames: List[DataFrame] = field(default_factory=list)
    #: the presence last told the peer on this connection (None: not yet)
    presence_sent: Optional[Presence] = None


class TcpChannel:
    """Both directions of the TCP link, with reconnection and exactly-once delivery.

    ``on_message(key, value)`` receives streaming values (a Bottle or a
    :class:`RobotState`); reliable ones land in the journal's inbox and
    ``on_reliable()`` is called so the owner delivers them.  ``presence()``
    says which flows have their module end connected here (None while not yet
    known); it goes to the peer
    on each new connection and whenever it changes (call :meth:`kick` to send a
    change at once), and the peer's arrives through ``on_presence(flows)``.
    """

    def __init__(self, *, side: str, peer: str, port: int, listen: bool, config_text: str,
                 journal: Journal, routes: List[Route], period: float,
                 on_message: Callable[[FlowKey, Any], None], on_reliable: Callable[[], None],
                 on_connected: Callable[[], None] = lambda: None,
                 link_timeout: float = 5.0, bind_host: str = "",
                 key: Optional[LinkKey] = None, on_keys: Optional[KeysHook] = None,
                 presence: Callable[[], Optional[Presence]] = frozenset,
                 on_presence: Callable[[Presence], None] = lambda flows: None) -> None:
        self.side = side
        self.presence = presence
        self.on_presence = on_presence
        self.key = key if key is not None else LinkKey.none()
        self.on_keys = on_keys
        self.peer_host = peer
        self.port = port
        self.listen = listen
        self.bind_host = bind_host
        self.fingerprint = fingerprint(config_text)
        self.journal = journal
        self.routes = {route.key: route for route in routes}
        self.period = period
        self.link_timeout = link_timeout
        self.on_message = on_message
        self.on_reliable = on_reliable
        self.on_connected = on_connected
        self.stats = LinkStats()
        self.drops = DropLedger("TCP channel", log)
        self.phase = "down"
        self.phase_since = time.monotonic()
        self._slots: Dict[FlowKey, Any] = {}
        self._dirty: Dict[FlowKey, bool] = {}
        self._lock = threading.Lock()
        self._wake = threading.Condition(self._lock)
        self._urgent = False
        self._events: Dict[FlowKey, float] = {}       # flows with an event waiting -> due time
        self._event_sent: Dict[FlowKey, float] = {}   # flow -> when its last event left
        self._connection: Optional[_Connection] = None
        self._stopping = threading.Event()
        self._threads: List[threading.Thread] = []
        self._listener: Optional[socket.socket] = None
        self._peer_ips = self._resolve_peer()
        self._handshakes = threading.BoundedSemaphore(MAX_HANDSHAKES)

    # -- public surface ---------------------------------------------------------------

    def start(self) -> None:
        if self.listen:
            self._listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
            self._listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            self._listener.bind((self.bind_host, self.port))
            self._listener.listen(4)
            self._listener.settimeout(0.5)
            log.info("TCP channel listening on port %d for %s", self.port, self.peer_host)
        self._spawn(self._connect_loop, "tcp connect")
        self._spawn(self._send_loop, "tcp send")

    def stop(self) -> None:
        self._stopping.set()
        with self._wake:
            self._wake.notify_all()
        self._drop("bridge stopping")
        if self._listener is not None:
            self._listener.close()
        for thread in self._threads:
            thread.join(timeout=3)

    def post(self, key: FlowKey, value: Any, event: bool = False) -> None:
        """The newest value of a streaming flow; it leaves with the next period's frame.

        An ``event`` leaves at once (see the module docstring), or when the
        flow's :data:`EVENT_MIN_GAP` has passed since its last event.
        """
        with self._wake:
            self._slots[key] = value
            self._dirty[key] = True
            if event and key not in self._events:
                self._events[key] = self._event_sent.get(key, -math.inf) + EVENT_MIN_GAP
                self._wake.notify_all()

    def send_reliable(self, key: FlowKey, bottle: Any) -> int:
        """Journal a reliable Bottle (raises :class:`~bridge.journal.QueueFull`); send at once."""
        seq = self.journal.append(key[0], key[1], compact.encode(bottle))
        self.kick()
        return seq

    def kick(self) -> None:
        with self._wake:
            self._urgent = True
            self._wake.notify_all()

    @property
    def connected(self) -> bool:
        return self.phase == "up"

    def silent_s(self) -> Optional[float]:
        """Seconds since the peer was last heard on the current connection (None: none).

        The peer sends at least every :data:`KEEPALIVE`, so a silence past that says the
        link is gone long before ``link_timeout`` drops the connection."""
        connection = self._connection
        if connection is None or connection.closed:
            return None
        return max(0.0, time.monotonic() - connection.last_rx)

    # -- phases --------------------------------------------------------------------

    def _move(self, event: str) -> None:
        nxt = PHASES[self.phase].get(event)
        if nxt is None:
            raise BridgeError(f"TCP channel: event {event!r} is illegal in phase {self.phase}")
        self.phase, self.phase_since = nxt, time.monotonic()

    def _spawn(self, target: Callable[[], None], name: str) -> None:
        thread = threading.Thread(target=target, name=f"bridge {name}", daemon=True)
        thread.start()
        self._threads = [t for t in self._threads if t.is_alive()] + [thread]

    def _resolve_peer(self) -> set:
        try:
            return {info[4][0] for info in socket.getaddrinfo(self.peer_host, None,
                                                               socket.AF_INET)}
        except OSError:
            return set()

    def _connect_loop(self) -> None:
        announced = False
        while not self._stopping.is_set():
            if self.listen:
                self._accept_once()
                continue
            if self._connection is not None and not self._connection.closed:
                self._stopping.wait(0.5)
                continue
            sock = self._dial()
            if sock is None:
                if not announced:
                    log.warning("TCP channel: peer %s:%d unreachable, retrying every second",
                                self.peer_host, self.port)
                    announced = True
                continue
            announced = False
            if not self._run_handshake(sock):
                self._stopping.wait(1.0)

    def _dial(self) -> Optional[socket.socket]:
        try:
            sock = socket.create_connection((self.peer_host, self.port), timeout=3)
        except OSError as exc:
            self.stats.last_error = f"connect: {exc.strerror or exc}"
            self._stopping.wait(1.0)
            return None
        return sock

    def _accept_once(self) -> None:
        """Take one connection; its handshake runs in a thread of its own."""
        assert self._listener is not None
        try:
            sock, address = self._listener.accept()
        except (socket.timeout, OSError):
            return
        self._peer_ips = self._resolve_peer() or self._peer_ips
        if not drops.from_peer(address[0], self._peer_ips):
            self.drops.drop(Reason.STRANGER, f"connection from {address[0]} (expecting "
                                             f"{self.peer_host})")
            sock.close()
            return
        if not self._handshakes.acquire(blocking=False):
            self.drops.drop(Reason.BUSY, f"{MAX_HANDSHAKES} handshakes already running; "
                                         f"refused {address[0]}:{address[1]}")
            sock.close()
            return

        def handshake() -> None:
            try:
                self._run_handshake(sock)
            finally:
                self._handshakes.release()

        self._spawn(handshake, "tcp handshake")

    def _run_handshake(self, sock: socket.socket) -> bool:
        """Authenticate a new connection; once it is up, it replaces any older one."""
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_KEEPALIVE, 1)
        try:
            peer = "%s:%d" % sock.getpeername()[:2]
        except OSError:
            sock.close()
            return False
        if self.phase == "down":
            self._move("connected")
        try:
            connection = self._handshake(sock, peer)
        except (OSError, BridgeError) as exc:
            with self._lock:
                if self.phase == "handshake":
                    self._move("failed")
            host = peer.rsplit(":", 1)[0]
            if isinstance(exc, BridgeProtocolError):
                self.drops.peer_error(exc, f"handshake with {host}")
            message = f"handshake with {host} failed: {exc}"
            if message != self.stats.last_error:
                log.warning("TCP channel: %s", message)
            self.stats.last_error = message
            sock.close()
            return False
        old = self._connection
        if old is not None and not old.closed:
            log.info("TCP channel: the peer reconnected from %s; dropping the old connection",
                     peer)
            self._drop("replaced by a new authenticated connection")
        with self._wake:
            self._connection = connection
            for key in self._slots:
                self._dirty[key] = True  # the new connection starts with full values
            self._urgent = True
            if self.phase == "down":
                self._move("connected")
            self._move("hello_ok")
            self._wake.notify_all()
        self.stats.connects += 1
        self.stats.last_error = ""
        log.info("TCP channel up with %s (%s, peer session %x, resending after %d)", peer,
                 "authenticated" if self.key.keyed else "NOT authenticated: --no-auth",
                 connection.session, connection.sent_upto)
        self._keys_hook("installed", connection.link)
        self._spawn(lambda: self._receive_loop(connection), "tcp receive")
        try:
            self.on_connected()
        except Exception:  # noqa: BLE001 -- a hook's bug must not take the link down
            self.stats.internal_errors += 1
            log.exception("TCP channel: on_connected hook failed")
        return True

    def _keys_hook(self, event: str, link: LinkConnection) -> None:
        keys = link.udp_keys
        if self.on_keys is not None and keys is not None:
            self.on_keys(event, *keys)

    def _handshake(self, sock: socket.socket, peer: str) -> _Connection:
        link = LinkConnection(self.side, self.key, self.fingerprint, self.journal.session)
        deadline = time.monotonic() + HANDSHAKE_TIMEOUT
        sock.sendall(link.start())
        accepted = 0
        while True:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise BridgeProtocolError(f"no complete handshake within "
                                          f"{HANDSHAKE_TIMEOUT:.0f} s")
            sock.settimeout(remaining)
            try:
                data = sock.recv(4096)
            except socket.timeout:
                continue
            if not data:  # not a drop: usually the peer refusing us, and saying so itself
                raise ConnectionAbortedError("peer closed during the handshake")
            link.feed(data)
            while (event := link.next_event()) is not None:
                if isinstance(event, PeerHello):
                    sock.sendall(link.send_auth())
                elif isinstance(event, PeerAuthenticated):
                    accepted = self.journal.accepted(event.session)
                    sock.sendall(link.send_resume(accepted))
                    self._keys_hook("offered", link)
                elif isinstance(event, LinkUp):
                    # The peer's link was up as soon as it sent its last handshake message:
                    # its first data frames may share this read (or sit, partial, in the
                    # link's buffer) and are handled once the connection is installed.
                    # Dropping them lost reliable messages: the peer had sent them.
                    # (Once up, the link yields only data: a repeated handshake raises.)
                    early = link.receive_data(b"")
                    sock.settimeout(None)
                    self.journal.acknowledge(event.peer_accepted)
                    return _Connection(sock, peer, link, event.peer_session,
                                       sent_upto=event.peer_accepted, ack_sent=accepted,
                                       early_frames=[e.frame for e in early
                                                     if isinstance(e, FrameReceived)])
                else:
                    raise BridgeProtocolError("peer sent data before the handshake ended")

    def round_trip_ms(self) -> Optional[float]:
        """The link's round trip as the kernel measures it (smoothed ``tcpi_rtt``), if up."""
        connection = self._connection
        if connection is None or connection.closed:
            return None
        try:
            info = connection.sock.getsockopt(socket.IPPROTO_TCP, socket.TCP_INFO, 104)
        except OSError:
            return None
        return struct.unpack_from("<I", info, TCP_INFO_RTT_OFFSET)[0] / 1000.0

    def _drop(self, reason: str, which: Optional[_Connection] = None) -> None:
        """Close the current connection -- or only ``which``, if it is still the current one
        (a receive loop noticing its old connection die must not close its successor)."""
        with self._wake:
            connection = self._connection
            if connection is None or connection.closed or \
                    (which is not None and which is not connection):
                if which is not None and not which.closed:
                    which.closed = True
                    which.sock.close()
                return
            connection.closed = True
            self._connection = None
            if self.phase == "up":
                self._move("failed")
        try:
            connection.sock.shutdown(socket.SHUT_RDWR)
        except OSError:
            pass
        connection.sock.close()
        log.warning("TCP channel down (%s): %s", connection.peer, reason)

    # -- receiving ---------------------------------------------------------------------

    def _receive_loop(self, connection: _Connection) -> None:
        sock = connection.sock
        try:
            sock.settimeout(0.25)
        except OSError:  # dropped (and closed) before this thread ran: nothing to receive
            return
        if not self._handle_frames(connection, connection.early_frames):
            return
        connection.early_frames = []
        while not connection.closed and not self._stopping.is_set():
            try:
                data = sock.recv(65536)
            except socket.timeout:
                if time.monotonic() - connection.last_rx > self.link_timeout:
                    self._drop(f"nothing heard for {self.link_timeout:.0f} s", connection)
                    return
                continue
            except OSError as exc:
                self._drop(f"receive failed: {exc.strerror or exc}", connection)
                return
            if not data:
                self._drop("peer closed the connection", connection)
                return
            connection.last_rx = time.monotonic()
            self.stats.bytes_in += len(data)
            try:
                received = [event.frame for event in connection.link.receive_data(data)
                            if isinstance(event, FrameReceived)]
            except BridgeProtocolError as exc:
                self.drops.peer_error(exc, "frame")
                self.stats.last_error = str(exc)
                self._drop(f"bad frame from the peer: {exc}", connection)
                return
            if not self._handle_frames(connection, received):
                return

    def _handle_frames(self, connection: _Connection, received: List[DataFrame]) -> bool:
        """Deliver the frames; False when one made us drop the connection."""
        try:
            for frame in received:
                self._on_frame(connection, frame)
        except BridgeProtocolError as exc:
            self.drops.peer_error(exc, "frame")
            self.stats.last_error = str(exc)
            self._drop(f"bad frame from the peer: {exc}", connection)
            return False
        except Exception:  # noqa: BLE001 -- our bug: seen, counted, and the link re-made
            self.stats.internal_errors += 1
            log.exception("TCP channel: receiving failed (a bug); dropping the connection "
                          "so the link does not claim to be up")
            self._drop("internal error while receiving", connection)
            return False
        return True

    def _on_frame(self, connection: _Connection, frame: DataFrame) -> None:
        self.stats.frames_in += 1
        if frame.ack is not None:
            self.journal.acknowledge(frame.ack)
        seq = frame.seq
        new_reliable = False
        for entry in frame.entries:
            self.stats.payload_in += len(entry.payload)
            route = self.routes.get(FlowKey(entry.id, entry.kind))
            if route is None:
                self.drops.drop(Reason.UNKNOWN_ID, f"entry id {entry.id} kind {entry.kind}")
                continue
            if route.reliable:
                if seq is None or entry.delta:
                    raise BridgeProtocolError(f"reliable entry {route.label} without a "
                                              f"sequence number")
                compact.decode(entry.payload)  # refuse garbage before it is journalled
                if self.journal.accept(connection.session, seq, entry.id, entry.kind,
                                       entry.payload):
                    self.stats.reliable_accepted += 1
                    new_reliable = True
                else:
                    self.drops.drop(Reason.DUPLICATE, f"{route.label} #{seq}")
                seq += 1
                continue
            try:
                value = self._decode_streaming(connection, route, entry)
            except BridgeProtocolError as exc:
                raise BridgeProtocolError(f"{route.label}: {exc}") from None
            try:
                self.on_message(route.key, value)
            except Exception:  # noqa: BLE001 -- a consumer's bug loses one latest-only value
                self.stats.internal_errors += 1
                log.exception("TCP channel: delivering %s failed (a bug)", route.label)
        if new_reliable:
            self.kick()  # owe an ack
            self.on_reliable()
        # After the entries: a module's last warning is journalled before the word that it
        # left, so its stand-in stays until the warning is written.  Said only when it
        # changes: a replaced connection's last frames must not overwrite the current word.
        if frame.presence is not None and connection is self._connection:
            try:
                self.on_presence(frame.presence)
            except Exception:  # noqa: BLE001 -- a consumer's bug; the next change says it again
                self.stats.internal_errors += 1
                log.exception("TCP channel: taking the peer's presence failed (a bug)")

    def _decode_streaming(self, connection: _Connection, route: Route, entry: Entry) -> Any:
        if route.form is Form.STATE:
            decoder = connection.state_decoders.setdefault(route.key, StateDecoder())
            return decoder.decode(entry.payload)
        if entry.delta:
            previous = connection.received_bottles.get(route.key)
            if previous is None:
                raise BridgeProtocolError("a delta before any full message")
            bottle = compact.decode_delta(entry.payload, previous)
        else:
            bottle = compact.decode(entry.payload)
        connection.received_bottles[route.key] = bottle
        return bottle

    # -- sending -----------------------------------------------------------------------

    def _send_loop(self) -> None:
        next_tick = time.monotonic() + self.period
        nudges = _Nudges()
        while not self._stopping.is_set():
            with self._wake:
                while not self._urgent and not self._stopping.is_set():
                    wake_at = min([next_tick, nudges.at, *self._events.values()])
                    remaining = wake_at - time.monotonic()
                    if remaining <= 0:
                        break
                    self._wake.wait(remaining)
                self._urgent = False
                connection = self._connection
                now = time.monotonic()
                tick = now >= next_tick
                due = set(self._events) if tick else \
                    {key for key, when in self._events.items() if when <= now}
                for key in due:
                    del self._events[key]
                    self._event_sent[key] = now
            if tick:
                next_tick = max(next_tick + self.period, now)
            if connection is None or connection.closed:
                nudges.at = math.inf
                continue
            try:
                nudge = nudges.take(now, _only_unacknowledged(connection.sock)) \
                    if now >= nudges.at else False
                if self._send_frame(connection, streams=None if tick else due, force=nudge):
                    nudges.awaited_frame_sent(time.monotonic(),
                                              (self.round_trip_ms() or 0.0) / 1000.0)
                if nudge:
                    self.stats.nudges += 1
            except OSError as exc:
                self._drop(f"send failed: {exc.strerror or exc}", connection)
            except BridgeError as exc:
                log.error("TCP channel: %s", exc)
            except Exception:  # noqa: BLE001 -- our bug: seen, counted, and the link re-made
                self.stats.internal_errors += 1
                log.exception("TCP channel: sending failed (a bug); dropping the connection")
                self._drop("internal error while sending", connection)

    def _streaming_entries(self, connection: _Connection,
                           only: Optional[set] = None) -> List[bytes]:
        with self._lock:
            ready = [(key, self._slots[key]) for key, dirty in self._dirty.items()
                     if dirty and (only is None or key in only)]
            for key, _ in ready:
                self._dirty[key] = False
        out = []
        for key, value in ready:
            route = self.routes[key]
            if callable(value):  # a lazy snapshot: read the newest value only now
                value = value()
            if route.form is Form.STATE:
                encoder = connection.state_encoders.setdefault(key, StateEncoder(self.period))
                entry = Entry(key[0], key[1], encoder.encode(value))
            else:
                full = compact.encode(value)
                previous = connection.sent_bottles.get(key)
                delta = compact.encode_delta(value, previous) if previous is not None else None
                entry = Entry(key[0], key[1], delta, True) if delta is not None and \
                    len(delta) < len(full) else Entry(key[0], key[1], full)
                connection.sent_bottles[key] = value
            self.stats.payload_out += len(entry.payload)
            out.append(frames.entry_bytes(entry))
            self._count(entry.id, len(out[-1]))
        return out

    def _count(self, ident: int, size: int) -> None:
        self.stats.bytes_by_id[ident] = self.stats.bytes_by_id.get(ident, 0) + size

    def _send_frame(self, connection: _Connection, streams: Optional[set],
                    force: bool = False) -> bool:
        """One frame: what the journal owes, the ack, and the streaming flows
        ``streams`` names (``None``: every changed flow, the periodic frame); sent even
        empty when ``force``.  Says whether it held what a pilot waits for (reliable
        messages, events, presence)."""
        encoded: List[bytes] = []
        reliable = self.journal.unacknowledged(after=connection.sent_upto,
                                               limit=MAX_RELIABLE_PER_FRAME)
        seq = reliable[0].seq if reliable else None
        for item in reliable:
            payload = item.payload
            route = self.routes.get(FlowKey(item.id, item.kind))
            if route is not None and route.expiring:   # it waited here: the module must know
                payload = aged_payload(payload, time.time() - item.queued)
            encoded.append(frames.entry_bytes(Entry(item.id, item.kind, payload)))
            self.stats.payload_out += len(payload)
            self._count(item.id, len(encoded[-1]))
        events = False
        if streams is None or streams:
            backlog = _unsent_bytes(connection.sock)
            if drops.hold_back(backlog):
                self.drops.drop(Reason.HELD_BACK, f"{backlog} bytes still unsent")
            else:
                streaming = self._streaming_entries(connection, only=streams)
                events = streams is not None and bool(streaming)
                encoded.extend(streaming)
        accepted = self.journal.accepted(connection.session)
        ack = accepted if accepted != connection.ack_sent else None
        present = self.presence()  # None: not known yet
        presence = present if present is not None and present != connection.presence_sent \
            else None
        now = time.monotonic()
        if not encoded and ack is None and presence is None and not force and \
                now - connection.last_tx < KEEPALIVE:
            return False
        frame = connection.link.send_data(frames.data_body(ack=ack, seq=seq, encoded=encoded,
                                                           presence=presence))
        connection.sock.sendall(frame)
        connection.last_tx = now
        connection.ack_sent = accepted
        if presence is not None:
            connection.presence_sent = presence
        if reliable:
            connection.sent_upto = reliable[-1].seq
            self.stats.reliable_sent += len(reliable)
            if len(reliable) == MAX_RELIABLE_PER_FRAME:
                self.kick()
        self.stats.frames_out += 1
        self.stats.bytes_out += len(frame)
        return bool(reliable) or events or presence is not None
