"""What the TCP channel's data frames say, both ways, sans-IO: one connection's session.

Theory of operation
-------------------
Everything in this module lives between the link's handshake (:mod:`bridge.wire.link`) and
the next one; nothing touches a socket, a thread or a clock.  A :class:`FrameSession`
takes the data frames a connection received and returns events, and says what to send
now as a frame body for :meth:`~bridge.wire.link.LinkConnection.send_data` to seal, as h11's
``Connection`` does.  The TCP channel (:mod:`bridge.transport.tcp_channel`) only moves the bytes,
asks the kernel about the socket's send queue (:class:`KernelQueue`) and passes in the
time; tests and fuzzers drive the session without a network.

Reliable messages (pilot commands, warnings) live in the journal's outbox and inbox
(:class:`Queues`, which :class:`~bridge.transport.journal.Journal` is).  After the handshake each
side's RESUME says the highest number it accepted from the other's journal session
(:meth:`FrameSession.resume_point`); the sender forgets what the peer has and sends the
rest again, in order (:meth:`FrameSession.peer_resumed`).  A frame numbers its first
reliable entry (``seq``) and the others follow; the receiver journals each, refuses a
gap as the peer's error and drops a number it already has (a duplicate, after a
reconnect).  Every frame that follows an acceptance carries ``ack``, the highest number
accepted, so the peer can forget it.  A flow with datagram copies (:mod:`bridge.transport.copies`)
sends each reliable message a second way, on the UDP channel, as its frame leaves
(:attr:`Outgoing.copies`); the receiving session journals a copy that is the next number
it expects (:meth:`FrameSession.accept_copy`), and the frame that follows finds it there
-- no drop, no second delivery.

Streaming values (statuses, the robot state) wait in :class:`Streams`, one slot per
flow, the newest value overwriting an older one.  The periodic frame, once per period T,
holds every flow that changed.  A value posted as an *event* (a module's status answering
a pilot's command, or with a new state: what the pilot waits to see) leaves at once
instead, alone or with other events, at most once per :data:`EVENT_MIN_GAP` per flow
(later ones are coalesced in the slot), so a pilot's command shows its effect within a
round trip instead of the next period, and a robot standing still sends exactly what the
periodic frames send.  When the kernel still holds unsent bytes (the link is slower than
we write), the streaming part of a frame is held back rather than queued, so the pilot
sees fresh state instead of a backlog; so it is while the link budget says the radio's queue
is full (:mod:`bridge.transport.link_budget`).  Bottles travel as deltas against the previous
value sent on the same connection (:mod:`bridge.wire.compact`), robot state in the Table 1
codec (:mod:`bridge.wire.state_codec`); every codec belongs to one session, so both restart
from full values on a new connection and the two ends never disagree.

When a frame the pilot waits for (events, reliable messages, presence) has left but the
peer has not acknowledged everything :data:`NUDGE_AFTER` (or a round trip plus
:data:`DELAYED_ACK`) later, an empty frame follows, up to :data:`NUDGES` times, the wait
doubling (:class:`Nudges`): a lone lost segment waits for TCP's retransmission timer
(200 ms at least, doubling), while the peer's selective acknowledgement of a later one
makes the kernel resend it at once.  Bytes still queued (a slow link) are not a loss:
nothing follows them.  A frame also leaves, empty, after :data:`KEEPALIVE` of silence.

Which flows have their module connected (:mod:`bridge.gym.presence`) is said on each new
connection and whenever it changes; on receipt it is the last event of its frame, after
the frame's reliable messages are journalled.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass, field
from typing import (AbstractSet, Any, Callable, Dict, FrozenSet, List, Mapping, Optional,
                    Protocol, Sequence, Tuple, Union)

from bridge.errors import BridgeProtocolError, BridgeUsageError
from bridge.flows import Carriage, FlowKey, Form, Route
from bridge.transport import drops
from bridge.transport.copies import ReliableCopy
from bridge.transport.drops import Reason
from bridge.transport.journal import Queued
from bridge.wire import compact, frames
from bridge.wire.frames import DataFrame, Entry, Presence
from bridge.wire.state_codec import StateDecoder, StateEncoder
from bridge.wire.transit import Lateness, stamp

MAX_RELIABLE_PER_FRAME = 256
#: Shortest time between two event sends of one flow; more frequent events wait (coalesced).
EVENT_MIN_GAP = 0.05
#: Longest silence on a connection: an empty frame then says we are alive.
KEEPALIVE = 1.0
#: How long a receiver may delay its acknowledgement (Linux: 40 ms).
DELAYED_ACK = 0.04
#: Least seconds before an unacknowledged frame the pilot waits for is followed by an empty
#: one (a round trip plus :data:`DELAYED_ACK` on a slower link): far shorter than TCP's
#: retransmission timer.
NUDGE_AFTER = 0.05
#: Empty frames at most after one the pilot waits for (the wait doubling each time).
NUDGES = 3


@dataclass
class LinkStats:
    """The TCP channel's counters (the bridge status shows them)."""

    frames_out: int = 0
    frames_in: int = 0
    bytes_out: int = 0
    bytes_in: int = 0
    payload_out: int = 0
    payload_in: int = 0
    reliable_sent: int = 0
    reliable_accepted: int = 0
    #: reliable messages whose datagram copy was journalled before their frame came
    reliable_by_copy: int = 0
    connects: int = 0
    #: empty frames sent after one the pilot waits for that was not acknowledged in time
    nudges: int = 0
    #: exceptions that are our bugs (logged with their traceback), not the peer's
    internal_errors: int = 0
    last_error: str = ""
    #: payload plus entry header bytes sent, per 8-bit id (frame headers not included)
    bytes_by_id: Dict[int, int] = field(default_factory=dict)


