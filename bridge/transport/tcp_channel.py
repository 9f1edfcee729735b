"""The TCP channel: commands, statuses and robot state between the two bridges.

Theory of operation
-------------------
One TCP connection joins the bridges; the robot side listens, the pilot side
dials (either can be chosen).  The channel's phase (:mod:`bridge.transport.channel_phase`)
is down, handshake or up; every failure -- a reset, a forged frame, a silent
peer for ``link_timeout`` seconds -- drops the connection and the dialer tries
again every second, forever.

Each connection speaks two sans-IO protocols, and this module only moves their
bytes, gives them the time and tells them what the kernel says of the socket:

* the link protocol of :mod:`bridge.wire.link` (:class:`~bridge.wire.link.LinkConnection`):
  HELLO, mutual authentication with the shared key, RESUME, then frames sealed
  with authentication tags;
* the frame session of :mod:`bridge.transport.frame_session`
  (:class:`~bridge.transport.frame_session.FrameSession`): what the data frames say --
  acknowledgements and resends from the :class:`~bridge.transport.journal.Journal`,
  duplicates, deltas, the period's frame and the events that leave at once, the
  empty frames that follow an unacknowledged one.

A connection that fails authentication, or later sends a frame whose tag is
wrong, is dropped and counted (:mod:`bridge.transport.drops`); on the listening side each
handshake runs in its own thread (at most :data:`MAX_HANDSHAKES`) and an
established link is only replaced by a connection that has proved the key, so
a stranger can neither stall the listener nor push the real peer off.  A proven
connection is installed, replacing any older one, and a current one dropped,
under the channel's lock, with the phase moved in the same step.

Threads: the connect thread dials (or accepts, starting a handshake thread per
connection); each installed connection has a receive thread; one send thread
sleeps until the period's tick, a due event or nudge, or a :meth:`kick` (a
reliable message journalled, an ack owed, presence changed).
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
from typing import Any, List, Optional, Tuple

from bridge.errors import BridgeError, BridgeProtocolError
from bridge.flows import FlowKey, Route
from bridge.transport import drops
from bridge.transport.channel_phase import ChannelPhase
from bridge.transport.copies import ReliableCopy
from bridge.transport.drops import DropLedger, Reason
from bridge.transport.frame_session import (Dropped, Due, Event, FrameSession, KernelQueue,
                                            LinkStats, PresenceHeard, ReliableAccepted, Streams,
                                            StreamValue, unaged)
from bridge.transport.journal import Journal
from bridge.transport.link_budget import LinkBudget, tcp_bytes
from bridge.transport.nursery import Nursery
from bridge.wire import compact
from bridge.wire.frames import DataFrame, Presence
from bridge.wire.link import (FrameReceived, LinkConnection, LinkKey, LinkUp, PeerAuthenticated,
                              PeerHello)

log = logging.getLogger("bridge.tcp")

#: Where ``struct tcp_info`` (linux/tcp.h) keeps ``tcpi_rtt``, in microseconds.
TCP_INFO_RTT_OFFSET = 68
#: Seconds a connection has to complete the handshake.
HANDSHAKE_TIMEOUT = 5.0
#: Handshakes run at once on the listening side; more connections are refused.
MAX_HANDSHAKES = 4
#: ``SIOCOUTQNSD`` (linux/sockios.h): bytes of a TCP socket not yet sent at all.
SIOCOUTQNSD = 0x894B


def fingerprint(text: str) -> bytes:
    return hashlib.sha256(text.encode()).digest()[:8]


# -- what the kernel says of a socket ------------------------------------------------------


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


def _round_trip_ms(sock: socket.socket) -> Optional[float]:
    """The kernel's smoothed round trip (``tcpi_rtt``) of ``sock``; None once it is closed."""
    try:
        info = sock.getsockopt(socket.IPPROTO_TCP, socket.TCP_INFO, 104)
    except OSError:
        return None
    return struct.unpack_from("<I", info, TCP_INFO_RTT_OFFSET)[0] / 1000.0


