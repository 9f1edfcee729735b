"""What the bridge does with each message: a sans-IO core, events in and actions out.

Theory of operation
-------------------
Every message a bridge handles is one of four events: a local program's message for the
link (:class:`LocalMessage`), a message from the peer off either channel
(:class:`PeerMessage`), a frame that left carrying reliable messages of flows copied as
datagrams (:class:`FrameLeft`), and a stop-all order or acknowledgement to send
(:class:`UrgentMessage`).  :meth:`BridgeCore.handle` turns each into the actions it takes:
send it reliably, post it as the newest value, send datagrams or datagram copies, hand a
copy to the journal, deliver it to a local port, carry out a stop or take its
acknowledgement.  Nothing here touches a socket, a port or a thread: the node
(:mod:`bridge.node`) performs the actions, as h11's user performs what ``send`` returns.

What happens to a message is decided by its route's :class:`~bridge.flows.Carriage` and its
direction, in one table (:data:`OUTBOUND`, :data:`INBOUND`); before, five functions of the
node each decided a part of it.  The GYM's part -- which status change a pilot waits for
(:class:`~bridge.gym.status_events.StatusEvents`), which copy of a status is the first
(:class:`~bridge.transport.copies.FirstStatus`) -- is asked, not duplicated.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable, Dict, List, Mapping, Optional, Tuple, Union

from bridge.config import PILOT, ROBOT, EmergencyStopFlow
from bridge.errors import BridgeUsageError
from bridge.flows import Carriage, FlowKey, Route
from bridge.gym.status_events import StatusEvents
from bridge.transport.copies import FirstStatus, ReliableCopy
from bridge.transport.drops import Reason

# -- events ----------------------------------------------------------------------------------


@dataclass(frozen=True)
class LocalMessage:
    """A local program's message on a flow this side sends."""

    key: FlowKey
    value: Any


@dataclass(frozen=True)
class PeerMessage:
    """A message from the peer, off the TCP or the UDP channel."""

    key: FlowKey
    value: Any


@dataclass(frozen=True)
class FrameLeft:
    """A TCP frame left carrying these reliable messages of flows copied as datagrams."""

    copies: Tuple[Tuple[FlowKey, ReliableCopy], ...]


@dataclass(frozen=True)
class UrgentMessage:
    """A stop-all order (pilot side) or its acknowledgement (robot side) to send;
    ``again``: a resending, which the TCP connection already carries."""

    key: FlowKey
    value: Any
    again: bool = False


Event = Union[LocalMessage, PeerMessage, FrameLeft, UrgentMessage]

# -- actions ---------------------------------------------------------------------------------


@dataclass(frozen=True)
class SendReliable:
    """Journal ``value`` and send it on the TCP channel: never lost, never run twice."""

    key: FlowKey
    value: Any


@dataclass(frozen=True)
class SendLatest:
    """The flow's newest value, for the TCP channel's next frame (at once if ``event``)."""

    key: FlowKey
    value: Any
    event: bool = False


@dataclass(frozen=True)
class SendDatagrams:
    """``value`` as the UDP channel's tiles or slices, with its next gather."""

    key: FlowKey
    value: Any


@dataclass(frozen=True)
class SendCopies:
    """``value`` as ``count`` datagrams now, the first copy to arrive wins (``again``: a
    resending of what already went, which a full radio's queue does without)."""

    key: FlowKey
    value: Any
    count: int
    again: bool = False


@dataclass(frozen=True)
class AcceptCopy:
    """A reliable message's datagram copy, for the TCP channel's journal to take or not."""

    key: FlowKey
    copy: ReliableCopy


@dataclass(frozen=True)
class Deliver:
    """Write ``value`` on the flow's local port or topic."""

    key: FlowKey
    value: Any


@dataclass(frozen=True)
class CarryOutStop:
    """Robot side: a stop-all order arrived; carry it out and acknowledge it."""

    value: Any


@dataclass(frozen=True)
class TakeAck:
    """Pilot side: the robot acknowledged a stop-all order."""

    value: Any


@dataclass(frozen=True)
class Drop:
    """Nothing done with a message, for ``reason``: counted and logged by the node."""

    reason: Reason
    detail: str


Action = Union[SendReliable, SendLatest, SendDatagrams, SendCopies, AcceptCopy, Deliver,
               CarryOutStop, TakeAck, Drop]

#: Which status events also go as datagram copies: what a pilot waits for, a new state or the
#: status answering a command.  (Later changes go by TCP only: at 9600 bit/s the copies of
#: every tick would cost more than the tail they cut.)
COPIED_STATUS_EVENTS = frozenset({"state", "first answer"})


