"""The bridge configuration: the paper's XML, turned into the list of bridged channels.

Theory of operation
-------------------
The file lists modules by 8-bit id (0..255, unique across every section):

* ``<modules><module name="gaze_control" id="7"/>`` -- a standard GYM module
  on the robot: its ``switch`` and ``command`` go pilot->robot (reliable:
  never dropped, never duplicated, in order, sent at once), its ``status``
  (latest only, batched every period, but at once when it answers a pilot's
  command or its state changes: :class:`bridge.gym.status_events.StatusEvents`),
  ``warning`` and ``receipt`` (reliable) go robot->pilot
  (:data:`walkman.gym.interfaces.GYM_PORTS`, whose order gives each flow's kind);
* ``<custom_modules>`` -- explicit ``<connection port_to_open source_port
  target_port location direction>``, names relative to ``/<module>``: the
  source side opens ``port_to_open`` and ``source_port`` feeds it; the
  destination side opens ``source_port``'s name and feeds ``target_port``
  (which is how ports get renamed);
* ``<robot_state id robot/>`` -- the HAL's joint state, compressed as Table 1
  counts it (this project's addition);
* ``<ros_topics><topic name type id direction channel/>`` -- ROS topics, on
  the UDP channel only: "TCP-ROS is unsupported: ROS data would saturate the
  channel", as the paper says.

``<bridge key="bridge.key">`` names the key file both bridges share (relative
to the XML file; ``--key`` on the command line wins), see :mod:`bridge.wire.link`.

Every channel gets ``(id, kind)``: the module id and which of its flows it
is.  The file is checked against ``bridge.xsd`` and then for what a schema
cannot say; every error names the file, the line and the problem.

Any input, however malformed, gives a :class:`BridgeConfig` or a
:class:`ConfigError` (``file:line: problem``).  The XML parser resolves no
entities and loads no DTD or network resource; a file may be at most
:data:`MAX_CONFIG_BYTES`; numbers must be finite and in range (ids 0..255,
quality 0..100, fec 0..0.5 or ``auto``, period/gather/rate > 0).  ``fec="auto"``
sizes the repairs from the loss the receiver reports (:mod:`bridge.transport.adaptive_fec`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import StrEnum
from functools import lru_cache
from pathlib import Path
from typing import Callable, ClassVar, Dict, List, Optional, Tuple, TypeVar, Union

from lxml import etree

from bridge.flows import STATE_KIND, STOP_ACK_KIND, STOP_ORDER_KIND, Carriage, FlowKey, Form, Route
from walkman.gym.interfaces import GYM_PORTS, RECEIPT

SCHEMA_PATH = Path(__file__).with_name("bridge.xsd")


class Side(StrEnum):
    """A PC of the topology: where a flow's messages come from or go to."""

    ROBOT = "robot"
    PILOT = "pilot"


class Transport(StrEnum):
    """The bridge's channel a flow crosses on."""

    TCP = "tcp"
    UDP = "udp"


class Middleware(StrEnum):
    """What a flow is on either PC: YARP ports or a ROS topic."""

    YARP = "yarp"
    ROS = "ros"


ROBOT, PILOT = Side.ROBOT, Side.PILOT
DIRECTIONS = {"robot_to_pilot": (ROBOT, PILOT), "pilot_to_robot": (PILOT, ROBOT)}
CHANNELS = tuple(Transport)
DEFAULT_PERIOD = 0.5
DEFAULT_GATHER = 0.4
DEFAULT_STATE_RATE = 10.0
#: Largest configuration file read (the DRC's is 5 kB).
MAX_CONFIG_BYTES = 1 << 20



class ConfigError(Exception):
    """The configuration is invalid; the message is ``file:line: problem``."""