# -- what the session needs from the journal -------------------------------------------


class Outbox(Protocol):
    """Reliable messages to send, kept until the peer acknowledges them."""

    def unacknowledged(self, after: int = 0, limit: int = 1 << 30) -> List[Queued]:
        """What the next frame carries; the journal then counts them as claimed (too late
        to cancel: :meth:`bridge.transport.journal.Journal.cancel`)."""

    def acknowledge(self, upto: int) -> int:
        """Forget up to ``upto``; :class:`BridgeProtocolError` past what was ever sent."""


class Inbox(Protocol):
    """Reliable messages accepted from the peer, per peer journal session."""

    def accepted(self, session: int) -> int: ...

    def accept(self, session: int, seq: int, ident: int, kind: int, payload: bytes,
               late_by: float = 0.0) -> bool:
        """Keep one; False for a repeat, :class:`BridgeProtocolError` for a gap."""


class Queues(Outbox, Inbox, Protocol):
    """Both halves, as :class:`~bridge.transport.journal.Journal` holds them."""


# -- events ------------------------------------------------------------------------------


@dataclass(frozen=True)
class StreamValue:
    """The newest value of a streaming flow (a Bottle or a robot state)."""

    key: FlowKey
    value: Any


@dataclass(frozen=True)
class ReliableAccepted:
    """A reliable message is in the inbox now, waiting to be delivered."""

    key: FlowKey
    seq: int


@dataclass(frozen=True)
class Acknowledged:
    """The peer accepted our reliable messages up to ``upto``; the outbox forgot them."""

    upto: int


@dataclass(frozen=True)
class PresenceHeard:
    """Which flows have their module connected on the peer's side (a frame's last event)."""

    flows: Presence


@dataclass(frozen=True)
class Dropped:
    """An entry that is not the peer's error, but not taken: an unknown flow, a duplicate."""

    reason: Reason
    detail: str


Event = Union[StreamValue, ReliableAccepted, Acknowledged, PresenceHeard, Dropped]


# -- what to send, and when ------------------------------------------------------------


@dataclass(frozen=True)
class Due:
    """What leaves now (:meth:`Streams.due`)."""

    #: the flows to send: None for the periodic frame (every changed flow)
    flows: Optional[FrozenSet[FlowKey]]
    #: those whose event is due, the periodic frame's too: a pilot waits for them, so the
    #: frame is followed by nudges
    events: FrozenSet[FlowKey] = frozenset()


