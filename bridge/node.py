"""One side of the bridge: the configuration's flows wired to channels and endpoints.

Theory of operation
-------------------
The channels start first, so the link comes up whatever else is running; the
endpoints open in a background thread that waits for the local yarpserver and
roscore, so the bridge can start before them (and survives their restarts:
ports re-register, the :class:`~nodekit.connections.ConnectionKeeper` remakes
connections, :class:`~nodekit.ros_node.RosNode` re-registers topics).

Data flows sink -> channel -> (link) -> channel -> source.  What happens to each
message -- journalled, posted as the newest value, sent as datagrams or copies,
delivered, dropped -- is the sans-IO core's decision (:mod:`bridge.core`); this
class is the I/O shell that performs it (:meth:`Bridge._perform`), and its threads
start in one place (:class:`~bridge.transport.nursery.Nursery`).  A module's
stand-in ports (the pilot's ``/M/switch:i``, ``/M/status:o``...) are open only
while the peer reports the module's own ports connected (:mod:`bridge.gym.stand_ins`);
the same thread that opened the endpoints keeps them in step.  Reliable messages
(pilot commands, warnings) go through the journal on both sides; the delivery
thread writes the inbox to the local ports in order, one flow at a time, and
keeps a message until its port is connected -- a command already taken when
its module went down (or sent while the link is down) waits for the module, it
is not lost.

The bridge describes itself on ``/bridge/<side>/status:o`` (every second) and
answers ``status`` on ``/bridge/<side>/rpc:i``, for ``yarp rpc`` and scripts:
link phase, queues, and what was dropped by reason (:mod:`bridge.transport.drops`:
forged, replayed, strangers, stale...).
"""

from __future__ import annotations

import logging
import math
import threading
import time
from dataclasses import asdict
from pathlib import Path
from typing import Any, Dict, List, Optional, Set, Tuple

from bridge import rpc_words
from bridge import status as status_codec
from bridge.config import PILOT, ROBOT, BridgeConfig, Channel
from bridge.core import (AcceptCopy, BridgeCore, CarryOutStop, Deliver, Drop, Event, FrameLeft,
                         LocalMessage, PeerMessage, SendCopies, SendDatagrams, SendLatest,
                         SendReliable, TakeAck, UrgentMessage)
from bridge.errors import BridgeProtocolError, BridgeUsageError
from bridge.flows import FlowKey, Form, Route
from bridge.gym.delivery import Delivery
from bridge.gym.expiry import aged_payload
from bridge.gym.presence import Presence
from bridge.gym.stand_ins import PRESENCE_PERIOD, StandIns
from bridge.gym.stop_line import VERBS, Ack, PilotStops, RobotStops
from bridge.transport.copies import ReliableCopy, ReliableCopyCodec
from bridge.transport.drops import DropLedger, Reason
from bridge.transport.journal import Journal, QueueFull
from bridge.transport.nursery import Nursery
from bridge.transport.link_budget import LinkBudget
from bridge.transport.tcp_channel import TcpChannel, TcpListener, TcpSettings
from bridge.transport.udp_channel import UdpChannel, UdpRoute
from bridge.wire.link import LinkKey
from yarp_lite.bursts import Burst
from yarp_lite.errors import YarpError
from yarp_lite.nameclient import NameClient
from yarp_lite.port import Port
from yarp_lite.rpc import RpcServer

log = logging.getLogger("bridge")

#: How often the bridge writes its status on ``/bridge/<side>/status:o`` (the pilot gateway
#: tells the pilots from it that the link is down, within about two of these).
STATUS_PERIOD = 0.5
#: Seconds between tries to open the YARP side after the name server refused (a port's name
#: taken by another program, say): the bridge keeps trying, the link stays up meanwhile.
OPEN_RETRY = 2.0


class _TcpEvents(TcpListener):
    """What the TCP channel tells the bridge, routed to the part that acts on it."""

    def __init__(self, bridge: "Bridge") -> None:
        self.bridge = bridge

    def message(self, key: FlowKey, value: Any) -> None:
        self.bridge._on_message(key, value)

    def reliable(self) -> None:
        self.bridge.delivery.wake.set()

    def connected(self) -> None:
        self.bridge._on_link_up()

    def keys(self, event: str, send_key: bytes, receive_key: bytes) -> None:
        self.bridge._on_keys(event, send_key, receive_key)

    def presence(self) -> Optional[Presence]:
        return self.bridge.stand_ins.here()

    def peer_presence(self, flows: Presence) -> None:
        self.bridge.stand_ins.on_peer(flows)

    def copies(self, copies: List[Tuple[FlowKey, ReliableCopy]]) -> None:
        self.bridge._perform(FrameLeft(tuple(copies)))

    def age(self, payload: bytes, seconds: float) -> bytes:
        return aged_payload(payload, seconds)