@dataclass(frozen=True)
class Flow:
    """What every bridged flow of messages has, YARP or ROS (:data:`Channel`)."""

    id: int                      # 8-bit module id
    kind: int                    # which flow of that module
    label: str                   # "gaze_control/status"
    source: Side                 # where messages come from
    destination: Side
    transport: Transport
    reliable: bool               # never dropped, in order, sent at once
    fec: float = 0.0             # the share of repair datagrams (UDP)
    fec_auto: bool = False       # repairs sized from the measured loss (fec unused)
    line: int = 0                # of the XML, for messages

    @property
    def key(self) -> FlowKey:
        return FlowKey(self.id, self.kind)

    def _datagrams(self, form: Form) -> Route:
        return Route(self.key, self.label, Carriage.DATAGRAMS, form, fec=self.fec,
                     fec_auto=self.fec_auto)


@dataclass(frozen=True)
class YarpChannel(Flow):
    """A flow between YARP ports: a GYM module's port or a custom connection.

    On the source side ``listen_port`` is opened and ``feed_port`` connected to it; on the
    destination side ``emit_port`` is opened and connected to ``deliver_port`` (or, when
    None, left for local programs to connect to, as they would to the original)."""

    middleware: ClassVar[Middleware] = Middleware.YARP
    listen_port: str = ""
    feed_port: str = ""
    emit_port: str = ""
    deliver_port: Optional[str] = None
    statuses: Tuple[str, ...] = ()     # a GYM module's states, beyond the GYM's own
    #: a GYM status: a change of its ``seq state`` head is an event that leaves at once
    status_events: bool = False
    #: a GYM switch or command: its messages carry a validity (:mod:`walkman.gym.validity`)
    expiring: bool = False
    #: a GYM module's receipts: what became of each command (:mod:`walkman.gym.command_life`)
    receipts: bool = False

    @property
    def module(self) -> str:
        """The module of the configuration this flow belongs to (its label's head)."""
        return self.label.split("/")[0]

    def opened_on(self, side: str) -> str:
        """The YARP port the bridge opens for this flow on ``side``."""
        return self.listen_port if side == self.source else self.emit_port

    def route(self, copies: "Optional[DatagramCopies]" = None) -> Route:
        """How this flow crosses (``copies``: the configuration's ``<datagram_copies>``)."""
        if self.transport is Transport.UDP:
            return self._datagrams(Form.BOTTLE)
        copied = 0
        if copies is not None:
            copied = copies.statuses if self.status_events else \
                copies.commands if self.reliable and (self.expiring or self.receipts) \
                else 0
        return Route(self.key, self.label,
                     Carriage.RELIABLE if self.reliable else Carriage.LATEST, Form.BOTTLE,
                     status_events=self.status_events, expiring=self.expiring,
                     copies=copied)


@dataclass(frozen=True)
class RosChannel(Flow):
    """A ROS topic, over the UDP channel only (the paper: "TCP-ROS is unsupported")."""

    middleware: ClassVar[Middleware] = Middleware.ROS
    ros_type: str = ""                 # package/Type
    latch: bool = False
    quality: int = 80                  # JPEG quality of an image's tiles

    @property
    def module(self) -> str:
        """A topic is its own module."""
        return self.label

    def route(self, copies: "Optional[DatagramCopies]" = None) -> Route:
        """How this flow crosses: as datagrams, always."""
        return self._datagrams(Form.ROS)


#: One bridged flow: a tagged union on ``middleware``.
Channel = Union[YarpChannel, RosChannel]


@dataclass(frozen=True)
class RobotStateFlow:
    """``<robot_state>``: the HAL's joint state, under its own id."""

    id: int
    robot: str                   # the robot's port prefix (``walkman``)
    transport: Transport

    @property
    def key(self) -> FlowKey:
        return FlowKey(self.id, STATE_KIND)


@dataclass(frozen=True)
class EmergencyStopFlow:
    """``<emergency_stop>``: the pilot's stop-all and the robot's acknowledgement, under one
    id; each goes at once on the TCP channel and as ``copies`` datagrams on the UDP one."""

    id: int
    robot: str = "walkman"       # whose HAL it holds
    copies: int = 3

    @property
    def stop_key(self) -> FlowKey:
        return FlowKey(self.id, STOP_ORDER_KIND)

    @property
    def ack_key(self) -> FlowKey:
        return FlowKey(self.id, STOP_ACK_KIND)


