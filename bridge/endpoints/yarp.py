"""YARP endpoints: ports with the original names, and the connections they need.

Theory of operation
-------------------
On the side where data starts, a :class:`YarpSink` opens a port (the original
``/module/switch:i`` for pilot commands, ``/bridge/robot/module/status`` fed by
the module's ``status:o`` for robot data).  On the other side a
:class:`YarpSource` opens the matching port (``/module/status:o`` for the
pilot to read, ``/bridge/pilot/module/switch`` connected to the module's
``switch:i``).

A :class:`nodekit.connections.ConnectionKeeper` owns every connection the bridge
needs and checks them twice a second -- locally, on the bridge's own port, so
checking costs no traffic -- and remakes any that is missing: after a module, a
name server or the bridge itself restarted, connections come back without
anyone asking.

:class:`RobotStateSink` gathers the HAL's per-chain ``stateSI:o`` into one
whole-robot reading; :class:`RobotStateSource` republishes it on the pilot
side as ``/<robot>/<chain>/stateSI:o`` (and whole, ``/<robot>/stateSI:o``, as the HAL
does) and, for YARP's own tools, as the
control board's ``state:o`` and ``stateExt:o`` (positions, velocities and
torques; control modes unknown, so marked invalid).
"""

from __future__ import annotations

import logging
import math
import threading
import time
from typing import Callable, Dict, List, Optional, Tuple

import numpy as np

from bridge.config import Channel
from bridge.gym.presence import READER_GRACE
from bridge.transport.nursery import Nursery
from bridge.wire import compact
from bridge.wire.state_codec import (Layout, RobotState, StateDecoder, StateEncoder,
                                     split_by_chain)
from nodekit.connections import ConnectionKeeper
from walkman.hal import protocol
from walkman.hal.controlboard import JointData, Stamp, encode_joint_data
from walkman.hal.protocol import ChainState, HalProtocolError, state_interval
from yarp_lite import network
from yarp_lite.bottle import Bottle, Vocab
from yarp_lite.buffered_port import BufferedPort
from yarp_lite.carriers import with_send_period
from yarp_lite.errors import YarpError
from yarp_lite.nameclient import NameClient
from yarp_lite.port import Port
from yarp_lite.rpc import RpcServer

log = logging.getLogger("bridge.yarp")


class YarpSink:
    """A port that takes messages from local programs for the link."""

    def __init__(self, channel: Channel, nameclient: NameClient, keeper: ConnectionKeeper,
                 submit: Callable[[Channel, Bottle], None]) -> None:
        self.channel = channel
        # Set before the port opens: a writer may connect and send at once (a pilot command
        # taken between the two was acknowledged and lost; found by walkman-chaos).
        self._submit = submit
        self._keeper = keeper
        self.port = Port(nameclient=nameclient, reader=self._on_bottle)
        self.port.open(channel.listen_port, wait=math.inf)
        self._feed = keeper.want(channel.feed_port, self.port.name, self.port,
                                 ours_is_source=False) if channel.feed_port else None

    @property
    def linked(self) -> bool:
        """Is the program's port this sink reads from connected (the module there)?"""
        return self._feed is not None and self._keeper.connected(self._feed)

    def _on_bottle(self, bottle: Bottle) -> None:
        self._submit(self.channel, bottle)
        return None

    def close(self) -> None:
        self._keeper.forget(self.port)
        self.port.close()


class YarpSource:
    """A port that gives local programs what arrived from the link."""

    def __init__(self, channel: Channel, nameclient: NameClient,
                 keeper: ConnectionKeeper) -> None:
        self.channel = channel
        self._keeper = keeper
        self.port = Port(nameclient=nameclient)
        self.port.open(channel.emit_port, wait=math.inf)
        self._opened = time.monotonic()
        self._delivery = keeper.want(self.port.name, channel.deliver_port, self.port,
                                     ours_is_source=True) if channel.deliver_port else None

    @property
    def linked(self) -> bool:
        """Is the program's port this source writes to connected (the module there)?"""
        return self._delivery is not None and self._keeper.connected(self._delivery)

    @property
    def ready(self) -> bool:
        """Can a reliable message be delivered now?  When its program's port is connected;
        for a port local programs connect to, when one reads it, or nobody has for
        :data:`READER_GRACE` since it opened."""
        if self.port.output_count > 0:
            return True
        return self.channel.deliver_port is None and \
            time.monotonic() - self._opened > READER_GRACE

    def deliver(self, bottle: Bottle) -> bool:
        self.port.drop_closed_outputs()     # a reader gone is no reader (ready asks)
        if not self.ready:
            return False
        return self.port.write(bottle) and self.port.is_open

    def close(self) -> None:
        self._keeper.forget(self.port)
        self.port.close()