def _kernel_queue(sock: socket.socket, budget: Optional[LinkBudget],
                  now: float) -> KernelQueue:
    """What the frame session needs to know of ``sock`` before each frame (cheap ioctls),
    and of the radio's queue where a link budget models it: the larger of the model and
    what the socket still holds for the peer (in the radio's queue, or soon)."""
    unsent = _unsent_bytes(sock)
    queued = 0 if budget is None else int(max(budget.queued(now), unsent))
    return KernelQueue(unsent, _only_unacknowledged(sock),
                       (_round_trip_ms(sock) or 0.0) / 1000.0, queued,
                       budget is not None and queued >= budget.limit)


def _shut(sock: socket.socket) -> None:
    try:
        sock.shutdown(socket.SHUT_RDWR)
    except OSError:
        pass  # already shut or reset: close() still releases it
    sock.close()


class _Lost(Exception):
    """The connection is gone (reset, closed, silent); the message says how."""


@dataclass(eq=False)
class _Connection:
    """One proven connection: its socket, its link protocol, its frame session."""

    sock: socket.socket
    peer: str
    link: LinkConnection
    session: FrameSession
    last_rx: float = field(default_factory=time.monotonic)
    closed: bool = False
    #: data frames that came in the same read as the peer's last handshake message
    early_frames: List[DataFrame] = field(default_factory=list)
    #: the receive thread's frames and the UDP channel's copies reach the session in turn
    receiving: threading.Lock = field(default_factory=threading.Lock)

    def read(self, link_timeout: float, stats: LinkStats) -> List[DataFrame]:
        """The frames the next bytes complete ([] after a quiet read timeout); raises
        :class:`_Lost`, or :class:`BridgeProtocolError` for bytes the link refuses."""
        try:
            data = self.sock.recv(65536)
        except socket.timeout:
            if time.monotonic() - self.last_rx > link_timeout:
                raise _Lost(f"nothing heard for {link_timeout:.0f} s") from None
            return []
        except OSError as exc:
            raise _Lost(f"receive failed: {exc.strerror or exc}") from None
        if not data:
            raise _Lost("peer closed the connection")
        self.last_rx = time.monotonic()
        stats.bytes_in += len(data)
        return [event.frame for event in self.link.receive_data(data)
                if isinstance(event, FrameReceived)]


