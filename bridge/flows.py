"""What a bridged flow is called and how it crosses: one :class:`FlowKey`, one :class:`Route`.

Theory of operation
-------------------
Every flow of the configuration is named on the wire by its 8-bit module id
and the flow's *kind* within that module: a :class:`FlowKey`.  How the flow
crosses the link -- which channel carries it, whether it is journalled, whether
a change leaves at once, in which form its values travel, whether its messages
carry a validity -- is decided once, by :meth:`bridge.config.BridgeConfig.routes`;
the TCP channel, the UDP channel and the bridge node only look it up.  Before,
three functions of the node and both channels each decided part of it.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum


@dataclass(frozen=True, order=True, slots=True)
class FlowKey:
    """A flow's name on the wire: module id (0..255) and the flow's kind within it.  Read by
    name (``key.id``, ``key.kind``), never by position: it is not a tuple."""

    id: int
    kind: int

    def __str__(self) -> str:
        return f"id {self.id} kind {self.kind}"


#: The kind of the robot state flow under its own id.
STATE_KIND = 0
#: The kinds of the stop-all's two flows under its id: the pilot's order, the robot's answer.
STOP_ORDER_KIND, STOP_ACK_KIND = 0, 1


class Carriage(str, Enum):
    """How a flow's messages cross the link."""

    #: journalled on both sides: never lost, never run twice, in order, sent at once (TCP)
    RELIABLE = "reliable"
    #: the newest value with the next period (TCP); a GYM status's change that a pilot
    #: waits for leaves at once (:class:`bridge.gym.status_events.StatusEvents`)
    LATEST = "latest"
    #: tiles or slices of one datagram each (UDP): what arrived is published after ``gather``
    DATAGRAMS = "datagrams"
    #: the stop-all: at once on the TCP channel, never held back behind a backlog, and as
    #: repeated datagrams on the UDP one; the receiver acts on the first copy
    URGENT = "urgent"


class Form(str, Enum):
    """What the values of a flow are, for the codec that carries them."""

    BOTTLE = "bottle"      # a YARP Bottle (compact codec, deltas on TCP)
    STATE = "state"        # the robot's joint state (Table 1 codec)
    ROS = "ros"            # a ROS message (its topic's codec)


@dataclass(frozen=True)
class Route:
    """How one flow travels, decided once from the configuration."""

    key: FlowKey
    label: str
    carriage: Carriage
    form: Form
    #: a GYM status: a change of its ``seq state`` head is an event that leaves at once
    status_events: bool = False
    #: a GYM switch or command: each message carries how long it may still start
    #: (:mod:`walkman.gym.validity`), and every hop adds the time it held it
    expiring: bool = False
    fec: float = 0.0
    fec_auto: bool = False
    #: a command, receipt or status also sent as this many datagrams on the UDP channel,
    #: first copy wins (:mod:`bridge.transport.copies`); 0: TCP only
    copies: int = 0

    @property
    def on_tcp(self) -> bool:
        return self.carriage is not Carriage.DATAGRAMS

    @property
    def on_udp(self) -> bool:
        return self.carriage in (Carriage.DATAGRAMS, Carriage.URGENT) or self.copies > 0

    @property
    def reliable(self) -> bool:
        return self.carriage is Carriage.RELIABLE

    @property
    def copied(self) -> bool:
        """Each message comes as several copies: a repeated part is expected, no drop."""
        return self.copies > 0 or self.carriage is Carriage.URGENT