@dataclass(frozen=True)
class DatagramCopies:
    """``<datagram_copies>``: how many datagram copies of each pilot command (and its
    receipt) and of each status event also cross on the UDP channel, beside the TCP
    channel's one (:mod:`bridge.transport.copies`); 0: none."""

    commands: int = 0
    statuses: int = 0


@dataclass
class BridgeConfig:
    path: str
    period: float = DEFAULT_PERIOD
    gather: float = DEFAULT_GATHER
    channels: List[Channel] = field(default_factory=list)
    modules: Dict[str, int] = field(default_factory=dict)
    gym_modules: Dict[str, Tuple[str, ...]] = field(default_factory=dict)  # name -> states
    robot_state: Optional[RobotStateFlow] = None
    emergency_stop: Optional[EmergencyStopFlow] = None
    datagram_copies: DatagramCopies = DatagramCopies()
    state_rate: float = DEFAULT_STATE_RATE                 # Hz the robot state is sampled
    key_file: Optional[Path] = None      # the shared key, if the file names one
    _index: Dict[FlowKey, Channel] = field(default_factory=dict, repr=False, compare=False)

    def sending(self, side: str) -> List[Channel]:
        return [c for c in self.channels if c.source == side]

    def receiving(self, side: str) -> List[Channel]:
        return [c for c in self.channels if c.destination == side]

    def channel(self, key: FlowKey) -> Optional[Channel]:
        return self._by_key().get(key)

    def routes(self) -> Dict[FlowKey, Route]:
        """Every flow with its route, the robot state's and the stop-all's included: how
        each crosses the link is decided here, once; the channels and the node look it up."""
        table = {channel.key: channel.route(self.datagram_copies) for channel in self.channels}
        state = self.robot_state
        if state is not None:
            table[state.key] = Route(state.key, f"{state.robot}/state",
                                     Carriage.LATEST if state.transport == "tcp"
                                     else Carriage.DATAGRAMS, Form.STATE)
        stop = self.emergency_stop
        if stop is not None:
            table[stop.stop_key] = Route(stop.stop_key, "stop_all", Carriage.URGENT, Form.BOTTLE)
            table[stop.ack_key] = Route(stop.ack_key, "stop_all/ack", Carriage.URGENT,
                                        Form.BOTTLE)
        return table

    def id_names(self) -> Dict[int, str]:
        """What each 8-bit id carries, as a pilot reads it (a module, a topic, the robot's
        state, the stop-all)."""
        names = {ident: module for module, ident in self.modules.items()}
        names.update({c.id: c.label for c in self.channels if c.middleware == "ros"})
        if self.robot_state is not None:
            names[self.robot_state.id] = f"{self.robot_state.robot} state"
        if self.emergency_stop is not None:
            names[self.emergency_stop.id] = "stop all"
        return names

    def _by_key(self) -> Dict[FlowKey, Channel]:
        # Built when first needed; parse() appends channels, nothing removes them.
        if len(self._index) != len(self.channels):
            self._index = {channel.key: channel for channel in self.channels}
        return self._index


@lru_cache(maxsize=1)
def _schema() -> etree.XMLSchema:
    """The schema, parsed once (it is fixed; parsing it cost more than a config)."""
    return etree.XMLSchema(etree.parse(str(SCHEMA_PATH)))


def _read_tree(data: bytes, where: str) -> etree._Element:
    """Parse, accepting the paper's two top-level elements (wrapped in <bridge>)."""
    parser = etree.XMLParser(remove_comments=True, remove_pis=True, resolve_entities=False,
                             load_dtd=False, no_network=True, huge_tree=False)
    try:
        root = etree.fromstring(data, parser)
        if root.tag == "bridge":
            return root
    except etree.XMLSyntaxError as exc:
        if "Extra content at the end of the document" not in str(exc) and \
                "junk after document element" not in str(exc):
            raise ConfigError(f"{where}:{exc.lineno}: malformed XML: {exc.msg}") from None
    body = data.split(b"?>", 1)[1] if data.lstrip().startswith(b"<?xml") else data
    offset = data.count(b"\n", 0, len(data) - len(body))
    try:
        root = etree.fromstring(b"\n" * offset + b"<bridge>" + body + b"</bridge>", parser)
    except etree.XMLSyntaxError as exc:
        raise ConfigError(f"{where}:{exc.lineno}: malformed XML: {exc.msg}") from None
    return root