class _Connector:
    """Gets the channel its proven connections: who may connect, and the handshake.

    The dialer tries the peer every second while no link is up.  The listener takes
    connections from the peer's addresses only and runs each handshake in a thread of its
    own (at most :data:`MAX_HANDSHAKES`; more are refused), so a stranger can neither stall
    it nor, without the key, get a connection installed.  Every proven connection goes to
    the channel's ``_install``, which replaces an older one; every way out of a handshake
    moves the phase, and closes the socket unless it was installed.  (A part of its
    channel: it reads the channel's settings and shares its phase, counters and threads.)
    """

    def __init__(self, channel: "TcpChannel") -> None:
        self.channel = channel
        self.phase, self.stats, self.drops = channel._phase, channel.stats, channel.drops
        self.stopping = channel._stopping
        self._listener: Optional[socket.socket] = None
        self._peer_ips = self._resolve_peer()
        self._handshakes = threading.BoundedSemaphore(MAX_HANDSHAKES)

    def open(self) -> None:
        """Listen, if this side listens (at once, so a port in use fails the start)."""
        settings = self.channel.settings
        if not settings.listen:
            return
        self._listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self._listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self._listener.bind((settings.bind_host, settings.port))
        self._listener.listen(4)
        self._listener.settimeout(0.5)
        log.info("TCP channel listening on port %d for %s", settings.port, settings.peer)

    def close(self) -> None:
        if self._listener is not None:
            self._listener.close()

    def run(self) -> None:
        """The connect thread: accept, or dial while no link is up, until the channel stops."""
        channel, announced = self.channel, False
        settings = channel.settings
        while not self.stopping.is_set():
            if self._listener is not None:
                self._accept_once()
                continue
            if channel.connected:
                self.stopping.wait(0.5)
                continue
            try:
                sock = socket.create_connection((settings.peer, settings.port), timeout=3)
            except OSError as exc:
                self.stats.last_error = f"connect: {exc.strerror or exc}"
                if not announced:
                    log.warning("TCP channel: peer %s:%d unreachable, retrying every second",
                                settings.peer, settings.port)
                    announced = True
                self.stopping.wait(1.0)
                continue
            announced = False
            if not self.run_handshake(sock):
                self.stopping.wait(1.0)

    def _resolve_peer(self) -> set:
        try:
            return {info[4][0] for info in socket.getaddrinfo(self.channel.settings.peer, None,
                                                               socket.AF_INET)}
        except OSError:
            return set()

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
                                             f"{self.channel.settings.peer})")
            sock.close()
            return
        if not self._handshakes.acquire(blocking=False):
            self.drops.drop(Reason.BUSY, f"{MAX_HANDSHAKES} handshakes already running; "
                                         f"refused {address[0]}:{address[1]}")
            sock.close()
            return

        def handshake() -> None:
            try:
                self.run_handshake(sock)
            finally:
                self._handshakes.release()

        self.channel._nursery.start_soon(handshake, "tcp handshake")

    def run_handshake(self, sock: socket.socket) -> bool:
        """Authenticate a new connection and have it installed; False if it was not."""
        try:
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_KEEPALIVE, 1)
            peer = "%s:%d" % sock.getpeername()[:2]
        except OSError:
            sock.close()
            return False
        self.phase.move("connected")
        try:
            connection = self._handshake(sock, peer)
        except (OSError, BridgeError) as exc:
            self.phase.move("failed")
            host = peer.rsplit(":", 1)[0]
            if isinstance(exc, BridgeProtocolError):
                self.drops.peer_error(exc, f"handshake with {host}")
            message = f"handshake with {host} failed: {exc}"
            if message != self.stats.last_error:
                log.warning("TCP channel: %s", message)
            self.stats.last_error = message
            sock.close()
            return False
        except Exception:  # noqa: BLE001 -- our bug: seen, counted, the socket not leaked
            self.phase.move("failed")
            self.stats.internal_errors += 1
            log.exception("TCP channel: the handshake with %s failed (a bug)", peer)
            sock.close()
            return False
        return self.channel._install(connection)

    def _handshake(self, sock: socket.socket, peer: str) -> _Connection:
        """The link's handshake over ``sock``, the frame session's RESUMEs with it."""
        channel = self.channel
        link = LinkConnection(channel.settings.side, channel.settings.key, channel.fingerprint,
                              channel.journal.session)
        session: Optional[FrameSession] = None
        deadline = time.monotonic() + HANDSHAKE_TIMEOUT
        sock.sendall(link.start())
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
                    session = channel._new_session(event.session)
                    sock.sendall(link.send_resume(session.resume_point()))
                    channel._keys_hook("offered", link)
                elif isinstance(event, LinkUp):
                    # The peer's link was up as soon as it sent its last handshake message:
                    # its first data frames may share this read (or sit, partial, in the
                    # link's buffer) and are handled once the connection is installed.
                    # Dropping them lost reliable messages: the peer had sent them.
                    # (Once up, the link yields only data: a repeated handshake raises.)
                    assert session is not None   # the link says LinkUp after the proof
                    early = link.receive_data(b"")
                    sock.settimeout(None)
                    session.peer_resumed(event.peer_accepted)
                    return _Connection(sock, peer, link, session,
                                       early_frames=[e.frame for e in early
                                                     if isinstance(e, FrameReceived)])
                else:
                    raise BridgeProtocolError("peer sent data before the handshake ended")


@dataclass(frozen=True)
class TcpSettings:
    """Where one side's TCP channel meets the other, and how it holds the link."""

    side: str                 # "robot" or "pilot"
    peer: str                 # the other PC's address
    port: int                 # the robot listens on it, the pilot connects to it
    listen: bool
    config_text: str          # the bridge's XML: both sides must hold the same (fingerprint)
    period: float             # seconds between the frames of streaming values
    link_timeout: float = 5.0  # seconds of silence after which the link is down
    bind_host: str = ""
    key: LinkKey = field(default_factory=LinkKey.none)


