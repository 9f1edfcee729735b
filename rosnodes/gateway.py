"""``walkman-pilot-gateway``: every GYM module of the bridge configuration, as ROS topics.

Theory of operation
-------------------
For each module ``M`` the gateway opens four YARP ports on the pilot's name
server (``/pilot_gateway/<station>/M/...``) and keeps them connected to the module's
``/M/switch:i``, ``/M/command:i``, ``/M/status:o`` and ``/M/warning:o`` -- the
module itself in the lab, the bridge's stand-ins in the DRC topology.  On the
pilot roscore it offers:

===========================  ==================================  ===========================
``/M/switch``                ``walkman_msgs/Switch``             in: start pause resume stop quit
``/M/command``               ``walkman_msgs/Command``            in (dangerous ones count down)
``/M/status``                ``walkman_msgs/Status``             out, latched, states decoded
``/M/warning``               ``walkman_msgs/Warning``            out
``/M/countdown``             ``walkman_msgs/Countdown``          out, 10 Hz while one waits
``/M/switch_and_wait``       ``walkman_msgs/SwitchModule``       service: the new state
``/M/send_command``          ``walkman_msgs/SendCommand``        service: the sequence number
``/M/get_status``            ``walkman_msgs/GetStatus``          service
``/pilot/sent_commands``     ``walkman_msgs/SentCommand``        out: everything any station sent
``/bridge/link``             ``walkman_msgs/Link``               out, latched: up, down, direct
``/pilot/command_states``    ``walkman_msgs/CommandState``       out: each command's life
``/pilot/stop_all``          ``walkman_msgs/StopAll``            service: hold the robot now
``/pilot/release``           ``walkman_msgs/StopAll``            service: the HAL may move again
``/pilot/scene_edit``        ``walkman_msgs/SceneObject``        in: an object a pilot placed
``/pilot/scene``             ``walkman_msgs/Scene``              out, latched: the shared scene
===========================  ==================================  ===========================

Every command and switch leaves with its lifetime (:mod:`walkman.gym.validity`):
the validity the pilot set, else the module's own default; a dangerous one may
start only within a short grace after its countdown.  ``/bridge/link`` follows the
pilot bridge's status port (:mod:`nodekit.link_watch`; ``--link direct`` in the
lab, where there is no bridge), so a pilot tells "link down" from "module dead".

Several gateways (the DRC had three pilot PCs: one roscore and one gateway
each, all on the pilot YARP name server) each claim a station number
(:mod:`rosnodes.stations`): their sequence numbers never collide, even in the
same millisecond, so a module never mistakes two pilots' commands for a
resend; and each republishes what the others sent, with who sent it (the
``sender`` of a Command or Switch: a Pilot Interface's name), so every pilot's
log shows every command; the shared 3-D scene crosses between stations the same way
(:mod:`rosnodes.scene_keeper`).  One roscore has one gateway: a second would forward every topic
command again, so it refuses to start.  Statuses are decoded with the module's list of states
(the ``statuses`` attribute in the bridge configuration, or the module's class).

Its parts: :mod:`rosnodes.module_link` (one module's ports), :mod:`rosnodes.gateway_ros`
(the services and command topics, as ROS messages), :mod:`rosnodes.pilot_topics` (what it
publishes), :mod:`rosnodes.stations` (station numbers, what the others sent) and
:mod:`rosnodes.scene_keeper` (the shared scene); this module decides and sends.  A message
from a topic is sent by a sender thread of its module and topic, never inside a rospy
callback (it may wait for its module's connection).
"""

from __future__ import annotations

import argparse
import logging
import math
import os
import queue
import re
import socket
import sys
import threading
import time
from pathlib import Path
from dataclasses import dataclass, field, replace
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple

from bridge import config as bridge_config
from bridge import rpc_words
from bridge import status as bridge_status
from bridge.errors import BridgeProtocolError, BridgeUsageError
from nodekit.connections import ConnectionKeeper
from nodekit.logs import configure_logging
from nodekit.link_watch import LinkPhase, LinkState, LinkWatch
from rosnodes.module_link import HeardStatus, ModuleLink, Sent
from rosnodes.gateway_ros import RosFace
from rosnodes.pilot_topics import PilotTopics
from rosnodes.scene_keeper import SceneKeeper
from rosnodes.stations import (SequenceNumbers, StationError, claim_station, parse_sent,
                               sent_bottle_fields)