class Streams:
    """The newest value of every streaming flow, and when each must leave (thread-safe).

    Lives as long as the channel: values posted while the link is down leave on the next
    connection, whose session starts them from full values (:meth:`restart`).
    """

    def __init__(self, period: float, now: float) -> None:
        self.period = period
        self._next_tick = now + period
        self._slots: Dict[FlowKey, Any] = {}
        self._dirty: Dict[FlowKey, bool] = {}
        self._events: Dict[FlowKey, float] = {}       # flows with an event waiting -> due
        self._event_sent: Dict[FlowKey, float] = {}   # flow -> when its last event left
        self._lock = threading.Lock()

    def post(self, key: FlowKey, value: Any, event: bool = False) -> bool:
        """Keep ``value`` (or a callable giving it when sent); True when an event was
        planned, so the sender should look at :meth:`wake_at` again."""
        with self._lock:
            self._slots[key] = value
            self._dirty[key] = True
            if not event or key in self._events:
                return False
            self._events[key] = self._event_sent.get(key, -math.inf) + EVENT_MIN_GAP
            return True

    def wake_at(self) -> float:
        """When something is due: the next period's tick or the first event."""
        with self._lock:
            return min([self._next_tick, *self._events.values()])

    def due(self, now: float) -> Due:
        """What leaves now: the periodic frame (every changed flow, and every event with
        it, still an event), else the flows whose event is due (perhaps none)."""
        with self._lock:
            tick = now >= self._next_tick
            due = frozenset(self._events) if tick else \
                frozenset(key for key, when in self._events.items() if when <= now)
            for key in due:
                del self._events[key]
                self._event_sent[key] = now
            if tick:
                self._next_tick = max(self._next_tick + self.period, now)
                return Due(None, due)
            return Due(due, due)

    def take(self, only: Optional[AbstractSet[FlowKey]] = None) -> List[Tuple[FlowKey, Any]]:
        """The changed values (of ``only``, if given), now no longer changed."""
        with self._lock:
            ready = [(key, self._slots[key]) for key, dirty in self._dirty.items()
                     if dirty and (only is None or key in only)]
            for key, _ in ready:
                self._dirty[key] = False
        return ready

    def restart(self) -> None:
        """A new connection: every value known leaves again (in full) with the next frame."""
        with self._lock:
            for key in self._slots:
                self._dirty[key] = True


@dataclass
class Nudges:
    """When a frame the pilot waits for is followed by an empty one."""

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


@dataclass(frozen=True)
class KernelQueue:
    """What the kernel says of the connection's send queue just before a frame is built."""

    #: bytes still held for the peer, sent or not (a backlog holds streaming values back)
    unsent: int = 0
    #: everything has left and some of it is not acknowledged yet (a nudge may help)
    only_unacknowledged: bool = False
    #: the kernel's smoothed round trip, in seconds (0: unknown)
    round_trip: float = 0.0
    #: bytes in the radio's queue as the link budget models it (:mod:`~bridge.transport.
    #: link_budget`), and whether that is all streaming data may fill
    radio_queued: int = 0
    radio_full: bool = False


@dataclass(frozen=True)
class Outgoing:
    """What :meth:`FrameSession.next_frame` decided."""

    #: the frame body to seal and send, or None: nothing to say now
    body: Optional[bytes] = None
    #: it holds what a pilot waits for (reliable messages, events, presence)
    awaited: bool = False
    #: the outbox has more than one frame carries: build the next one at once
    more: bool = False
    #: streaming values were held back behind this many bytes, unsent in the kernel or
    #: in the radio's queue (0: none)
    held_back: int = 0
    #: the reliable messages of copied flows in this frame, as sent, for their datagram
    #: copies (:mod:`bridge.transport.copies`)
    copies: Tuple[Tuple[FlowKey, int, bytes], ...] = ()
    #: the frame's clock stamp (:mod:`bridge.wire.transit`), which its copies carry too
    clock: int = 0