# -- codecs of YARP flows on the UDP channel ---------------------------------------------


class BottleUdpCodec:
    tiled = False

    def encode(self, value: Bottle) -> bytes:
        return compact.encode(value)

    def decode(self, data: bytes, completeness: float) -> Bottle:
        return compact.decode(data)


class StateUdpCodec:
    """Every datagram-borne state is a key frame: datagrams get lost, deltas would not."""

    tiled = False

    def __init__(self, period: float) -> None:
        self.period = period

    def encode(self, value: "RobotState | Callable[[], RobotState]") -> bytes:
        state = value() if callable(value) else value
        return StateEncoder(self.period).encode(state)

    def decode(self, data: bytes, completeness: float) -> RobotState:
        return StateDecoder().decode(data)


# -- the robot state ------------------------------------------------------------------


class RobotStateSink:
    """Robot side: the HAL's chains, read as one whole-robot state."""

    def __init__(self, robot: str, nameclient: NameClient, keeper: ConnectionKeeper,
                 post: Callable[[Callable[[], RobotState]], None], rate: float,
                 threads: Optional[Nursery] = None) -> None:
        self.robot = robot
        self.nameclient = nameclient
        self.keeper = keeper
        self.post = post
        self.rate = rate
        self.layout: Optional[Layout] = None
        self._ports: List[BufferedPort] = []
        self._offsets: Dict[str, Tuple[int, int]] = {}
        self._lock = threading.Lock()
        self._q = self._tau = self._temperature = np.zeros(0)
        self._unheard: set = set()   # chains of the layout with no state yet
        self._time = 0.0
        self._updated = 0.0
        self._posted = 0.0
        self._stop = threading.Event()
        self._thread = (threads or Nursery()).start_soon(self._run, "robot state")

    def _ask_layout(self) -> Optional[Layout]:
        try:
            contact = self.nameclient.query(protocol.robot_rpc_name(self.robot))
            if contact is None:
                return None
            reply = network.request(contact, [Vocab("get"), "chains"], timeout=3)
        except YarpError:
            return None
        chains = [(str(group[0]), tuple(str(j) for j in group[1:])) for group in reply
                  if isinstance(group, list) and len(group) > 1]
        return Layout(tuple(chains)) if chains else None

    def _adopt(self, layout: Layout) -> None:
        for port in self._ports:
            self.keeper.forget(port)
            port.close()
        self._ports = []
        offsets, start = {}, 0
        for chain, count in layout.counts:
            offsets[chain] = (start, count)
            start += count
        with self._lock:
            self.layout = layout
            self._offsets = offsets
            self._q, self._tau = np.zeros(start), np.zeros(start)
            self._temperature = np.zeros(start)
            self._unheard = {chain for chain, _ in layout.counts}
        interval = state_interval(1.0 / self.rate)
        for chain, _ in layout.chains:
            port = BufferedPort(nameclient=self.nameclient,
                                on_read=lambda b, chain=chain: self._on_state(chain, b),
                                min_interval=interval)
            port.open(f"/bridge/robot/state/{chain}:i")
            self._ports.append(port)
            # asked for at that rate (``+period``): the HAL sends 50 states a second, not 500
            self.keeper.want(protocol.port_names(self.robot, chain)["state_si"], port.name,
                             port, ours_is_source=False,
                             carrier=with_send_period("fast_tcp", interval))
        log.info("robot state: %d chains, %d joints", len(layout.chains), layout.joints)

    def _on_state(self, chain: str, bottle: Bottle) -> None:
        start, count = self._offsets.get(chain, (0, 0))
        try:
            state = protocol.decode_state_si(bottle, count)
        except HalProtocolError as exc:
            log.warning("robot state: %s: %s", chain, exc)
            return
        with self._lock:
            self._q[start:start + count] = state.q
            self._tau[start:start + count] = state.tau
            self._temperature[start:start + count] = state.temperature
            self._time = state.time
            self._unheard.discard(chain)
            if not self._unheard:    # a chain never heard would read as zeros on the pilot
                self._updated = time.monotonic()

    def snapshot(self) -> RobotState:
        with self._lock:
            return RobotState(self.layout, self._time, self._q.copy(), self._tau.copy(),
                              self._temperature.copy())

    def _run(self) -> None:
        asked = 0.0
        while not self._stop.wait(1.0 / self.rate):
            now = time.monotonic()
            stale = now - self._updated > 2.0
            if (self.layout is None or stale) and now - asked > 2.0:
                asked = now
                found = self._ask_layout()
                if found is not None and found != self.layout:
                    self._adopt(found)
            if self.layout is not None and self._updated > self._posted:
                self._posted = self._updated
                self.post(self.snapshot)

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=3)
        for port in self._ports:
            port.close()