from rosnodes.timed import CANCELLED, SENT, Countdowns
from walkman.gym.lifecycle import TARGET
from walkman.modules import module_class
from walkman.gym.command_life import (CommandLife, CommandState, Ledger, Receipt,
                                      ReceiptError, decode_receipt)
from walkman.gym.interfaces import (InterfaceError, PilotCommand, command_text, decode_command,
                                    decoder_for, decode_status, encode_command, readable)
from walkman.gym.validity import (DANGEROUS_GRACE, Lifetime, ValidityError, check_validity,
                                  stamp)
from yarp_lite.bottle import Bottle
from yarp_lite.bottle_text import parse
from yarp_lite.errors import YarpError
from yarp_lite.nameclient import NameClient
from yarp_lite.port import Port
from yarp_lite.rpc import RpcClient
from walkman import MODELS_DIR

log = logging.getLogger("walkman.gateway")

DEFAULT_CONFIG = MODELS_DIR / "bridge_drc.xml"
#: Where the pilot bridge says how the link is (:mod:`bridge.node`), and takes cancels.
BRIDGE_STATUS = "/bridge/pilot/status:o"
BRIDGE_RPC = "/bridge/pilot/rpc:i"
#: The lifecycle state each switch word leads to (walkman.gym.lifecycle owns the table).
EXPECTED = {switch.value: state.value for switch, state in TARGET.items()}


@dataclass(frozen=True)
class Switched:
    """A switch-and-wait's outcome: the module's state then, and why not, if not."""

    ok: bool
    state: str
    message: str = ""


@dataclass(frozen=True)
class Cancelled:
    """A cancel's outcome: the numbers taken back, and what happened, in words."""

    ok: bool
    numbers: List[int]
    message: str


@dataclass(frozen=True)
class Stopped:
    """A stop-all's or release's outcome, as ``/pilot/stop_all`` answers it."""

    ok: bool
    message: str
    round_trip_ms: float = 0.0
    robot_ms: float = 0.0
    paused: List[str] = field(default_factory=list)


class GatewayError(Exception):
    """The gateway was started or asked wrongly; the text says how."""


def module_statuses(name: str, declared: Sequence[str]) -> List[str]:
    """The module's list of states: from the configuration, else from its class."""
    if declared:
        return list(declared)
    return list(getattr(module_class(name), "statuses", []) or [])


def command_decoder(name: str) -> Callable[[Bottle], PilotCommand]:
    """How the module reads ``cmd N`` (an argument for commands that need numbers)."""
    found = module_class(name)
    return decoder_for(found) if found is not None else decode_command


def lifetime(module: str, asked: float) -> Lifetime:
    """A fresh command's lifetime: the validity the pilot asked for, else none said, so the
    module applies its own default (its class is the one truth for it, and a module the
    pilot PC does not know declares it too)."""
    if not asked:
        return Lifetime(0.0, None)
    try:
        return Lifetime(0.0, check_validity(float(asked)))
    except ValidityError as exc:
        raise GatewayError(f"validity: {exc}") from None


def life_text(sent: str) -> str:
    """A sent command's text as the pilot typed it: ``(turn 1.57) 42`` -> ``turn 1.57``."""
    try:
        return command_text(decode_command(parse(sent)))
    except (InterfaceError, ValueError):
        return sent


def build_command(msg: Any, seq: int,
                  decode: Callable[[Bottle], PilotCommand] = decode_command) -> PilotCommand:
    """A ``walkman_msgs/Command`` (or SendCommand request) as the GYM command it names."""
    text = (msg.text or "").strip()
    if text:
        try:
            parsed = decode(parse(text))
        except (InterfaceError, ValueError) as exc:
            raise GatewayError(f"command text {text!r} is not a command: {exc}") from None
        return PilotCommand(parsed.name, parsed.args, seq)
    name = (msg.command or "").strip()
    if not name or " " in name:
        raise GatewayError(f"command name {msg.command!r} must be one word (or use text)")
    return PilotCommand(name, (*[str(w) for w in msg.words], *[float(n) for n in msg.numbers]),
                        seq)