@dataclass
class BridgeCore:
    """One side's decisions on every message (the node performs them).

    ``routes``: every flow's route (:meth:`bridge.config.BridgeConfig.routes`); ``datagrams``:
    whether this side has a UDP channel; ``stop``: the stop-all's flows, if configured."""

    side: str
    routes: Mapping[FlowKey, Route]
    datagrams: bool = True
    stop: Optional[EmergencyStopFlow] = None
    status_events: StatusEvents = field(default_factory=StatusEvents)
    first_status: FirstStatus = field(default_factory=FirstStatus)

    def __post_init__(self) -> None:
        if self.side not in (ROBOT, PILOT):
            raise BridgeUsageError(f"side must be robot or pilot, not {self.side!r}")

    def handle(self, event: Event) -> List[Action]:
        """The actions ``event`` takes, in the order the node performs them."""
        if isinstance(event, (LocalMessage, PeerMessage)):
            route = self.routes.get(event.key)
            if route is None:
                return [Drop(Reason.UNKNOWN_ID if isinstance(event, PeerMessage)
                             else Reason.UNCONFIGURED,
                             f"{event.key}: not a flow of the configuration")]
            table = OUTBOUND if isinstance(event, LocalMessage) else INBOUND
            return table[route.carriage](self, route, event.value)
        if isinstance(event, FrameLeft):
            if not self.datagrams:
                return []
            return [SendCopies(key, copy, self.routes[key].copies) for key, copy in event.copies
                    if key in self.routes]
        if isinstance(event, UrgentMessage):
            return self._urgent(event.key, event.value, tcp=not event.again)
        raise BridgeUsageError(f"not a bridge event: {event!r}")

    def delivered(self, module_id: int) -> None:
        """A pilot's switch or command reached module ``module_id``: its status changes
        within :data:`~bridge.gym.status_events.COMMAND_WINDOW` are events."""
        self.status_events.commanded(module_id)

    def module_gone(self, key: FlowKey) -> None:
        """The module of ``key`` left: its next status is new, whatever its number."""
        self.first_status.forget(key)

    # -- outbound, by carriage ---------------------------------------------------------------

    def _send_reliable(self, route: Route, value: Any) -> List[Action]:
        return [SendReliable(route.key, value)]

    def _send_latest(self, route: Route, value: Any) -> List[Action]:
        event = self.status_events.classify(route.key.id, value) if route.status_events \
            else None
        actions: List[Action] = [SendLatest(route.key, value, event is not None)]
        if event in COPIED_STATUS_EVENTS and route.copies and self.datagrams:
            actions.append(SendCopies(route.key, value, route.copies))
        return actions

    def _send_datagrams(self, route: Route, value: Any) -> List[Action]:
        if not self.datagrams:
            return [Drop(Reason.UNCONFIGURED, f"{route.label}: no UDP channel to carry it")]
        return [SendDatagrams(route.key, value)]

    def _send_urgent(self, route: Route, value: Any) -> List[Action]:
        return self._urgent(route.key, value, tcp=True)

    def _urgent(self, key: FlowKey, value: Any, tcp: bool) -> List[Action]:
        """Every way at once: the TCP channel's next frame (unless a resending, which the
        connection already carries) and repeated datagrams."""
        actions: List[Action] = [SendLatest(key, value, True)] if tcp else []
        if self.datagrams and self.stop is not None:
            actions.append(SendCopies(key, value, self.stop.copies, again=not tcp))
        return actions

    # -- inbound, by carriage ----------------------------------------------------------------

    def _take_copy(self, route: Route, value: Any) -> List[Action]:
        """A reliable message comes off the link only through the journal (TCP) or as a
        datagram copy of it, which the journal takes or not."""
        if isinstance(value, ReliableCopy):
            return [AcceptCopy(route.key, value)]
        return [Drop(Reason.MALFORMED, f"{route.label}: a reliable flow's message that is "
                                       f"not a copy of a journalled one")]

    def _deliver_latest(self, route: Route, value: Any) -> List[Action]:
        if route.copies and not self.first_status.first(route.key, value):
            return []      # the other copy of one written, or a late one a newer overtook
        return [Deliver(route.key, value)]

    def _deliver(self, route: Route, value: Any) -> List[Action]:
        return [Deliver(route.key, value)]

    def _stop_line(self, route: Route, value: Any) -> List[Action]:
        """An order is the robot's to carry out, an acknowledgement the pilot's to take."""
        if self.stop is not None and route.key == self.stop.stop_key and self.side == ROBOT:
            return [CarryOutStop(value)]
        if self.stop is not None and route.key == self.stop.ack_key and self.side == PILOT:
            return [TakeAck(value)]
        return [Drop(Reason.UNKNOWN_ID, f"{route.label} arrived at the {self.side}'s side, "
                                        f"which only sends it")]


Handler = Callable[[BridgeCore, Route, Any], List[Action]]

#: What a message does, by its flow's carriage and its direction: the one place it is said.
OUTBOUND: Dict[Carriage, Handler] = {
    Carriage.RELIABLE: BridgeCore._send_reliable,
    Carriage.LATEST: BridgeCore._send_latest,
    Carriage.DATAGRAMS: BridgeCore._send_datagrams,
    Carriage.URGENT: BridgeCore._send_urgent,
}
INBOUND: Dict[Carriage, Handler] = {
    Carriage.RELIABLE: BridgeCore._take_copy,
    Carriage.LATEST: BridgeCore._deliver_latest,
    Carriage.DATAGRAMS: BridgeCore._deliver,
    Carriage.URGENT: BridgeCore._stop_line,
}