def load(path: Path) -> BridgeConfig:
    path = Path(path)
    try:
        with path.open("rb") as file:
            data = file.read(MAX_CONFIG_BYTES + 1)
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read: {exc.strerror}") from None
    return parse(data, str(path))


def parse(text: Union[str, bytes], where: str = "<bridge config>") -> BridgeConfig:
    """The configuration in ``text`` (a file's bytes, or its text)."""
    if isinstance(text, str):
        try:
            text = text.encode("utf-8")
        except UnicodeEncodeError as exc:
            line = text.count("\n", 0, exc.start) + 1
            raise ConfigError(f"{where}:{line}: not text: {exc.reason}") from None
    if len(text) > MAX_CONFIG_BYTES:
        raise ConfigError(f"{where}:1: larger than {MAX_CONFIG_BYTES} bytes")
    root = _read_tree(text, where)
    schema = _schema()
    if not schema.validate(root):
        error = schema.error_log.last_error
        raise ConfigError(f"{where}:{error.line}: {error.message}" if error is not None else
                          f"{where}:{root.sourceline}: invalid configuration")
    config = BridgeConfig(path=where,
                          period=_positive(root, "period", DEFAULT_PERIOD, where),
                          gather=_positive(root, "gather", DEFAULT_GATHER, where))
    key = root.get("key")
    if key is not None:
        if not key.strip():
            raise ConfigError(f"{where}:{root.sourceline}: key names no file")
        config.key_file = (Path(where).parent / Path(key).expanduser()) \
            if not Path(key).expanduser().is_absolute() else Path(key).expanduser()
    sections = _Sections(config, where)
    sections.gym_modules(root)
    sections.custom_modules(root)
    sections.robot_state(root)
    sections.emergency_stop(root)
    sections.datagram_copies(root)
    sections.ros_topics(root)
    return config