class Bridge:
    """Everything one PC runs to reach the other."""

    def __init__(self, config: BridgeConfig, config_text: str, *, side: str, peer: str,
                 tcp_port: int, udp_port: int, peer_udp_port: Optional[int] = None,
                 listen: Optional[bool] = None, state_dir: Path,
                 udp_rate: Optional[float] = None, link_rate: Optional[float] = None,
                 link_timeout: float = 5.0, queue_limit: int = 1000, fsync: bool = False,
                 key: Optional[LinkKey] = None) -> None:
        if side not in (ROBOT, PILOT):
            raise ValueError(f"side must be robot or pilot, not {side!r}")
        self.config = config
        self.side = side
        self.nameclient = NameClient()
        self.journal = Journal(state_dir, limit=queue_limit, fsync=fsync)
        self.refused = 0
        self.internal_errors = 0
        self.drops = DropLedger("bridge", log)
        self._sources: Dict[FlowKey, Any] = {}
        self._sinks: List[Any] = []
        self._opened: Set[FlowKey] = set()   # the flows whose endpoint is open
        self._ros_sinks: List[Any] = []
        self._stop = threading.Event()
        self._nursery = Nursery()
        self._status_ports: List[Port] = []
        self.keeper = None
        self.ros_node = None
        self.routes: Dict[FlowKey, Route] = config.routes()
        udp_routes = self._udp_routes()
        #: every decision on a message; this class performs them (bridge.core)
        self.core = BridgeCore(side, self.routes, datagrams=bool(udp_routes),
                               stop=config.emergency_stop)
        self.delivery = Delivery(config, side, self.journal, self.routes, source=self._source,
                                 post=self._post, one_way=self._one_way,
                                 on_delivered=self.core.delivered, drops=self.drops)
        self.stand_ins = StandIns(config, side, state_dir, self.journal,
                                  open_endpoint=self._open_yarp_endpoint,
                                  on_here_changed=lambda: self.tcp.kick(),
                                  on_opened=self.delivery.wake.set,
                                  on_closed=self.core.module_gone)
        tcp_routes = [route for route in self.routes.values() if route.on_tcp]
        settings = TcpSettings(side, peer, tcp_port,
                               (side == ROBOT) if listen is None else listen, config_text,
                               config.period, link_timeout,
                               key=key if key is not None else LinkKey.none())
        #: the radio's queue as both channels fill it (None: no --link-rate, no budget)
        self.budget = LinkBudget(link_rate) if link_rate else None
        self.tcp = TcpChannel(settings, self.journal, tcp_routes, _TcpEvents(self), self.budget)
        self.udp = UdpChannel(peer=peer, port=udp_port, peer_port=peer_udp_port or udp_port,
                              routes=udp_routes, gather=config.gather,
                              on_message=self._on_message, rate=udp_rate,
                              budget=self.budget) if udp_routes else None
        stop = config.emergency_stop
        self.stop_all_here = None        # the robot's StopAll, once the name server answers
        self.pilot_stops = PilotStops(
            lambda order, again: self._perform(UrgentMessage(stop.stop_key, order, again)),
            round_trip=lambda: (self.tcp.round_trip_ms() or 0.0) / 1000.0) \
            if stop is not None and side == PILOT else None
        self.robot_stops = RobotStops(self._carry_out_stop,
                                      lambda ack, again: self._perform(
                                          UrgentMessage(stop.ack_key, ack, again)),
                                      threads=self._nursery) \
            if stop is not None and side == ROBOT else None

    def _on_keys(self, event: str, send_key: bytes, receive_key: bytes) -> None:
        if self.udp is not None:
            self.udp.set_keys(event, send_key, receive_key)

    # -- wiring ------------------------------------------------------------------------

    def _udp_routes(self) -> List[UdpRoute]:
        """The UDP channel's routes, each with the codec of its values."""
        from bridge.endpoints.yarp import BottleUdpCodec, StateUdpCodec

        udp = []
        for route in self.routes.values():
            if not route.on_udp:
                continue
            if route.reliable:   # a command's or receipt's datagram copies
                codec = ReliableCopyCodec()
            elif route.form is Form.STATE:
                codec = StateUdpCodec(1.0 / self.config.state_rate)
            elif route.form is Form.ROS:
                from bridge.endpoints.ros import codec_for

                codec = codec_for(self.config.channel(route.key))
            else:
                codec = BottleUdpCodec()
            udp.append(UdpRoute.of(route, codec))
        return udp

    def start(self) -> None:
        self.tcp.start()
        if self.udp is not None:
            self.udp.start()
        self._nursery.start_soon(self._open_endpoints, "endpoints")
        self._nursery.start_soon(lambda: self.delivery.run(self._stop), "delivery")

    def _open_endpoints(self) -> None:
        """Open every endpoint but the stand-ins, then keep the stand-ins in step."""
        from nodekit.connections import ConnectionKeeper

        ros_channels = [c for c in self.config.channels if c.middleware == "ros"]
        if ros_channels:
            self._start_ros(ros_channels)
        self.keeper = ConnectionKeeper()
        opening = time.monotonic()
        failures = Burst()
        while not self._stop.is_set():
            try:
                self._open_yarp_side()
                break
            except YarpError as exc:   # a name taken, a name server refusing: not for good
                if failures.record():
                    log.error("cannot open the YARP side (%s); trying again every %.0f s "
                              "(%d tries)", exc, OPEN_RETRY, failures.count)
                self._stop.wait(OPEN_RETRY)
            except Exception:
                log.exception("opening the endpoints failed")
                raise
        if self._stop.is_set():
            return
        # Connect to the modules already here before saying which are: a bridge that
        # restarts must not tell the peer, for a moment, that every module has gone.
        connecting = time.monotonic()
        self.keeper.check_now()
        connected = time.monotonic()
        self._stop.wait(PRESENCE_PERIOD)
        self.keeper.start()
        self.delivery.wake.set()
        if self.robot_stops is not None:
            self._open_stop_all()
        log.info("bridge %s side ready: %d flows out, %d in (ports opened in %.2f s, "
                 "connected to the modules here in %.2f s)", self.side,
                 len(self.config.sending(self.side)), len(self.config.receiving(self.side)),
                 connecting - opening, connected - connecting)
        self.stand_ins.keep(self._stop)

    def _open_yarp_side(self) -> None:
        """Open the status ports and every YARP endpoint not open yet (so a try after a
        failure opens only what the last one did not)."""
        from bridge.endpoints.yarp import RobotStateSink, RobotStateSource

        self._open_status_ports()
        for channel in self.config.channels:
            if self._stop.is_set():
                return
            if channel.middleware != "yarp" or channel.key in self.stand_ins.keys or \
                    channel.key in self._opened:
                continue
            endpoint = self._open_yarp_endpoint(channel)
            self._opened.add(channel.key)
            if channel.key in self.stand_ins.watched:
                self.stand_ins.watch(channel.key, endpoint)
            if channel.source == self.side:
                self._sinks.append(endpoint)
            else:
                self._sources[channel.key] = endpoint
        state = self.config.robot_state
        if state is not None and state.key not in self._opened:
            if self.side == ROBOT:
                self._sinks.append(RobotStateSink(
                    state.robot, self.nameclient, self.keeper,
                    lambda snapshot: self._post(self.routes[state.key], snapshot),
                    self.config.state_rate, self._nursery))
            else:
                self._sources[state.key] = RobotStateSource(state.robot, self.nameclient)
            self._opened.add(state.key)

    def _open_yarp_endpoint(self, channel: Channel) -> Any:
        from bridge.endpoints.yarp import YarpSink, YarpSource

        if channel.source == self.side:
            return YarpSink(channel, self.nameclient, self.keeper, self._submit)
        return YarpSource(channel, self.nameclient, self.keeper)

    def _start_ros(self, channels: List[Channel]) -> None:
        from bridge.endpoints.ros import RosSink, RosSource
        from nodekit.ros_node import RosNode

        self.ros_node = RosNode(f"walkman_bridge_{self.side}")

        def open_topics() -> None:
            for channel in channels:
                if channel.source == self.side:
                    self._ros_sinks.append(RosSink(channel, self._submit))
                else:
                    self._sources[channel.key] = RosSource(channel)

        self.ros_node.when_ready(open_topics)
        self.ros_node.start()
        self._nursery.start_soon(self._repeat_latched, "latched")

    def _open_status_ports(self) -> None:
        """``/bridge/<side>/status:o`` (then its publisher) and ``rpc:i``, each once."""
        base = f"/bridge/{self.side}"
        if not self._status_ports:
            status = Port(nameclient=self.nameclient).open(f"{base}/status:o", wait=math.inf)
            self._status_ports.append(status)
            self._nursery.start_soon(lambda: self._publish_status(status), "status")
        if len(self._status_ports) == 1:
            rpc = RpcServer(nameclient=self.nameclient,
                            handler=lambda request: rpc_words.answer(request, self))
            rpc.open(f"{base}/rpc:i", wait=math.inf)
            self._status_ports.append(rpc)

    # -- data paths --------------------------------------------------------------------

    def _source(self, key: FlowKey) -> Optional[Any]:
        """The endpoint that delivers ``key``'s messages here: always open, or a stand-in."""
        return self._sources.get(key) or self.stand_ins.source(key)

    def _submit(self, channel: Channel, value: Any) -> None:
        """A local message for the link (called by sinks, in their threads)."""
        self._post(self.routes[channel.key], value)

    def _post(self, route: Route, value: Any) -> None:
        """``value`` onto the link the way its route says (a sink's message, a receipt)."""
        self._perform(LocalMessage(route.key, value))

    def _on_message(self, key: FlowKey, value: Any) -> None:
        """A message off either channel (in the channel's thread)."""
        self._perform(PeerMessage(key, value))

    def _perform(self, event: Event) -> None:
        """What the core decides for ``event``, done: the bridge's only I/O on messages."""
        for action in self.core.handle(event):
            match action:
                case SendReliable(key, value):
                    try:
                        self.tcp.send_reliable(key, value)
                    except QueueFull as exc:
                        self.refused += 1
                        log.error("refused a message on %s: %s", self.routes[key].label, exc)
                case SendLatest(key, value, urgent):
                    self.tcp.post(key, value, event=urgent)
                case SendDatagrams(key, value) if self.udp is not None:
                    self.udp.post(key, value)
                case SendCopies(key, value, count, again) if self.udp is not None:
                    self.udp.send_now(key, value, count, again)
                case AcceptCopy(key, copy):
                    self.tcp.accept_copy(key, copy)
                case Deliver(key, value):
                    self._deliver(key, value)
                case CarryOutStop(order) if self.robot_stops is not None:
                    self.robot_stops.on_order(order)
                case TakeAck(ack) if self.pilot_stops is not None:
                    self.pilot_stops.on_ack(ack)
                case Drop(reason, detail):
                    self.drops.drop(reason, detail)
                case _:     # the core decided for an I/O this side does not have: a bug
                    self.internal_errors += 1
                    log.error("bridge core: %r cannot be carried out on the %s's side",
                              action, self.side)

    def _deliver(self, key: FlowKey, value: Any) -> None:
        source = self._source(key)
        if source is None:
            self.drops.drop(Reason.NOT_READY, f"{key}: local endpoint not open yet")
            return
        try:
            source.deliver(value)
        except (YarpError, BridgeProtocolError) as exc:
            log.warning("delivering on %s failed: %s", key, exc)

    # -- the stop-all -------------------------------------------------------------------

    def stop_all(self, word: str = "stop_all", timeout: float = 5.0) -> Optional[Ack]:
        """Pilot side: hold the robot (``stop_all``) or let its HAL go (``release``);
        the robot's acknowledgement, or None if none came in ``timeout``."""
        if self.pilot_stops is None:
            raise BridgeUsageError("no <emergency_stop> in the configuration, or not the "
                                   "pilot's bridge: nothing to send a stop-all on")
        return self.pilot_stops.order(word, timeout)

    def _open_stop_all(self) -> None:
        from walkman.gym.stop_all import StopAll

        stop = self.config.emergency_stop
        try:
            self.stop_all_here = StopAll(stop.robot, sorted(self.config.gym_modules),
                                         "/bridge/robot/stop_all", self.nameclient)
        except YarpError as exc:
            log.error("stop-all: cannot open its ports (%s); a stop-all will be acknowledged "
                      "as NOT carried out", exc)

    def _carry_out_stop(self, word: str, stop_id: int) -> Ack:
        """Robot side: the HAL holds and every module pauses (or the HAL is released)."""
        executor = self.stop_all_here
        if executor is None:
            return Ack(stop_id, VERBS[word], False, 0.0)
        report = executor.stop(stop_id) if word == "stop_all" else executor.release(stop_id)
        return Ack(stop_id, VERBS[word], report.hal, report.took_ms, tuple(report.modules))

    def _one_way(self) -> float:
        """Seconds a message takes over the link, as half the measured round trip."""
        return (self.tcp.round_trip_ms() or 0.0) / 2000.0

    def _on_link_up(self) -> None:
        for sink in self._ros_sinks:
            sink.repeat_latched(force=True)

    def _repeat_latched(self) -> None:
        while not self._stop.wait(1.0):
            for sink in list(self._ros_sinks):
                sink.repeat_latched()

    # -- status -------------------------------------------------------------------------

    def status(self) -> Dict[str, Any]:
        stats = self.tcp.stats
        silent = self.tcp.silent_s()
        out: Dict[str, Any] = {
            "side": self.side,
            "time": round(time.time(), 3),  # wall clock, so samples read later keep their time
            "link": self.tcp.phase,
            "link_since_s": int(time.monotonic() - self.tcp.phase_since),
            "silent_s": round(silent, 1) if silent is not None else -1.0,
            "round_trip_ms": round(self.tcp.round_trip_ms() or 0.0, 1),
            "queued_commands": self.journal.waiting(),
            "oldest_queued_s": int(self.journal.oldest_age()),
            "undelivered": len(self.journal.undelivered()),
            "refused": self.refused,
            "delivered": self.delivery.delivered,
            "cancelled_dropped": self.delivery.cancelled_dropped,
            "internal_errors": self.internal_errors + self.stand_ins.internal_errors +
            self.delivery.internal_errors,
            "authenticated": self.tcp.settings.key.keyed,
            "modules_here": self._modules(self.stand_ins.here() or frozenset()),
            "modules_shown": self._modules(self.stand_ins.shown()),
            "dropped": self._dropped(),
            "tcp": {**asdict(stats), "drops": dict(self.tcp.drops.counts),
                    "last_drop": self.tcp.drops.last_error},
        }
        if self.budget is not None:
            out["link_budget"] = {"rate": self.budget.rate, "limit": int(self.budget.limit),
                                  "queued": int(self.budget.queued(time.monotonic())),
                                  "spent": self.budget.spent,
                                  "spent_over_limit": self.budget.spent_over}
        if self.udp is not None:
            udp = {**asdict(self.udp.stats), "drops": dict(self.udp.drops.counts),
                   "last_drop": self.udp.drops.last_error}
            udp["flows"] = {name: {**flow, "mean_completeness": round(
                self.udp.stats.flows[name].mean_completeness, 4)}
                for name, flow in udp["flows"].items()}
            out["udp"] = udp
        return out

    def _modules(self, flows: Presence) -> List[str]:
        """The modules that have any of ``flows``."""
        names = {self.config.channel(key).module for key in flows}
        return sorted(names)

    def _dropped(self) -> Dict[str, int]:
        """Drops by reason, summed over the channels and the delivery side."""
        total: Dict[str, int] = {}
        for ledger in (self.tcp.drops, self.udp.drops if self.udp else None, self.drops):
            for reason, count in (ledger.counts.items() if ledger else ()):
                total[reason] = total.get(reason, 0) + count
        return total

    def cancel(self, module: str, seq: Optional[int]) -> Tuple[List[int], List[int]]:
        """Take back the module's switch or command numbered ``seq`` (every one, for None)
        if no frame has carried it yet: :meth:`bridge.gym.delivery.Delivery.cancel`."""
        return self.delivery.cancel(module, seq)

    def _publish_status(self, port: Port) -> None:
        """The status every period to every reader that took the last one: a reader held up
        misses some, and the others never wait for it (they would read "link down")."""
        while not self._stop.wait(STATUS_PERIOD):
            try:
                port.write(status_codec.to_bottle(self.status()), skip_busy=True)
            except YarpError as exc:
                log.warning("%s: status not published (%s)", port.name, exc)

    def stop(self) -> None:
        self._stop.set()
        self.delivery.wake.set()
        stand_ins = self.stand_ins.close()   # none opens from now on
        if self.stop_all_here is not None:
            self.stop_all_here.close()
        if self.keeper is not None:
            self.keeper.stop()
        self.tcp.stop()
        if self.udp is not None:
            self.udp.stop()
        endpoints = {id(e): e for e in [*self._sinks, *list(self._sources.values()),
                                        *stand_ins, *self._ros_sinks]}
        for endpoint in endpoints.values():
            try:
                endpoint.close()
            except (YarpError, OSError) as exc:   # its network already gone: nothing to close
                log.debug("closing %s: %s", endpoint, exc)
            except Exception:  # noqa: BLE001 -- a bug: seen, and the others still closed
                self.internal_errors += 1
                log.exception("closing %s failed (a bug)", endpoint)
        for port in self._status_ports:
            port.close()
        if self.ros_node is not None:
            self.ros_node.stop()
        self.journal.close()