class RobotStateSource:
    """Pilot side: the HAL's state ports, republished from what the link brings."""

    def __init__(self, robot: str, nameclient: NameClient) -> None:
        self.robot = robot
        self.nameclient = nameclient
        self.layout: Optional[Layout] = None
        self._ports: Dict[str, Tuple[Port, Port, Port]] = {}
        self._whole: Optional[Port] = None
        self._whole_joints: List[str] = []
        self._rpc: Optional[RpcServer] = None
        self._previous: Optional[RobotState] = None
        self._stamp = Stamp()
        self.received = 0

    def _adopt(self, layout: Layout) -> None:
        self.close()
        for chain, _ in layout.chains:
            names = protocol.port_names(self.robot, chain)
            self._ports[chain] = tuple(  # type: ignore[assignment]
                Port(nameclient=self.nameclient).open(names[key], wait=math.inf)
                for key in ("state", "state_ext", "state_si"))
        self._whole = Port(nameclient=self.nameclient).open(
            protocol.whole_state_port_name(self.robot), wait=math.inf)
        self._whole_joints = [joint for _, joints in layout.chains for joint in joints]
        self.layout = layout  # before the rpc port opens: its first caller gets the answer
        self._previous = None
        # The HAL's grouping, for whole-body readers on this side (read only: no commands).
        self._rpc = RpcServer(nameclient=self.nameclient, handler=self._on_rpc)
        self._rpc.open(protocol.robot_rpc_name(self.robot), wait=math.inf)

    def _on_rpc(self, request: Bottle) -> Bottle:
        if len(request) > 1 and str(request[0]) == "get" and str(request[1]) == "chains" and \
                self.layout is not None:
            return Bottle([Bottle([name, *joints]) for name, joints in self.layout.chains])
        return Bottle([Vocab("fail"), "the bridge's copy of the HAL only answers [get] chains"])

    def deliver(self, state: RobotState) -> bool:
        if state.layout != self.layout:
            self._adopt(state.layout)
        qdot = np.zeros_like(state.q)
        previous = self._previous
        if previous is not None and state.time > previous.time:
            qdot = (state.q - previous.q) / (state.time - previous.time)
        self._previous = state
        envelope = self._stamp.update(time.time()).envelope()
        self.received += 1
        pieces = zip(split_by_chain(state.layout, state.q), split_by_chain(state.layout, qdot),
                     split_by_chain(state.layout, state.tau),
                     split_by_chain(state.layout, state.temperature))
        if self._whole is not None and self._whole.has_outputs:
            self._whole.write(protocol.encode_whole_state(ChainState(
                self._stamp.count, state.time, tuple(state.q.tolist()), tuple(qdot.tolist()),
                tuple(state.tau.tolist()), tuple(state.temperature.tolist())),
                self._whole_joints))
        for (chain, q), (_, dq), (_, tau), (_, temperature) in pieces:
            state_port, ext_port, si_port = self._ports[chain]
            q_deg = np.degrees(q)
            state_port.write(Bottle(q_deg.tolist()), envelope)
            ext_port.write(encode_joint_data(JointData(
                tuple(q_deg.tolist()), tuple(np.degrees(dq).tolist()), None,
                tuple(tau.tolist())), len(q)), envelope)
            si_port.write(protocol.encode_state_si(ChainState(
                self._stamp.count, state.time, tuple(q.tolist()), tuple(dq.tolist()),
                tuple(tau.tolist()), tuple(temperature.tolist()))))
        return True

    def close(self) -> None:
        for ports in self._ports.values():
            for port in ports:
                port.close()
        self._ports = {}
        if self._whole is not None:
            self._whole.close()
            self._whole = None
        if self._rpc is not None:
            self._rpc.close()
            self._rpc = None