class _Sections:
    """Reads the sections of one configuration into ``config``: ids are shared by every
    section and each port is claimed once per side, so the checks live here."""

    def __init__(self, config: BridgeConfig, where: str) -> None:
        self.config, self.where = config, where
        self.ids: Dict[int, int] = {}                      # id -> the line that took it
        self.claimed: Dict[Tuple[str, str], int] = {}      # (side, port) -> line

    def take_id(self, element: etree._Element) -> int:
        value = _number(element, "id", 0, self.where, int)
        line = element.sourceline
        if not 0 <= value <= 255:
            raise ConfigError(f"{self.where}:{line}: id {value} does not fit in 8 bits (0..255)")
        if value in self.ids:
            raise ConfigError(f"{self.where}:{line}: duplicate id {value} (first used on line "
                              f"{self.ids[value]}); ids are shared by every section")
        self.ids[value] = line
        return value

    def claim(self, side: str, port: str, line: int) -> None:
        if (side, port) in self.claimed:
            raise ConfigError(f"{self.where}:{line}: port {port} on the {side} side is claimed "
                              f"twice (also on line {self.claimed[side, port]})")
        self.claimed[side, port] = line

    def gym_modules(self, root: etree._Element) -> None:
        """GYM modules: one flow per GYM port (switch, command, status, warning, ...)."""
        config, where = self.config, self.where
        for element in root.iterfind("modules/module"):
            name, module_id = element.get("name"), self.take_id(element)
            _check_name(name, element, where)
            config.modules[name] = module_id
            statuses = tuple((element.get("statuses") or "").split())
            config.gym_modules[name] = statuses
            for kind, gym_port in enumerate(GYM_PORTS):   # the kind byte on the wire
                flow, reliable = gym_port.flow, gym_port.reliable
                direction = "pilot_to_robot" if gym_port.to_robot else "robot_to_pilot"
                source, destination = DIRECTIONS[direction]
                original = gym_port.of(name)
                bridge_port = f"/bridge/{source}/{name}/{flow}"
                if direction == "pilot_to_robot":
                    listen, feed, emit, deliver = original, "", bridge_port, original
                else:
                    listen, feed, emit, deliver = bridge_port, original, original, None
                self.claim(source, listen, element.sourceline)
                self.claim(destination, emit, element.sourceline)
                config.channels.append(YarpChannel(
                    id=module_id, kind=kind, label=f"{name}/{flow}", source=source,
                    destination=destination, transport=Transport.TCP, reliable=reliable,
                    listen_port=listen, feed_port=feed, emit_port=emit, deliver_port=deliver,
                    statuses=statuses, line=element.sourceline,
                    status_events=flow == "status", expiring=direction == "pilot_to_robot",
                    receipts=gym_port is RECEIPT))

    def custom_modules(self, root: etree._Element) -> None:
        """Custom modules: up to eight connections each, as the paper's XML."""
        config, where = self.config, self.where
        for element in root.iterfind("custom_modules/module"):
            name, module_id = element.get("name"), self.take_id(element)
            _check_name(name, element, where)
            config.modules[name] = module_id
            for kind, connection in enumerate(element.iterfind("connection")):
                line = connection.sourceline
                if kind > 7:
                    raise ConfigError(f"{where}:{line}: module {name} has more than 8 connections "
                                      f"(the kind field has 3 bits); split it into two modules")
                direction = connection.get("direction")
                if direction not in DIRECTIONS:
                    raise ConfigError(f"{where}:{line}: unknown direction {direction!r} "
                                      f"(robot_to_pilot or pilot_to_robot)")
                source, destination = DIRECTIONS[direction]
                location = connection.get("location")
                if location not in (ROBOT, PILOT):
                    raise ConfigError(f"{where}:{line}: unknown location {location!r} "
                                      f"(robot or pilot)")
                if location != source:
                    raise ConfigError(f"{where}:{line}: location {location} contradicts direction "
                                      f"{direction}: data starts on the {source} side")
                transport = connection.get("channel", "tcp")
                if transport not in CHANNELS:
                    raise ConfigError(f"{where}:{line}: unknown channel {transport!r} (tcp or udp)")
                names = {attr: _relative(name, connection.get(attr), line, where)
                         for attr in ("port_to_open", "source_port", "target_port")}
                # Pilot commands are kept intact unless said otherwise; robot data streams.
                default = "false" if direction == "pilot_to_robot" else "true"
                streaming = connection.get("streaming", default) in ("true", "1")
                self.claim(source, names["port_to_open"], line)
                self.claim(destination, names["source_port"], line)
                config.channels.append(YarpChannel(
                    id=module_id, kind=kind, label=f"{name}{connection.get('port_to_open')}",
                    source=source, destination=destination, transport=Transport(transport),
                    reliable=not streaming, listen_port=names["port_to_open"],
                    feed_port=names["source_port"], emit_port=names["source_port"],
                    deliver_port=names["target_port"], line=line))

    def robot_state(self, root: etree._Element) -> None:
        """The robot state flow (Table 1 codec)."""
        config, where = self.config, self.where
        for element in root.iterfind("robot_state"):
            state_id = self.take_id(element)
            transport = element.get("channel", "tcp")
            if transport not in CHANNELS:
                raise ConfigError(f"{where}:{element.sourceline}: unknown channel {transport!r}")
            config.robot_state = RobotStateFlow(state_id, element.get("robot"),
                                                Transport(transport))
            config.state_rate = _positive(element, "rate", DEFAULT_STATE_RATE, where)

    def emergency_stop(self, root: etree._Element) -> None:
        """The stop-all line."""
        config, where = self.config, self.where
        for element in root.iterfind("emergency_stop"):
            copies = _number(element, "copies", 3, where, int)
            if not 1 <= copies <= 10:
                raise ConfigError(f"{where}:{element.sourceline}: copies is 1..10 datagrams, got "
                                  f"{copies}")
            config.emergency_stop = EmergencyStopFlow(self.take_id(element),
                                                      element.get("robot", "walkman"), copies)

    def datagram_copies(self, root: etree._Element) -> None:
        """How many datagram copies commands and statuses get."""
        config, where = self.config, self.where
        for element in root.iterfind("datagram_copies"):
            counts = {}
            for attribute in ("commands", "statuses"):
                counts[attribute] = _number(element, attribute, 0, where, int)
                if not 0 <= counts[attribute] <= 5:
                    raise ConfigError(f"{where}:{element.sourceline}: {attribute} is 0..5 datagram "
                                      f"copies, got {counts[attribute]}")
            config.datagram_copies = DatagramCopies(**counts)

    def ros_topics(self, root: etree._Element) -> None:
        """ROS topics: over UDP only."""
        config, where = self.config, self.where
        for element in root.iterfind("ros_topics/topic"):
            line = element.sourceline
            topic_id = self.take_id(element)
            direction = element.get("direction")
            if direction not in DIRECTIONS:
                raise ConfigError(f"{where}:{line}: unknown direction {direction!r} "
                                  f"(robot_to_pilot or pilot_to_robot)")
            transport = element.get("channel")
            if transport == "tcp":
                raise ConfigError(f"{where}:{line}: TCP-ROS is unsupported: ROS data would "
                                  f"saturate the channel (use channel=\"udp\")")
            if transport not in CHANNELS:
                raise ConfigError(f"{where}:{line}: unknown channel {transport!r} (udp for ROS)")
            topic, ros_type = element.get("name"), element.get("type")
            if not topic.startswith("/") or "/" not in ros_type:
                raise ConfigError(f"{where}:{line}: topic needs an absolute name and a "
                                  f"package/Type, got {topic!r} {ros_type!r}")
            source, destination = DIRECTIONS[direction]
            self.claim(source, "ros:" + topic, line)
            self.claim(destination, "ros:" + topic + ":publish", line)
            fec_auto = element.get("fec") == "auto"
            fec = 0.0 if fec_auto else _number(element, "fec", 0.0, where)
            if not 0 <= fec <= 0.5:
                raise ConfigError(f"{where}:{line}: fec is a repair fraction 0..0.5 or auto, "
                                  f"got {fec}")
            quality = _number(element, "quality", 80, where, int)
            if not 0 <= quality <= 100:
                raise ConfigError(f"{where}:{line}: quality is a JPEG quality 0..100, "
                                  f"got {quality}")
            config.channels.append(RosChannel(
                id=topic_id, kind=0, label=topic, source=source, destination=destination,
                transport=Transport.UDP, reliable=False, ros_type=ros_type,
                latch=element.get("latch", "false") in ("true", "1"),
                quality=quality, fec=fec, fec_auto=fec_auto, line=line))