class Gateway:
    """All modules' links and their ROS faces."""

    def __init__(self, modules: Dict[str, List[str]], countdown: float, node_name: str,
                 direct: bool = False) -> None:
        self.modules = modules
        self.link_watch = LinkWatch(direct, time.monotonic())
        self.ledger = Ledger()
        self._ledger_lock = threading.Lock()
        self._link_lock = threading.Lock()
        self.bridge_in: Optional[Port] = None
        self._stopper = None    # the lab's stop-all executor (walkman.gym.stop_all)
        self.prefix = ""
        self.station = 0
        self.node_name = node_name
        self.countdowns = Countdowns(countdown)
        self.sequence: Optional[SequenceNumbers] = None
        self.sent_out: Optional[Port] = None
        self.sent_in: Optional[Port] = None
        self.scene: Optional[SceneKeeper] = None
        self._peers: set = set()
        #: set once the station is claimed and the ports are open: ROS waits for it
        self.yarp_open = threading.Event()
        self.links: Dict[str, ModuleLink] = {}
        self.keeper = ConnectionKeeper()
        self.nameclient = NameClient()
        self._lock = threading.Lock()
        self.topics = PilotTopics(modules)
        self._ros_handlers: List[Any] = []   # subscribers and services, kept alive
        self._stop = threading.Event()
        #: what the pilots' topics ask of each module, its switches and its commands each
        #: done in order by a sender thread of their own (as rospy gave each topic one): a
        #: message may wait up to CONNECT_GRACE for its connection, never in a rospy
        #: callback, in front of another module's, or a switch (a stop) behind a command
        self._asked: Dict[Tuple[str, str], "queue.Queue[Callable[[], None]]"] = {
            (module, kind): queue.Queue() for module in modules for kind in ("switch", "command")}
        #: set when the gateway must end: a signal, or ``error`` (another gateway is here)
        self.finished = threading.Event()
        self.error = ""
        self.ros_node = None

    # -- YARP side ---------------------------------------------------------------------

    def open_yarp(self) -> None:
        """Claim a station, then open every module's ports under ``/pilot_gateway/<station>``."""
        self.station, self.sent_out = claim_station(
            self.nameclient, lambda name: Port(nameclient=self.nameclient).open(name,
                                                                               wait=math.inf))
        self.sequence = SequenceNumbers(self.station)
        self.prefix = f"/pilot_gateway/{self.station}"
        self.sent_in = Port(nameclient=self.nameclient, reader=self._on_peer_sent)
        self.sent_in.open(f"{self.prefix}/sent:i", wait=math.inf)
        self.scene = SceneKeeper(self.station, self.prefix, self.nameclient)
        for module, statuses in self.modules.items():
            self.links[module] = ModuleLink(module, statuses, self.prefix, self.nameclient,
                                            self.keeper, self._on_status, self._on_warning,
                                            self._on_receipt)
        if self.link_watch.state.state is LinkPhase.DIRECT:
            from walkman.gym.stop_all import StopAll

            self._stopper = StopAll("walkman", list(self.modules), f"{self.prefix}/stop_all",
                                    self.nameclient)
        else:
            self.bridge_in = Port(nameclient=self.nameclient, reader=self._on_bridge_status)
            self.bridge_in.open(f"{self.prefix}/bridge:i", wait=math.inf)
            self.keeper.want(BRIDGE_STATUS, self.bridge_in.name, self.bridge_in,
                             ours_is_source=False)
            threading.Thread(target=self._watch_link, name="gateway link", daemon=True).start()
        self.keeper.start()
        threading.Thread(target=self._find_peers, name="gateway peers", daemon=True).start()
        self.yarp_open.set()
        log.info("gateway: pilot station %d; YARP ports open for %s", self.station,
                 ", ".join(self.modules))

    def _find_peers(self) -> None:
        """Read every other station's ``sent:o`` and ``scene:o``, found on the name server at
        once and then every 2 s (a station that waited first missed what the others sent
        meanwhile)."""
        pattern = re.compile(r"^/pilot_gateway/(\d+)/(sent|scene):o$")
        readers = {"sent": self.sent_in, "scene": self.scene.into}
        while True:
            try:
                names = [c.name for c in self.nameclient.list()]
            except YarpError:
                names = []
            for name in names:
                found = pattern.match(name)
                if found and int(found.group(1)) != self.station and name not in self._peers:
                    self._peers.add(name)
                    reader = readers[found.group(2)]
                    self.keeper.want(name, reader.name, reader, ours_is_source=False)
            if self._stop.wait(2.0):
                return

    # -- the link ----------------------------------------------------------------------

    def _on_bridge_status(self, bottle: Bottle) -> None:
        try:
            status = bridge_status.from_bottle(bottle)
        except BridgeProtocolError as exc:
            log.warning("gateway: not a bridge status on %s: %s", BRIDGE_STATUS, exc)
            return
        with self._link_lock:
            changed = self.link_watch.on_status(status, time.monotonic())
        if changed is not None:
            self._link_changed(changed)

    def _watch_link(self) -> None:
        while not self._stop.wait(0.25):
            with self._link_lock:
                changed = self.link_watch.tick(time.monotonic())
            if changed is not None:
                self._link_changed(changed)

    def _link_changed(self, state: LinkState) -> None:
        if state.state is LinkPhase.DOWN:
            log.warning("gateway: the link to the robot is down (%s); %d command(s) held",
                        state.reason, state.queued)
            with self._ledger_lock:
                changed = self.ledger.link_down()
            self._publish_states(changed)
        else:
            log.info("gateway: the link to the robot is %s", state.state)
        self._publish_link()

    def _publish_link(self) -> None:
        with self._link_lock:
            state = self.link_watch.state
        self.topics.link(state, time.monotonic() - state.since)

    def _on_peer_sent(self, bottle: Bottle) -> None:
        fields = parse_sent(bottle)
        if fields is None:
            log.warning("gateway: a malformed sent-command record from another station: %s",
                        str(bottle)[:120])
            return
        station, sender, module, port, text, seq = fields
        if station != self.station:
            log.info("gateway: station %d sent to /%s/%s:i: %s (from %s)", station, module,
                     port, text, sender)
            self._publish_sent(module, port, text, seq, sender, station)

    def _on_status(self, link: ModuleLink, bottle: Bottle) -> None:
        try:
            seq, state, data = decode_status(bottle, link.statuses)
        except InterfaceError as exc:
            log.warning("gateway: %s sent a malformed status: %s", link.module, exc)
            return
        code = str(bottle[1])
        with link.changed:
            link.last_status = HeardStatus(seq, state, data, bottle)
            link.changed.notify_all()
        self.topics.status(link.module, seq, state, code, data)

    def _on_warning(self, link: ModuleLink, bottle: Bottle) -> None:
        text = " ".join(str(v) for v in bottle[1:]) if len(bottle) > 1 else str(bottle)
        seq = int(bottle[0]) if bottle and isinstance(bottle[0], int) else 0
        with link.changed:
            link.warnings.append(text)
            link.changed.notify_all()
        self.topics.warning(link.module, seq, text)

    # -- ROS side ----------------------------------------------------------------------

    def start_ros(self) -> None:
        from nodekit.ros_node import RosNode

        self.ros_node = RosNode(self.node_name)
        self.ros_node.when_ready(self._open_ros)
        self.ros_node.when_failed(self._ros_failed)
        self.ros_node.start()

    def _ros_failed(self, why: str) -> None:
        """No topics, no services: a gateway without its ROS side serves no pilot."""
        self.error = f"its ROS side did not open: {why}"
        self.finished.set()

    def _other_gateway(self) -> Optional[str]:
        """The URI of a live gateway already serving our modules on this roscore, if any."""
        import rosgraph
        import rospy

        master = rosgraph.Master(rospy.get_name())
        for module in self.modules:
            try:
                uri = master.lookupService(f"/{module}/send_command")
            except (rosgraph.MasterError, OSError):
                continue
            host_port = uri.split("://", 1)[-1].rstrip("/")
            host, _, port = host_port.rpartition(":")
            try:
                socket.create_connection((host, int(port)), timeout=2).close()
            except (OSError, ValueError):
                continue  # left behind by a gateway that died: ours replaces it
            return uri  # asked before we register anything: it is not ours
        return None

    def _open_ros(self) -> None:
        """Once the node is registered (a roscore restart registers the same again:
        :class:`nodekit.ros_node.RosNode`)."""
        while not self.yarp_open.wait(1.0):    # the station numbers what ROS brings
            if self.finished.is_set():
                return
        other = self._other_gateway()
        if other is not None:
            self.error = (f"another pilot gateway already serves these modules on this "
                          f"roscore ({other}); a second one would forward every topic "
                          f"command twice.  Run one gateway per roscore (several pilots: "
                          f"one roscore each, all on the pilot YARP name server)")
            self.finished.set()
            return
        self.topics.open()
        self._publish_link()
        self._ros_handlers = RosFace(self).open()
        for module, link in self.links.items():
            heard = link.last_status
            if heard is not None:
                self.topics.status(module, heard.seq, heard.state, heard.code, heard.data)
        self.scene.open_ros()
        threading.Thread(target=self._countdown_loop, name="gateway countdowns",
                         daemon=True).start()
        for (module, kind), asked in self._asked.items():
            threading.Thread(target=self._sender_loop, args=(asked,),
                             name=f"gateway {module} {kind}", daemon=True).start()
        log.info("gateway: ROS topics and services up for %s", ", ".join(self.modules))

    # -- sending -----------------------------------------------------------------------

    def send_switch(self, module: str, word: str, seq: int = 0, sender: str = "",
                    validity: float = 0.0) -> Sent:
        link = self.links[module]
        word = word.strip().lower()
        if word not in EXPECTED:
            return Sent(False, f"'{word}' is not a switch command (start, pause, resume, "
                               f"stop, quit)")
        seq = seq or self.sequence.next()
        try:
            life = lifetime(module, validity)
        except GatewayError as exc:
            return Sent(False, str(exc))
        sent_at = self.topics.now()     # before the send: its receipt may come back at once
        sent = link.send(link.switch, stamp(Bottle([word, seq]), life))
        if sent.ok:
            if word in ("stop", "quit"):
                for event in self.countdowns.cancel_all(module):
                    self._publish_countdown(event, sender)
            self._log_sent(module, "switch", f"{word} {seq}", seq, sender, sent_at)
        return replace(sent, seq=seq)

    def send_command(self, module: str, command: PilotCommand,
                     sender: str = "") -> Sent:
        link = self.links[module]
        if command.lifetime is None:
            command = replace(command, lifetime=lifetime(module, 0.0))
        sent_at = self.topics.now()     # before the send: its receipt may come back at once
        sent = link.send(link.command, encode_command(command))
        if sent.ok:
            shown = encode_command(replace(command, lifetime=None))
            self._log_sent(module, "command", readable(shown), command.seq or 0, sender,
                           sent_at)
        return replace(sent, seq=command.seq or 0)

    def _log_sent(self, module: str, port: str, text: str, seq: int, sender: str,
                  sent_at: Optional[Any] = None) -> None:
        sender = sender or "rostopic"
        log.info("gateway: sent to /%s/%s:i: %s (from %s)", module, port, text, sender)
        if self.sent_out is not None:
            self.sent_out.write(Bottle(sent_bottle_fields(self.station, sender, module, port,
                                                          text, seq)))
        self._publish_sent(module, port, text, seq, sender, self.station, sent_at)

    def _publish_sent(self, module: str, port: str, text: str, seq: int, sender: str,
                      station: int, sent_at: Optional[Any] = None) -> None:
        if seq:
            life = CommandLife(module, port, seq, life_text(text), sender or "rostopic",
                               station)
            with self._ledger_lock:
                changed = self.ledger.sent(
                    life, link_down=self.link_watch.state.state is LinkPhase.DOWN)
            self._publish_states(changed)
        self.topics.sent(module, port, text, seq, sender, station, sent_at)

    # -- the commands' lives -------------------------------------------------------------

    def _on_receipt(self, link: ModuleLink, bottle: Bottle) -> None:
        try:
            receipt = decode_receipt(bottle)
        except ReceiptError as exc:
            log.warning("gateway: %s sent a malformed receipt: %s", link.module, exc)
            return
        with self._ledger_lock:
            changed = self.ledger.receipt(link.module, receipt)
        self._publish_states(changed)

    def _publish_states(self, lives: List[CommandLife]) -> None:
        self.topics.command_states(lives)

    def _refuse(self, module: str, text: str) -> None:
        log.warning("gateway: %s", text)
        self.topics.warning(module, 0, f"gateway: {text}")

    def _sender_loop(self, asked: "queue.Queue[Callable[[], None]]") -> None:
        while not self._stop.is_set():
            try:
                job = asked.get(timeout=0.25)
            except queue.Empty:
                continue
            try:
                job()
            except Exception:  # noqa: BLE001 -- our bug: seen; the next message still goes
                log.exception("gateway: sending a pilot's message failed (a bug)")

    def ask_switch(self, module: str, msg: Any) -> None:
        """A ``walkman_msgs/Switch`` from a topic: sent by the module's switch sender, in
        order (a rospy callback returns at once)."""
        self._asked[(module, "switch")].put(lambda: self._switch_from_topic(module, msg))

    def ask_command(self, module: str, msg: Any) -> None:
        """A ``walkman_msgs/Command`` from a topic: counted down if dangerous, else sent,
        by the module's command sender, in order (a rospy callback returns at once)."""
        self._asked[(module, "command")].put(lambda: self._command_from_topic(module, msg))

    def _switch_from_topic(self, module: str, msg: Any) -> None:
        sent = self.send_switch(module, msg.command, msg.seq, msg.sender,
                                getattr(msg, "validity", 0.0))
        if not sent.ok:
            self._refuse(module, sent.message)

    def _command_from_topic(self, module: str, msg: Any) -> None:
        try:
            command = build_command(msg, msg.seq or 0, command_decoder(module))
            life = lifetime(module, getattr(msg, "validity", 0.0))
        except GatewayError as exc:
            self._refuse(module, str(exc))
            return
        if msg.dangerous:
            text = encode_command(replace(command, seq=None, lifetime=None)).to_text()
            sender = msg.sender or "rostopic"
            now = time.monotonic()
            countdown = float(msg.countdown) or self.countdowns.default
            # It may start within a short grace after its countdown, never later: one
            # queued through a blackout that ended the countdown does not run.
            life = Lifetime(0.0, countdown + DANGEROUS_GRACE)
            try:
                event = self.countdowns.request(module, text, now, (command, sender, life, now),
                                                countdown)
            except ValueError as exc:
                self._refuse(module, str(exc))
                return
            log.info("gateway: %s %s: %s (%s)", module, text,
                     "cancelled" if event.state == CANCELLED else
                     f"waiting {event.remaining:.1f} s (send it again to cancel)", sender)
            self._publish_countdown(event, sender)
            return
        sent = self.send_command(module, replace(
            command, seq=command.seq or self.sequence.next(), lifetime=life), msg.sender)
        if not sent.ok:
            self._refuse(module, sent.message)

    def _countdown_loop(self) -> None:
        while not self._stop.wait(0.1):
            now = time.monotonic()
            for event in self.countdowns.tick(now):
                command, sender, life, asked = event.pending.payload
                if event.state == SENT:
                    sent = self.send_command(event.pending.module, replace(
                        command, seq=command.seq or self.sequence.next(),
                        lifetime=life.older(now - asked)), sender)
                    if not sent.ok:
                        self._refuse(event.pending.module, sent.message)
                self._publish_countdown(event, sender)

    def _publish_countdown(self, event, sender: str = "") -> None:
        self.topics.countdown(event.pending.module, event.pending.text, event.remaining,
                              event.state, sender)

    # -- services ----------------------------------------------------------------------

    def switch_and_wait(self, module: str, word: str, timeout: float) -> "Switched":
        """Send ``word`` and wait, up to ``timeout`` s, for the state it leads to, or for a
        warning of the module's that names it."""
        link = self.links[module]
        word = word.strip().lower()
        with link.changed:
            warnings_before = len(link.warnings)
        sent = self.send_switch(module, word, sender="service")
        if not sent.ok:
            return Switched(False, link.lifecycle, sent.message)
        wanted = EXPECTED[word]
        deadline = time.monotonic() + timeout
        with link.changed:
            while True:
                if link.lifecycle == wanted:
                    return Switched(True, link.last_status.state)
                news = [w for w in link.warnings[warnings_before:] if word in w]
                if news:
                    return Switched(False, link.lifecycle, news[-1])
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    return Switched(False, link.lifecycle,
                                    f"no {wanted} state within {timeout:g} s")
                link.changed.wait(remaining)

    def send_request(self, module: str, request: Any) -> Sent:
        """A ``walkman_msgs/SendCommand`` request, numbered now and sent."""
        try:
            command = build_command(request, self.sequence.next(), command_decoder(module))
            command = replace(command,
                              lifetime=lifetime(module, getattr(request, "validity", 0.0)))
        except GatewayError as exc:
            return Sent(False, str(exc))
        return self.send_command(module, command, "service")

    def cancel(self, module: str, seq: int) -> Cancelled:
        """Take back the module's queued command ``seq`` (0: all of them) from the pilot
        bridge.  Only what no frame has carried can be taken back; a command already on its
        way is said so, never claimed cancelled."""
        if self.link_watch.state.state is LinkPhase.DIRECT:
            return Cancelled(False, [], "no bridge here (the lab): a command goes straight to "
                                        "its module and never waits, so there is nothing to "
                                        "cancel")
        try:
            cancelled, too_late = rpc_words.read_cancel_reply(
                self._ask_bridge(rpc_words.cancel_request(module, seq or None), timeout=5.0))
        except YarpError as exc:
            return Cancelled(False, [], f"cannot reach the pilot bridge ({BRIDGE_RPC}): {exc}")
        except BridgeUsageError as exc:
            return Cancelled(False, [], f"the pilot bridge refused: {exc}")
        except BridgeProtocolError as exc:
            return Cancelled(False, [], f"the pilot bridge's answer is malformed: {exc}")
        with self._ledger_lock:
            changed = [life for n in cancelled for life in self.ledger.receipt(
                module, Receipt(n, CommandState.CANCELLED, "cancelled by a pilot"))]
        self._publish_states(changed)
        parts = []
        if cancelled:
            parts.append("cancelled " + " ".join(map(str, cancelled)))
        if too_late:
            parts.append(f"{' '.join(map(str, too_late))} already on the way to the robot: "
                         f"not cancelled")
        if not parts:
            parts.append(f"no queued command {seq}" if seq else "nothing queued")
        message = "; ".join(parts)
        log.info("gateway: cancel %s %s: %s", module, seq or "all", message)
        return Cancelled(bool(cancelled) or not too_late and not seq, list(cancelled), message)

    def stop_all(self, word: str) -> Stopped:
        """``stop_all`` or ``release``: through the pilot bridge (its stop line), or in the
        lab by this gateway itself."""
        started = time.monotonic()
        if self.link_watch.state.state is LinkPhase.DIRECT:
            try:
                stopper = self._local_stop_all()
            except GatewayError as exc:
                return Stopped(False, str(exc))
            report = stopper.stop(self.sequence.next()) if word == "stop_all" \
                else stopper.release(self.sequence.next())
            took = (time.monotonic() - started) * 1000.0
            return Stopped(report.hal, report.line() if report.hal or word == "stop_all" else
                           f"release: {report.problem}", took, report.took_ms,
                           list(report.modules))
        try:
            ack = rpc_words.read_stop_reply(self._ask_bridge(Bottle([word]), timeout=8.0))
        except YarpError as exc:
            return Stopped(False, f"cannot reach the pilot bridge ({BRIDGE_RPC}): {exc}")
        except BridgeUsageError as exc:   # its words: "stop_all: the robot did not ..."
            return Stopped(False, str(exc) if str(exc).startswith(word) else f"{word}: {exc}")
        except BridgeProtocolError as exc:
            return Stopped(False, f"{word}: the pilot bridge's answer is malformed: {exc}")
        paused = list(ack.modules)
        message = (f"{word}: {'HAL held' if ack.hal else 'HAL NOT held'}; pause sent to "
                   f"{', '.join(paused) or 'no module'}" if word == "stop_all" else
                   f"release: HAL {'free' if ack.hal else 'NOT released'}")
        return Stopped(ack.hal, message, ack.round_trip_ms, ack.took_ms, paused)

    def _ask_bridge(self, request: Bottle, timeout: float) -> Bottle:
        """One request to the pilot bridge's RPC port (:mod:`bridge.rpc_words`)."""
        client = RpcClient(nameclient=self.nameclient)
        try:
            client.connect(BRIDGE_RPC)
            return client.call(request, timeout=timeout)
        finally:
            client.close()

    def _local_stop_all(self) -> Any:
        """The lab's stop-all executor (one network: this gateway reaches the HAL itself)."""
        if self._stopper is None:
            raise GatewayError("the gateway's YARP side is not open yet")
        return self._stopper

    def close(self) -> None:
        self._stop.set()
        self.keeper.stop()
        for link in self.links.values():
            link.close()
        if self._stopper is not None:
            self._stopper.close()
        for port in (self.sent_in, self.sent_out, self.bridge_in):
            if port is not None:
                port.close()
        if self.scene is not None:
            self.scene.close()
        if self.ros_node is not None:
            self.ros_node.stop()