class TcpListener:
    """What a TCP channel tells its owner, and asks of it: override what you need (as
    python-can's Listener).  Called from the channel's threads."""

    def message(self, key: FlowKey, value: Any) -> None:
        """A streaming value arrived (a Bottle or a :class:`RobotState`)."""

    def reliable(self) -> None:
        """Reliable messages landed in the journal's inbox: deliver them."""

    def connected(self) -> None:
        """A connection was proven and installed."""

    def keys(self, event: str, send_key: bytes, receive_key: bytes) -> None:
        """The link's datagram keys, for the UDP channel: ``offered`` (the peer may already
        send with ``receive_key``), then ``installed`` (send with ``send_key`` from now on)."""

    def presence(self) -> Optional[Presence]:
        """Which flows have their module end connected here (None: not known yet)."""
        return frozenset()

    def peer_presence(self, flows: Presence) -> None:
        """The peer said which of its flows have their module end connected."""

    def copies(self, copies: List[Tuple[FlowKey, ReliableCopy]]) -> None:
        """A frame left with these reliable messages of flows sent as datagram copies too."""

    def age(self, payload: bytes, seconds: float) -> bytes:
        """An expiring message as it leaves after ``seconds`` in the outbox."""
        return unaged(payload, seconds)


class TcpChannel:
    """Both directions of the TCP link, with reconnection and exactly-once delivery.

    Streaming values go to ``listener.message``; reliable ones land in the journal's inbox
    and ``listener.reliable()`` is called so the owner delivers them.  The listener's
    ``presence()`` goes to the peer on each new connection and whenever it changes (call
    :meth:`kick` to send a change at once), and the peer's arrives through
    ``peer_presence``.  After each frame, ``copies`` gets its reliable messages of flows
    with datagram copies (:mod:`bridge.transport.copies`); the copies that come back go to
    :meth:`accept_copy`.
    """

    def __init__(self, settings: TcpSettings, journal: Journal, routes: List[Route],
                 listener: TcpListener, budget: Optional[LinkBudget] = None) -> None:
        self.settings = settings
        #: the radio's queue, shared with the UDP channel: full, streaming values wait
        self.budget = budget
        self.listener = listener
        self.fingerprint = fingerprint(settings.config_text)
        self.journal = journal
        self.routes = {route.key: route for route in routes}
        self.stats = LinkStats()
        self.drops = DropLedger("TCP channel", log)
        self._phase = ChannelPhase()
        self._streams = Streams(settings.period, time.monotonic())
        self._wake = threading.Condition()   # the current connection, its phase, _urgent
        self._urgent = False
        self._connection: Optional[_Connection] = None
        self._stopping = threading.Event()
        self._nursery = Nursery()
        self._connector = _Connector(self)

    # -- public surface ---------------------------------------------------------------

    def start(self) -> None:
        self._connector.open()
        self._nursery.start_soon(self._connector.run, "tcp connect")
        self._nursery.start_soon(self._send_loop, "tcp send")

    def stop(self) -> None:
        self._stopping.set()
        with self._wake:
            self._wake.notify_all()
        self._drop("bridge stopping")
        self._connector.close()
        self._nursery.join()

    def post(self, key: FlowKey, value: Any, event: bool = False) -> None:
        """The newest value of a streaming flow; it leaves with the next period's frame.

        An ``event`` leaves at once (see :mod:`bridge.transport.frame_session`), or when the
        flow's :data:`EVENT_MIN_GAP` has passed since its last event.
        """
        if self._streams.post(key, value, event):
            with self._wake:
                self._wake.notify_all()

    def send_reliable(self, key: FlowKey, bottle: Any) -> int:
        """Journal a reliable Bottle (raises :class:`~bridge.transport.journal.QueueFull`);
        send at once."""
        seq = self.journal.append(key.id, key.kind, compact.encode(bottle))
        self.kick()
        return seq

    def accept_copy(self, key: FlowKey, copy: ReliableCopy) -> bool:
        """A reliable message's datagram copy: journalled if the current connection's
        session expects it next (then delivered as if its frame had come); False if not."""
        connection = self._connection
        if connection is None or connection.closed:
            return False
        try:
            with connection.receiving:
                event = connection.session.accept_copy(key, copy, time.monotonic())
        except BridgeProtocolError as exc:
            self.drops.peer_error(exc, "reliable copy")
            return False
        if event is None:
            return False
        self._deliver(connection, [event])
        return True

    def kick(self) -> None:
        with self._wake:
            self._urgent = True
            self._wake.notify_all()

    @property
    def phase(self) -> str:
        """"down", "handshake" or "up" (:mod:`bridge.transport.channel_phase`)."""
        return self._phase.phase

    @property
    def phase_since(self) -> float:
        return self._phase.since

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

    def round_trip_ms(self) -> Optional[float]:
        """The link's round trip as the kernel measures it (smoothed ``tcpi_rtt``), if up."""
        connection = self._connection
        if connection is None or connection.closed:
            return None
        return _round_trip_ms(connection.sock)

    # -- connections -------------------------------------------------------------------

    def _new_session(self, peer_session: int) -> FrameSession:
        """The frame session of a connection whose peer proved the key."""
        return FrameSession(self.journal, self.routes, self._streams, peer_session,
                            period=self.settings.period, stats=self.stats, age=self.listener.age)

    def _install(self, connection: _Connection) -> bool:
        """Make a proven connection the current one, closing any older one: one step under
        the lock, so two handshakes ending together cannot both find no link and both
        install, or lose one's socket."""
        with self._wake:
            old = None
            if self._stopping.is_set():
                self._phase.move("failed")
                connection.closed = True
            else:
                old, self._connection = self._connection, connection
                self._phase.move("hello_ok")
                if old is not None:
                    old.closed = True
                self._streams.restart()   # the new connection starts with full values
                self._urgent = True
                self._wake.notify_all()
        if connection.closed:
            _shut(connection.sock)
            return False
        if old is not None:
            _shut(old.sock)
            log.warning("TCP channel: the peer reconnected from %s; the connection from %s "
                        "is replaced", connection.peer, old.peer)
        self.stats.connects += 1
        self.stats.last_error = ""
        log.info("TCP channel up with %s (%s, peer session %x, resending after %d)",
                 connection.peer,
                 "authenticated" if self.settings.key.keyed else "NOT authenticated: --no-auth",
                 connection.session.peer_session, connection.session.sent_upto or 0)
        self._keys_hook("installed", connection.link)
        self._nursery.start_soon(lambda: self._receive_loop(connection), "tcp receive")
        try:
            self.listener.connected()
        except Exception:  # noqa: BLE001 -- a hook's bug must not take the link down
            self.stats.internal_errors += 1
            log.exception("TCP channel: the listener's connected() failed")
        return True

    def _keys_hook(self, event: str, link: LinkConnection) -> None:
        keys = link.udp_keys
        if keys is not None:
            self.listener.keys(event, *keys)

    def _drop(self, reason: str, which: Optional[_Connection] = None) -> None:
        """Close the current connection -- or only ``which``, if it is still the current one
        (a receive loop noticing its old connection die must not close its successor)."""
        with self._wake:
            current = self._connection
            if current is not None and (which is None or which is current):
                self._connection = None
                current.closed = True
                self._phase.move("lost")
            else:
                if which is None or which.closed:
                    return
                which.closed = True     # a replaced connection: closed quietly
                current = None
        if current is None:
            which.sock.close()
            return
        _shut(current.sock)
        log.warning("TCP channel down (%s): %s", current.peer, reason)

    # -- receiving ---------------------------------------------------------------------

    def _receive_loop(self, connection: _Connection) -> None:
        try:
            connection.sock.settimeout(0.25)
        except OSError:  # dropped (and closed) before this thread ran: nothing to receive
            return
        received, connection.early_frames = connection.early_frames, []
        while self._handle_frames(connection, received):
            if connection.closed or self._stopping.is_set():
                return
            try:
                received = connection.read(self.settings.link_timeout, self.stats)
            except _Lost as lost:
                self._drop(str(lost), connection)
                return
            except BridgeProtocolError as exc:
                self._bad_frame(connection, exc)
                return

    def _bad_frame(self, connection: _Connection, exc: BridgeProtocolError) -> None:
        self.drops.peer_error(exc, "frame")
        self.stats.last_error = str(exc)
        self._drop(f"bad frame from the peer: {exc}", connection)

    def _handle_frames(self, connection: _Connection, received: List[DataFrame]) -> bool:
        """Deliver the frames; False when one made us drop the connection."""
        try:
            for frame in received:
                self.stats.frames_in += 1
                with connection.receiving:
                    events = connection.session.receive(frame, connection.last_rx)
                self._deliver(connection, events)
        except BridgeProtocolError as exc:
            self._bad_frame(connection, exc)
            return False
        except Exception:  # noqa: BLE001 -- our bug: seen, counted, and the link re-made
            self.stats.internal_errors += 1
            log.exception("TCP channel: receiving failed (a bug); dropping the connection "
                          "so the link does not claim to be up")
            self._drop("internal error while receiving", connection)
            return False
        return True

    def _deliver(self, connection: _Connection, events: List[Event]) -> None:
        """One frame's events to the owner: values, then the word that reliable messages
        wait, then the presence (a module's last warning is journalled before the word that
        it left, so its stand-in stays until the warning is written)."""
        for event in events:
            if isinstance(event, StreamValue):
                try:
                    self.listener.message(event.key, event.value)
                except Exception:  # noqa: BLE001 -- a consumer's bug loses one latest value
                    self.stats.internal_errors += 1
                    log.exception("TCP channel: delivering %s failed (a bug)",
                                  self.routes[event.key].label)
            elif isinstance(event, Dropped):
                self.drops.drop(event.reason, event.detail)
        if any(isinstance(event, ReliableAccepted) for event in events):
            self.kick()  # owe an ack
            self.listener.reliable()
        # Taken from the current connection only: a replaced connection's last frames must
        # not overwrite the current word.
        heard = events[-1] if events else None
        if isinstance(heard, PresenceHeard) and connection is self._connection:
            try:
                self.listener.peer_presence(heard.flows)
            except Exception:  # noqa: BLE001 -- a consumer's bug; the next change says it
                self.stats.internal_errors += 1
                log.exception("TCP channel: taking the peer's presence failed (a bug)")

    # -- sending -----------------------------------------------------------------------


    def _send_loop(self) -> None:
        while not self._stopping.is_set():
            with self._wake:
                while not self._urgent and not self._stopping.is_set():
                    current = self._connection
                    nudge_at = current.session.nudge_at if current is not None else math.inf
                    remaining = min(self._streams.wake_at(), nudge_at) - time.monotonic()
                    if remaining <= 0:
                        break
                    self._wake.wait(remaining)
                self._urgent = False
                connection = self._connection
            now = time.monotonic()
            due = self._streams.due(now)
            if connection is None or connection.closed:
                continue
            try:
                self._send(connection, now, due)
            except OSError as exc:
                self._drop(f"send failed: {exc.strerror or exc}", connection)
            except BridgeError as exc:
                log.error("TCP channel: %s", exc)
            except Exception:  # noqa: BLE001 -- our bug: seen, counted, and the link re-made
                self.stats.internal_errors += 1
                log.exception("TCP channel: sending failed (a bug); dropping the connection")
                self._drop("internal error while sending", connection)

    def _send(self, connection: _Connection, now: float, due: Due) -> None:
        """The frame the session says is due, if any."""
        out = connection.session.next_frame(now, wall=time.time(), due=due,
                                            presence=self.listener.presence(),
                                            kernel=_kernel_queue(connection.sock, self.budget,
                                                                 now))
        if out.held_back:
            self.drops.drop(Reason.HELD_BACK, f"{out.held_back} bytes queued ahead of them "
                                              f"(the kernel's or the radio's)")
        if out.body is None:
            return
        frame = connection.link.send_data(out.body)
        connection.sock.sendall(frame)
        if self.budget is not None:
            self.budget.spend(tcp_bytes(len(frame)), time.monotonic())
        self.stats.frames_out += 1
        self.stats.bytes_out += len(frame)
        if out.copies:
            session = self.journal.session
            try:
                self.listener.copies([(key, ReliableCopy(session, seq, payload, out.clock))
                                for key, seq, payload in out.copies])
            except Exception:  # noqa: BLE001 -- a consumer's bug: the frame has them anyway
                self.stats.internal_errors += 1
                log.exception("TCP channel: sending datagram copies failed (a bug)")
        if out.more:
            self.kick()