Number = TypeVar("Number", int, float)


def _number(element: etree._Element, attribute: str, default: Number, where: str,
            convert: Callable[[str], Number] = float) -> Number:
    """A numeric attribute the schema let through, made sure to be a finite number."""
    text = element.get(attribute)
    if text is None:
        return default
    try:
        value = convert(text)
    except ValueError:  # e.g. an integer of more digits than Python converts
        raise ConfigError(f"{where}:{element.sourceline}: {attribute} {text[:40]!r} is not "
                          f"a usable number") from None
    if not math.isfinite(value):
        raise ConfigError(f"{where}:{element.sourceline}: {attribute} {text[:40]!r} is not "
                          f"finite")
    return value


def _positive(root: etree._Element, attribute: str, default: float, where: str) -> float:
    value = _number(root, attribute, default, where)
    if value <= 0:
        raise ConfigError(f"{where}:{root.sourceline}: {attribute} must be positive, got {value}")
    return value


def _check_name(name: str, element: etree._Element, where: str) -> None:
    if not name or "/" in name or " " in name:
        raise ConfigError(f"{where}:{element.sourceline}: module name {name!r} must be one word "
                          f"without '/' or spaces")


def _relative(module: str, port: Optional[str], line: int, where: str) -> str:
    if not port or not port.startswith("/") or port.endswith("/") or " " in port:
        raise ConfigError(f"{where}:{line}: port {port!r} must look like /name (relative to "
                          f"/{module})")
    return f"/{module}{port}"