def select_modules(config_path: Path, wanted: Optional[str]) -> Dict[str, List[str]]:
    config = bridge_config.load(config_path)
    gym = {name: module_statuses(name, statuses)
           for name, statuses in config.gym_modules.items()}
    if not wanted:
        return gym
    names = [n.strip() for n in wanted.split(",") if n.strip()]
    unknown = [n for n in names if n not in gym]
    if unknown:
        raise GatewayError(f"unknown module(s) {', '.join(unknown)}; {config_path} lists "
                           f"{', '.join(sorted(gym))}")
    return {n: gym[n] for n in names}


def main(argv: Optional[List[str]] = None) -> int:
    parser = argparse.ArgumentParser(prog="walkman-pilot-gateway",
                                     description="GYM modules as ROS topics and services.")
    parser.add_argument("--config", type=Path, default=DEFAULT_CONFIG,
                        help="bridge configuration listing the modules (default: %(default)s)")
    parser.add_argument("--modules", help="only these modules (comma separated)")
    parser.add_argument("--countdown", type=float, default=3.0,
                        help="seconds a dangerous command waits (default 3)")
    parser.add_argument("--name", default="", help="ROS node name (default: unique per PC)")
    parser.add_argument("--link", choices=["bridge", "direct"], default="bridge",
                        help="bridge: the robot is behind the pilot bridge, whose status says "
                             "whether the link is up (/bridge/link); direct: one network, no "
                             "bridge (the lab)")
    options = parser.parse_args(argv)
    configure_logging("gateway")
    try:
        modules = select_modules(options.config, options.modules)
    except (GatewayError, bridge_config.ConfigError) as exc:
        print(f"walkman-pilot-gateway: {exc}", file=sys.stderr)
        return 2
    if options.countdown <= 0:
        print("walkman-pilot-gateway: --countdown must be positive", file=sys.stderr)
        return 2
    from nodekit.msgs import ensure_importable

    ensure_importable()
    unique = options.name or f"pilot_gateway_{os.uname().nodename.replace('-', '_')}_{os.getpid()}"
    gateway = Gateway(modules, options.countdown, unique, direct=options.link == "direct")
    gateway.start_ros()        # its topics open once the YARP side is (either may come first)
    try:
        gateway.open_yarp()
    except (YarpError, StationError) as exc:
        print(f"walkman-pilot-gateway: {exc}", file=sys.stderr)
        return 1
    import signal

    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: gateway.finished.set())
    gateway.finished.wait()
    gateway.close()
    if gateway.error:
        print(f"walkman-pilot-gateway: {gateway.error}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