# -- the session -------------------------------------------------------------------------


#: What an expiring message becomes as it leaves after waiting so many seconds.
Age = Callable[[bytes, float], bytes]


def unaged(payload: bytes, seconds: float) -> bytes:
    """A message as it was: for a transport that carries no validity."""
    return payload


class FrameSession:
    """One connection's data frames: frames in, events out; what to send now, bodies out.

    Made when the peer proved the key (its journal ``peer_session`` is then known); up
    once both RESUMEs are through.  Receiving and sending touch disjoint state, so one
    thread may receive while another sends.
    """

    def __init__(self, queues: Queues, routes: Mapping[FlowKey, Route], streams: Streams,
                 peer_session: int, *, period: float,
                 stats: Optional[LinkStats] = None, age: Age = unaged) -> None:
        """``age(payload, seconds)``: an expiring message as it leaves after waiting
        ``seconds`` in the outbox (the GYM's validity, :func:`bridge.gym.expiry.aged_payload`;
        the transport knows only that a route is ``expiring``)."""
        self.queues = queues
        self.age = age
        self.routes = routes
        self.streams = streams
        self.peer_session = peer_session
        self.period = period
        self.stats = stats if stats is not None else LinkStats()
        self.sent_upto: Optional[int] = None    # highest reliable number sent (after RESUME)
        self.ack_sent: Optional[int] = None     # highest acceptance told (RESUME, then acks)
        self.nudges = Nudges()
        self._last_tx = -math.inf
        self._presence_sent: Optional[Presence] = None
        self._sent_bottles: Dict[FlowKey, Any] = {}
        self._received_bottles: Dict[FlowKey, Any] = {}
        self._state_encoders: Dict[FlowKey, StateEncoder] = {}
        self._state_decoders: Dict[FlowKey, StateDecoder] = {}
        self._copied_upto = 0    # highest number a datagram copy brought first
        self.lateness = Lateness()

    # -- RESUME ----------------------------------------------------------------------

    def resume_point(self) -> int:
        """What our RESUME says: the highest number accepted from the peer's session."""
        if self.ack_sent is not None:
            raise BridgeUsageError("frame session: our RESUME was already made")
        self.ack_sent = self.queues.accepted(self.peer_session)
        return self.ack_sent

    def peer_resumed(self, peer_accepted: int) -> None:
        """The peer's RESUME: forget what it has; the rest is sent again, in order."""
        if self.sent_upto is not None:
            raise BridgeUsageError("frame session: the peer's RESUME was already taken")
        self.queues.acknowledge(peer_accepted)
        self.sent_upto = peer_accepted

    @property
    def up(self) -> bool:
        return self.ack_sent is not None and self.sent_upto is not None

    def _check_up(self, what: str) -> None:
        if not self.up:
            raise BridgeUsageError(f"frame session: {what} before both RESUMEs")

    # -- receiving -------------------------------------------------------------------

    def receive_body(self, body: bytes, read_at: Optional[float] = None) -> List[Event]:
        """A frame body as the link unsealed it; :class:`BridgeProtocolError` if bad."""
        frame = frames.parse_body(body)
        if not isinstance(frame, DataFrame):
            raise BridgeProtocolError(f"a {type(frame).__name__} frame after the handshake")
        return self.receive(frame, read_at)

    def receive(self, frame: DataFrame, read_at: Optional[float] = None) -> List[Event]:
        """The events of one data frame, in order (presence last); raises
        :class:`BridgeProtocolError` for anything the peer must not send -- the reliable
        messages before it in the frame stay accepted, as the peer will learn by our ack.
        ``read_at``: when its bytes were read (monotonic), to tell how late it came."""
        self._check_up("a data frame")
        late_by = self._late_by(frame.clock, read_at)
        events: List[Event] = []
        if frame.ack is not None:
            self.queues.acknowledge(frame.ack)
            events.append(Acknowledged(frame.ack))
        seq = frame.seq
        for entry in frame.entries:
            self.stats.payload_in += len(entry.payload)
            route = self.routes.get(FlowKey(entry.id, entry.kind))
            if route is None:
                events.append(Dropped(Reason.UNKNOWN_ID,
                                      f"entry id {entry.id} kind {entry.kind}"))
            elif route.reliable:
                if seq is None or entry.delta:
                    raise BridgeProtocolError(f"reliable entry {route.label} without a "
                                              f"sequence number")
                accepted = self._accept(route, entry, seq, late_by)
                if accepted is not None:
                    events.append(accepted)
                seq += 1
            else:
                try:
                    value = self._decode_streaming(route, entry)
                except BridgeProtocolError as exc:
                    raise BridgeProtocolError(f"{route.label}: {exc}") from None
                events.append(StreamValue(route.key, value))
        if frame.presence is not None:
            events.append(PresenceHeard(frame.presence))
        return events

    def _late_by(self, clock: Optional[int], read_at: Optional[float]) -> float:
        if clock is None or read_at is None:
            return 0.0
        return self.lateness.of(clock, read_at)

    def accept_copy(self, key: FlowKey, copy: ReliableCopy,
                    read_at: Optional[float] = None) -> Optional[Event]:
        """A reliable message that came as a datagram copy (:mod:`~bridge.transport.copies`):
        journalled
        if it is the next number from this connection's peer session; None when its frame
        came first, when it is ahead of a gap the frames fill in order, or when it belongs
        to another session.  :class:`BridgeProtocolError` for a payload no codec reads.
        The caller serialises it with :meth:`receive`."""
        route = self.routes.get(key)
        if not self.up or route is None or not route.reliable or not route.copies or \
                copy.session != self.peer_session or \
                copy.seq != self.queues.accepted(self.peer_session) + 1:
            return None
        event = self._accept(route, Entry(key.id, key.kind, copy.payload), copy.seq,
                             self._late_by(copy.clock, read_at))
        if isinstance(event, ReliableAccepted):
            self._copied_upto = copy.seq
            self.stats.reliable_by_copy += 1
        return event

    def _accept(self, route: Route, entry: Entry, seq: int, late_by: float = 0.0
                ) -> Optional[Event]:
        """Journal one reliable message (``late_by``: seconds its frame came later than the
        quickest, which its age grows by); None for the frame of one its copy brought."""
        compact.decode(entry.payload)  # refuse garbage before it is journalled
        if not self.queues.accept(self.peer_session, seq, entry.id, entry.kind, entry.payload,
                                  late_by):
            if seq <= self._copied_upto:
                return None
            return Dropped(Reason.DUPLICATE, f"{route.label} #{seq}")
        self.stats.reliable_accepted += 1
        return ReliableAccepted(route.key, seq)

    def _decode_streaming(self, route: Route, entry: Entry) -> Any:
        if route.form is Form.STATE:
            decoder = self._state_decoders.setdefault(route.key, StateDecoder())
            return decoder.decode(entry.payload)
        if entry.delta:
            previous = self._received_bottles.get(route.key)
            if previous is None:
                raise BridgeProtocolError("a delta before any full message")
            bottle = compact.decode_delta(entry.payload, previous)
        else:
            bottle = compact.decode(entry.payload)
        self._received_bottles[route.key] = bottle
        return bottle

    # -- sending ---------------------------------------------------------------------

    @property
    def nudge_at(self) -> float:
        """When the sender must look again for a nudge (inf: none planned)."""
        return self.nudges.at

    def next_frame(self, now: float, *, wall: float,
                   due: Due = Due(None),
                   presence: Optional[Presence] = None,
                   kernel: KernelQueue = KernelQueue()) -> Outgoing:
        """The frame to send at ``now`` (``wall``: the wall clock, for command ageing).

        It holds what the outbox owes, our ack, the presence if it changed (None: not
        known yet) and what :meth:`Streams.due` said is due (by default the periodic
        frame: every changed flow).  Its bookkeeping counts it as sent: a session whose
        frame could not be sent is over (the connection is dropped).
        """
        streams, events = due.flows, due.events
        self._check_up("a frame to send")
        nudge = now >= self.nudges.at and self.nudges.take(now, kernel.only_unacknowledged)
        reliable = self.queues.unacknowledged(after=self.sent_upto or 0,
                                              limit=MAX_RELIABLE_PER_FRAME)
        encoded, copies = [], []
        for item in reliable:
            route = self.routes.get(FlowKey(item.id, item.kind))
            payload = item.payload
            if route is not None and route.expiring:   # it waited here: the module must know
                payload = self.age(payload, wall - item.queued)
            encoded.append(self._reliable_entry(item, payload))
            if route is not None and route.copies:
                copies.append((route.key, item.seq, payload))
        held_back = 0
        carries_event = False
        if streams is None or streams:
            if drops.hold_back(kernel.unsent) or kernel.radio_full:
                held_back = max(kernel.unsent, kernel.radio_queued, 1)
                # The stop-all is never held back behind a backlog: it is what must arrive.
                urgent = {key for key, route in self.routes.items()
                          if route.carriage is Carriage.URGENT and
                          (streams is None or key in streams)}
                if urgent:
                    streaming = self._streaming_entries(self.streams.take(urgent))
                    carries_event = bool(streaming)
                    encoded.extend(streaming)
            else:
                taken = self.streams.take(streams)
                # An event that rides with the periodic frame is awaited all the same: a
                # sender late for both (a loaded machine) sent it unnudged (fc3, 2026-11-27).
                carries_event = any(key in events for key, _ in taken)
                encoded.extend(self._streaming_entries(taken))
        accepted = self.queues.accepted(self.peer_session)
        ack = accepted if accepted != self.ack_sent else None
        if presence == self._presence_sent:
            presence = None
        if not encoded and ack is None and presence is None and not nudge and \
                now - self._last_tx < KEEPALIVE:
            return Outgoing(held_back=held_back)
        clock = stamp(now)
        body = frames.data_body(ack=ack, seq=reliable[0].seq if reliable else None,
                                encoded=encoded, presence=presence, clock=clock)
        self._last_tx = now
        self.ack_sent = accepted
        if presence is not None:
            self._presence_sent = presence
        if reliable:
            self.sent_upto = reliable[-1].seq
            self.stats.reliable_sent += len(reliable)
        awaited = bool(reliable) or carries_event or presence is not None
        if awaited:
            self.nudges.awaited_frame_sent(now, kernel.round_trip)
        if nudge:
            self.stats.nudges += 1
        return Outgoing(body, awaited, len(reliable) == MAX_RELIABLE_PER_FRAME, held_back,
                        tuple(copies), clock)

    def _reliable_entry(self, item: Queued, payload: bytes) -> bytes:
        self.stats.payload_out += len(payload)
        return self._counted(Entry(item.id, item.kind, payload))

    def _streaming_entries(self, values: Sequence[Tuple[FlowKey, Any]]) -> List[bytes]:
        out = []
        for key, value in values:
            route = self.routes[key]
            if callable(value):  # a lazy snapshot: read the newest value only now
                value = value()
            if route.form is Form.STATE:
                encoder = self._state_encoders.setdefault(key, StateEncoder(self.period))
                entry = Entry(key.id, key.kind, encoder.encode(value))
            else:
                full = compact.encode(value)
                previous = self._sent_bottles.get(key)
                delta = compact.encode_delta(value, previous) if previous is not None \
                    else None
                entry = Entry(key.id, key.kind, delta, True) \
                    if delta is not None and len(delta) < len(full) \
                    else Entry(key.id, key.kind, full)
                self._sent_bottles[key] = value
            self.stats.payload_out += len(entry.payload)
            out.append(self._counted(entry))
        return out

    def _counted(self, entry: Entry) -> bytes:
        encoded = frames.entry_bytes(entry)
        by_id = self.stats.bytes_by_id
        by_id[entry.id] = by_id.get(entry.id, 0) + len(encoded)
        return encoded
