"""The whole-body interface: the robot as one kinematic chain, in SI units.

Upper tier of the HAL (the paper's *WholeBodyInterface*): modules call
``sense_position()`` and ``move(q)`` on 33-element vectors in the model's
joint order and never see how the robot groups joints into chains, nor YARP.

Theory of operation
-------------------
Any YARP robot will do: each chain is a YARP control board
(:mod:`walkman.hal.controlboard`), the client of ``remote_controlboard``
written on yarp_lite.  The grouping is found at connection time:

* a Walk-Man HAL (or the bridge's copy of it) answers ``[get] chains`` on
  ``/<robot>/rpc:i`` with every chain and its joints, and streams the compact
  SI state ``stateSI:o`` (with the HAL's temperatures and a state count), so
  that is what we read;
* any other YARP robot is found chain by chain (:mod:`walkman.hal.discovery`:
  ``/<robot>/<chain>/rpc:i`` for the model's chains, ``[get] [axes]``, ``[get] [name] j``);
  its state is the standard ``stateExt:o`` (``jointData``, degrees) and its
  motor temperatures are asked with ``[get] [tmps]`` once a second.

Commands are YARP's streaming position-direct commands (``[dpos]``,
``[dpog]`` on ``command:i``); the joints a module commands are switched to
position-direct mode (``[set] [icmd] [cmog]``) the first time, and again
after the robot was away.  The head of each command also carries ``(seq N)``,
the state count it answers, which the HAL uses to measure sense->move
latency and any other robot ignores.

Connections are persistent (made by the name server), so a module can start
before the robot, and survives the robot restarting.  ``move`` refuses what
would be unsafe -- wrong length, NaN -- with :class:`HalUsageError`, clamps
references to the joint limits and reports it, and sends nothing when the
robot is not there.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import Dict, List, Optional, Sequence, Set, Tuple

import numpy as np

from walkman.hal import controlboard, protocol
from walkman.hal.clock import RobotClock
from walkman.hal.controlboard import ControlBoardError
from walkman.hal.discovery import find_grouping
from walkman.hal.rounds import RoundPeriod
from walkman.hal.protocol import HalProtocolError, HalUsageError
from walkman.model.description import walkman
from walkman.model.description import Robot as RobotModel
from walkman.realtime import BACKGROUND_PRIORITY, PATH_PRIORITY, keep_priority
from yarp_lite import network
from yarp_lite.bottle import Bottle, Vocab
from yarp_lite.buffered_port import BufferedPort
from yarp_lite.bursts import Burst
from yarp_lite.carriers import with_send_period
from yarp_lite.errors import NetworkError, YarpError
from yarp_lite.nameclient import NameClient
from yarp_lite.port import Port

log = logging.getLogger("walkman.robot")

#: State older than this means the HAL is gone.
STALE_AFTER = 0.5
#: How far the robot's clock runs on past the newest state at least (s): a few HAL periods.
MIN_CLOCK_AHEAD = 0.01
#: s between the states and sensor readings a module takes while it does not control the
#: robot (:meth:`Robot.read_idle`): the newest each time.
IDLE_READ_INTERVAL = 0.02


def check_reference(q: Sequence[float], names: Sequence[str], lower: np.ndarray,
                    upper: np.ndarray) -> np.ndarray:
    """A whole-body reference, validated (HalUsageError) and clamped to the limits."""
    values = np.asarray(q, dtype=float)
    if values.shape != (len(names),):
        raise HalUsageError(f"move needs {len(names)} joint positions, "
                            f"got {values.shape[0] if values.ndim else 'a scalar'}")
    if not np.all(np.isfinite(values)):
        bad = [names[i] for i in np.flatnonzero(~np.isfinite(values))]
        raise HalUsageError(f"move refused: non-finite reference for {', '.join(bad)}")
    return np.clip(values, lower, upper)


class WholeBody(ABC):
    """What a GYM module sees of the robot, in the model's joint order and SI units.

    :class:`Robot` (over YARP, any robot) and
    :class:`walkman.gym.offline.SimulatedRobot` (straight on a simulator) both
    implement it, so every module runs in either without knowing which.
    """

    joint_names: List[str]
    index: Dict[str, int]
    lower: np.ndarray
    upper: np.ndarray

    @property
    @abstractmethod
    def connected(self) -> bool:
        """True while the robot's state is fresh."""

    @property
    def state_age(self) -> float:
        return 0.0 if self.connected else math.inf

    def read_idle(self, idle: bool) -> None:
        """Told by the module's runner whether the module controls the robot now; a robot
        read over the network reads slowly while it does not (:meth:`Robot.read_idle`), one
        read straight from a simulator has nothing to slow."""

    @abstractmethod
    def sense_position(self) -> np.ndarray: ...

    @abstractmethod
    def sense_velocity(self) -> np.ndarray: ...

    @abstractmethod
    def sense_torque(self) -> np.ndarray: ...

    @abstractmethod
    def sense_temperature(self) -> np.ndarray:
        """Motor (board) temperatures, deg C."""

    @abstractmethod
    def sense_ft(self, sensor: str) -> np.ndarray: ...

    @abstractmethod
    def sense_imu(self) -> Optional[Tuple[List[float], List[float], List[float]]]: ...

    @abstractmethod
    def move(self, q: Sequence[float], mode: str = "pos",
             joints: Optional[Sequence[str]] = None) -> bool:
        """Stream a whole-body position reference (rad); False when the robot is away."""

    def hold(self) -> bool:
        """Keep the current position (the safe answer to anything unexpected)."""
        if not self.connected:
            return False
        return self.move(np.clip(self.sense_position(), self.lower, self.upper))

    @abstractmethod
    def take_hal_warnings(self) -> List[str]:
        """What the robot refused or overrode of our commands since last asked."""

    def wait_until_ready(self, timeout: float = 10.0) -> bool:
        return True

    #: When the newest state round (every chain's state of one robot step) arrived
    #: (``time.monotonic``); 0: none yet.
    newest_round: float = 0.0

    @property
    def round_period(self) -> float:
        """Seconds between state rounds; 0: not known, and a module's loop then runs on the
        wall clock (:mod:`walkman.gym.pacing`)."""
        return 0.0

    def wait_round(self, after: float, timeout: float) -> Optional[float]:
        """When a round newer than ``after`` arrived (the newest); None if none in ``timeout``."""
        return None

    def close(self) -> None:
        """Release ports and connections."""


@dataclass
class _ChainLink:
    """One chain of the robot as this client sees it (guarded by ``Robot._lock``)."""

    name: str
    indices: List[int]
    command: Port
    rpc: str                                       # the chain's rpc:i port name
    wanted: Set[int] = field(default_factory=set)  # joints we command (position direct)
    direct: Set[int] = field(default_factory=set)  # ... that the robot has switched
    seen_at: float = 0.0                           # when its state last arrived
    seq: int = 0                                   # and its count
    reported: bool = False


class Robot(WholeBody):
    """Whole-body access to a robot, for one module (``owner`` prefixes its ports)."""

    def __init__(self, owner: str, robot: str = "walkman", model: Optional[RobotModel] = None,
                 nameclient: Optional[NameClient] = None, connect_timeout: float = 30.0,
                 carrier: str = "fast_tcp", state_interval: float = 0.0,
                 realtime_readers: bool = False, sensors: bool = True,
                 lockstep: bool = False) -> None:
        self.owner = owner.rstrip("/")
        #: In lockstep with the robot's clock (:mod:`walkman.gym.lockstep`): joints are switched
        #: to position direct inside ``move``, before the command, so the first tick's command
        #: is never refused for a mode on its way (a race the physics would remember).
        self.lockstep = lockstep
        #: False: the force/torque sensors and the IMU are not read (a client that shows only
        #: joints, such as ``walkman-joint-state``, spares three 100-Hz streams).
        self.sensors = sensors
        #: The threads reading the robot's state take a real-time priority (a GYM module's
        #: runner asks for it: :mod:`walkman.realtime`).
        self.realtime_readers = realtime_readers
        self._idle = False      # read_idle: the readers' priority too
        #: Read each chain's state at most this often (the newest; see :func:`walkman.hal.protocol.state_interval`).
        self.state_interval = state_interval
        #: The robot's time, for a module's trajectories (:mod:`walkman.hal.clock`).
        self.clock = RobotClock(max_ahead=max(2 * state_interval, MIN_CLOCK_AHEAD),
                                silence=STALE_AFTER)
        self.robot = robot
        self.model = model or walkman()
        self.nameclient = nameclient or NameClient()
        self.carrier = carrier
        self.joint_names: List[str] = self.model.joint_names
        self.index = {name: i for i, name in enumerate(self.joint_names)}
        count = len(self.joint_names)
        self.lower = np.array([self.model.joint(n).lower for n in self.joint_names])
        self.upper = np.array([self.model.joint(n).upper for n in self.joint_names])
        self._q = np.zeros(count)
        self._qdot = np.zeros(count)
        self._tau = np.zeros(count)
        self._temperature = np.zeros(count)
        self._seen = np.zeros(count, dtype=bool)
        self._updated = 0.0
        self._lock = threading.Lock()
        self._round = threading.Condition(self._lock)  # a round arrived (see wait_round)
        self._rounds = RoundPeriod(STALE_AFTER)
        self._bad_whole = Burst()
        self._ft: Dict[str, np.ndarray] = {}
        self._imu: Optional[Tuple[List[float], List[float], List[float]]] = None
        #: the robot time each sensor's newest reading is stamped with (our HAL on a clock)
        self._sensor_times: Dict[str, float] = {}
        self._round_time = -math.inf    # the robot time of the newest round (our HAL's)
        self._commanded: List[str] = []   # chains written to since take_commanded, once a write
        self.chains: Dict[str, List[int]] = {}
        self._state_readers: List[BufferedPort] = []    # their intervals: read_idle
        self._sensor_readers: List[BufferedPort] = []
        self._links: Dict[str, _ChainLink] = {}
        self._ports: List[Port] = []
        self._subs: List[Tuple[str, str]] = []
        self.standard = False  # True: a plain YARP robot (no stateSI:o, no [get] chains)
        self.clamped = 0
        self.last_seq = 0
        self._hal_warnings: List[str] = []
        self._stop = threading.Event()
        self._mode_wanted = threading.Event()  # wakes the mode keeper
        self._connect(connect_timeout)
        threading.Thread(target=self._keep_modes, daemon=True,
                         name=f"{self.owner} control modes").start()

    # -- connecting ----------------------------------------------------------------------

    def _connect(self, timeout: float) -> None:
        found = find_grouping(self.nameclient, self.robot, self.model, self.owner, timeout)
        self.standard, grouping = found.standard, found.chains
        for chain, joints in grouping.items():
            unknown = [j for j in joints if j not in self.index]
            if unknown:
                raise HalProtocolError(f"robot chain {chain} has joints this model lacks: "
                                       f"{unknown}")
            self.chains[chain] = [self.index[j] for j in joints]
        missing = set(self.joint_names) - {j for joints in grouping.values() for j in joints}
        if missing and not self.standard:
            raise HalProtocolError(f"the HAL does not expose joints {sorted(missing)}")
        if missing:
            log.info("%s: this robot has no %s; those joints stay unseen", self.owner,
                     ", ".join(sorted(missing)))
            self._seen[[self.index[j] for j in missing]] = True
        # One reader for the whole robot where the HAL streams it (one wake-up per robot step:
        # eight chain readers spread one step's state over 0.4 ms, 1.4 ms at p99), else a
        # reader per chain.
        whole = None if self.standard else protocol.whole_state_port_name(self.robot)
        if whole is not None and self.nameclient.query(whole) is None:
            whole = None
        for chain, indices in self.chains.items():
            names = protocol.port_names(self.robot, chain)
            command = Port(nameclient=self.nameclient)
            command.open(f"{self.owner}/robot/{chain}/command:o")
            self._ports.append(command)
            self._links[chain] = _ChainLink(chain, indices, command, names["rpc"])
            self._persist(command.name, names["command"])
            if whole is None:  # after the link: the first state may come at once
                reader = self._on_state_ext if self.standard else self._on_state_si
                state = BufferedPort(nameclient=self.nameclient, min_interval=self.state_interval)
                state.on_read = lambda b, chain=chain, idx=indices, port=state: reader(
                    chain, idx, b, port.envelope)
                state.open(f"{self.owner}/robot/{chain}/state:i")
                self._ports.append(state)
                self._state_readers.append(state)
                self._persist(names["state_ext" if self.standard else "state_si"], state.name,
                              stream=True)
        #: A whole-robot state lists the chains' joints one chain after the other (the
        #: grouping's order): their indices and names, worked out once, not for every state.
        self._whole_links = list(self._links.values())
        self._whole_indices = [i for link in self._whole_links for i in link.indices]
        self._whole_joints = [self.joint_names[i] for i in self._whole_indices]
        log.info("%s: reading the robot's state %s", self.owner,
                 f"whole from {whole}" if whole else f"chain by chain ({len(self.chains)})")
        if whole is not None:  # after the links: its first state may come at once
            state = BufferedPort(nameclient=self.nameclient, min_interval=self.state_interval,
                                 on_read=self._on_whole_state_si)
            state.open(f"{self.owner}/robot/state:i")
            self._ports.append(state)
            self._state_readers.append(state)
            self._persist(whole, state.name, stream=True)
        if self.sensors:
            self._read_sensors()
        if self.standard:
            threading.Thread(target=self._poll_temperatures, daemon=True,
                             name=f"{self.owner} temperatures").start()
            return
        warnings = BufferedPort(nameclient=self.nameclient, strict=True,
                                on_read=self._on_hal_warning)
        warnings.open(f"{self.owner}/robot/warning:i")
        self._ports.append(warnings)
        self._persist(protocol.hal_warning_port_name(self.robot), warnings.name)

    def _read_sensors(self) -> None:
        for sensor in (s.name for s in self.model.sensors if s.kind == "ft"):
            port = BufferedPort(nameclient=self.nameclient,
                                on_read=None)
            port.on_read = lambda b, sensor=sensor, port=port: self._on_ft(sensor, b, port.envelope)
            port.open(f"{self.owner}/robot/{sensor}:i")
            self._ports.append(port)
            self._sensor_readers.append(port)
            self._persist(protocol.ft_port_name(self.robot, sensor), port.name, stream=True)
        imu = BufferedPort(nameclient=self.nameclient)
        imu.on_read = lambda b: self._on_imu(b, imu.envelope)
        imu.open(f"{self.owner}/robot/inertial:i")
        self._ports.append(imu)
        self._sensor_readers.append(imu)
        self._persist(protocol.imu_port_name(self.robot), imu.name, stream=True)

    def _persist(self, source: str, target: str, stream: bool = False) -> None:
        """Ask the name server to keep this connection up (robot restarts included).
        ``stream``: our HAL's state or a sensor, asked for at :attr:`state_interval` only
        (``+period``, :func:`yarp_lite.carriers.send_period`), so the HAL does not send what
        this reader would drop unread; a plain YARP robot's streams come whole."""
        carrier = self.carrier
        if stream and not self.standard:
            carrier = with_send_period(carrier, self.state_interval)
        if not self.nameclient.subscribe(source, f"{carrier}:/{target}"):
            raise NetworkError(f"name server refused the connection {source} -> {target}")
        self._subs.append((source, f"{carrier}:/{target}"))

    def wait_until_ready(self, timeout: float = 10.0) -> bool:
        """Block until every joint has been seen at least once."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            with self._lock:
                if self._seen.all():
                    return True
            time.sleep(0.01)
        return False

    def close(self) -> None:
        self._stop.set()
        for source, target in self._subs:
            try:
                self.nameclient.unsubscribe(source, target)
            except YarpError as exc:
                log.warning("%s: cannot unsubscribe %s -> %s (%s); the name server "
                            "keeps it", self.owner, source, target, exc)
        for port in self._ports:
            port.close()

    # -- incoming state --------------------------------------------------------------------

    def read_idle(self, idle: bool) -> None:
        """Read the state and sensors every :data:`IDLE_READ_INTERVAL` (the newest each
        time) while ``idle``, else at :attr:`state_interval` and every sensor reading.

        A module that is not started, is stopped, or paused without balancing needs only to
        know the robot is there and where it stands: eight such modules, each decoding 500-Hz
        states and three 100-Hz sensors, took a third of a core and a sixth of the HAL's.
        Back in control it reads at its own rate after at most one idle interval."""
        self._idle = idle
        for port in self._state_readers:
            port.min_interval = max(self.state_interval, IDLE_READ_INTERVAL) if idle \
                else self.state_interval
        for port in self._sensor_readers:
            port.min_interval = IDLE_READ_INTERVAL if idle else 0.0

    def _reader_priority(self) -> None:
        """A module's readers run above its loop while it controls the robot, and below
        every loop while it is idle: an idle module's readers (gaze_control's and
        temperature's while only walking walks) took the CPU from the loop of the one
        walking, and on a slow 2-core machine that loop stalled 20 ms at a time."""
        if self.realtime_readers:
            keep_priority(BACKGROUND_PRIORITY if self._idle else PATH_PRIORITY)

    def _on_state_si(self, chain: str, indices: List[int], bottle: Bottle,
                     envelope: str = "") -> None:
        self._reader_priority()
        try:
            state = protocol.decode_state_si(bottle, len(indices))
        except HalProtocolError as exc:
            log.warning("%s: bad state from the HAL on %s: %s", self.owner, chain, exc)
            return
        self.clock.observe(state.time)
        link = self._links[chain]
        self._store((link,), link.indices, state.seq, state.q, state.qdot, state.tau,
                    state.temperature, robot_time=state.time)

    def _on_whole_state_si(self, bottle: Bottle) -> None:
        self._reader_priority()
        try:
            state = protocol.decode_whole_state(bottle, self._whole_joints)
        except HalProtocolError as exc:  # refused, so the robot looks away: the module holds
            if self._bad_whole.record():
                log.warning("%s: whole-robot state from the HAL refused (#%d of this burst): "
                            "%s", self.owner, self._bad_whole.count, exc)
            return
        self.clock.observe(state.time)
        self._store(self._whole_links, self._whole_indices, state.seq, state.q, state.qdot,
                    state.tau, state.temperature, robot_time=state.time)

    def _on_state_ext(self, chain: str, indices: List[int], bottle: Bottle,
                      envelope: str = "") -> None:
        self._reader_priority()
        try:
            data = controlboard.decode_joint_data(bottle)
            if data.position is None or len(data.position) != len(indices):
                raise ControlBoardError(f"positions for {len(indices)} joints expected")
        except ControlBoardError as exc:
            log.warning("%s: bad stateExt from %s: %s", self.owner, chain, exc)
            return
        stamp = controlboard.Stamp.from_envelope(envelope)
        # Timed by arrival: a YARP device's stamp need not move (fakeMotionControl's is 0).
        self.clock.observe(time.monotonic())
        zeros = [0.0] * len(indices)
        self._store((self._links[chain],), indices, stamp.count if stamp else 0,
                    np.radians(data.position),
                    np.radians(data.velocity) if data.velocity else zeros,
                    data.torque or zeros, None, data.control_modes)

    def _store(self, links: Sequence[_ChainLink], indices: List[int], seq: int,
               q: Sequence[float], qdot: Sequence[float], tau: Sequence[float],
               temperature: Optional[Sequence[float]],
               modes: Optional[Sequence[str]] = None,
               robot_time: Optional[float] = None) -> None:
        """The state of ``links`` (their joints at ``indices``, in order), arrived now;
        ``modes`` (one chain's) when the state says them; ``robot_time`` when it says the
        robot's time (our HAL's ``stateSI``).  A whole-robot state is stored in one go: at
        500 Hz in every module, chain by chain cost a third of its reading."""
        now = time.monotonic()
        with self._lock:
            for link in links:
                # A robot back from silence, or restarted (its count went back), may have
                # booted our joints in another mode; so may anyone who changed their modes.
                lost = [k for k in link.direct if modes[k] != "posd"] if modes is not None else []
                # In lockstep a gap in the wall clock is the machine's, not the robot's: only
                # a count that went back says it restarted.
                stale = now - link.seen_at > STALE_AFTER and not self.lockstep
                if stale or seq < link.seq or lost:
                    link.direct.difference_update(lost if lost else set(link.direct))
                    if link.wanted - link.direct:
                        self._mode_wanted.set()
                link.seen_at, link.seq = now, seq
            self._q[indices] = q
            self._qdot[indices] = qdot
            self._tau[indices] = tau
            if temperature is not None:
                self._temperature[indices] = temperature
            self._seen[indices] = True
            self.last_seq = seq
            self._updated = now
            if all(other.seen_at > self.newest_round for other in self._links.values()):
                self._rounds.round(now, seq, robot_time)
                if robot_time is not None:
                    self._round_time = robot_time
                self._round.notify_all()

    def _poll_temperatures(self) -> None:
        """A plain YARP robot streams no temperatures: ask for them once a second."""
        while not self._stop.wait(1.0):
            for link in list(self._links.values()):
                reply = self._rpc(link, [Vocab("get"), Vocab("tmps")])
                values = reply[2] if reply is not None and len(reply) > 2 else None
                if isinstance(values, list) and len(values) == len(link.indices) and \
                        all(isinstance(v, float) for v in values):
                    with self._lock:
                        self._temperature[link.indices] = values

    def _rpc(self, link: _ChainLink, request: Sequence) -> Optional[Bottle]:
        """One request to a chain's rpc:i; None (logged once) if it failed."""
        try:
            contact = self.nameclient.query(link.rpc)
            # Named as our command port's module, so the HAL's arbitration sees one owner.
            reply = network.request(contact, request, timeout=2,
                                    sender=f"{self.owner}/robot/{link.name}/rpc:o") \
                if contact else None
        except YarpError as exc:
            reply, why = None, str(exc)
        else:
            why = "no answer" if reply is None else f"answered {reply.to_text()[:80]}"
        if reply is not None and len(reply) and str(reply[-1]) == "ok":
            link.reported = False
            return reply
        if not link.reported:
            link.reported = True
            log.info("%s: %s %s: %s", self.owner, link.rpc, Bottle(request).to_text(), why)
        return None

    def _on_ft(self, sensor: str, bottle: Bottle, envelope: str = "") -> None:
        if len(bottle) >= 6:
            self._ft[sensor] = np.array([float(v) for v in bottle[:6]])
            self._sensor_read(sensor, envelope)

    def _sensor_read(self, sensor: str, envelope: str) -> None:
        if not self.lockstep:
            return
        stamp = controlboard.Stamp.from_envelope(envelope)
        if stamp is not None:
            with self._round:
                self._sensor_times[sensor] = stamp.time
                self._round.notify_all()

    def _on_hal_warning(self, bottle: Bottle) -> None:
        """Keep what the HAL says about this module's own commands (arbitration, and
        commands refused because a joint left position direct: switch it back)."""
        if len(bottle) >= 5 and str(bottle[2]) == self.owner:
            with self._lock:
                self._hal_warnings.append(str(bottle[1]))
                del self._hal_warnings[:-20]
                if str(bottle[4]) == "wrong mode":
                    for link in self._links.values():
                        link.direct.clear()
                    self._mode_wanted.set()

    def take_hal_warnings(self) -> List[str]:
        """What the HAL refused or overrode of this module's commands since last asked."""
        with self._lock:
            warnings, self._hal_warnings = self._hal_warnings, []
        return warnings

    def _on_imu(self, bottle: Bottle, envelope: str = "") -> None:
        try:
            self._imu = protocol.decode_inertial(bottle)
        except HalProtocolError as exc:
            log.warning("%s: bad inertial message: %s", self.owner, exc)
            return
        self._sensor_read("inertial", envelope)

    # -- sensing ------------------------------------------------------------------------------

    @property
    def connected(self) -> bool:
        """True while the HAL's state is fresh."""
        return self._updated > 0 and time.monotonic() - self._updated < STALE_AFTER

    @property
    def state_age(self) -> float:
        return time.monotonic() - self._updated if self._updated else math.inf

    @property
    def newest_round(self) -> float:  # type: ignore[override]
        return self._rounds.newest

    @property
    def round_period(self) -> float:
        """The robot's step period (:class:`walkman.hal.rounds.RoundPeriod`); 0: not known."""
        with self._lock:
            return self._rounds.period(time.monotonic())

    def wait_round(self, after: float, timeout: float) -> Optional[float]:
        with self._round:
            if self.newest_round <= after and timeout > 0:
                self._round.wait_for(lambda: self.newest_round > after, timeout)
            return self.newest_round if self.newest_round > after else None

    @property
    def round_time(self) -> float:
        """The robot time of the newest whole round (our HAL's states say it; -inf: none)."""
        return self._round_time

    def wait_round_at(self, at_least: float, timeout: float) -> bool:
        """Wait until a round of robot time ``at_least`` or later is here, with the sensor
        readings streamed at its step (a module in lockstep: :mod:`walkman.gym.lockstep`);
        False if not within ``timeout``."""
        with self._round:
            return self._round.wait_for(lambda: self._whole_round_at(at_least), timeout)

    def _whole_round_at(self, at_least: float) -> bool:
        """(lock held) The round is here, and each sensor's newest reading is the one of its
        step (sensors stream on the steps that are whole multiples of their period)."""
        now = self._round_time
        if now < at_least - 1e-6:
            return False
        if not self.sensors or self.standard:
            return True
        oldest = now - protocol.SENSOR_PERIOD_S + 1e-4
        names = [s.name for s in self.model.sensors if s.kind == "ft"] + ["inertial"]
        return all(self._sensor_times.get(name, -math.inf) >= oldest for name in names)

    def lockstep_view(self) -> str:
        """What a module in lockstep has of the robot, for a log line when a round is late."""
        with self._lock:
            sensors = ", ".join(f"{name} {when:.4f}" for name, when in
                                sorted(self._sensor_times.items()))
            return (f"newest round {self._round_time:.4f} s (count {self.last_seq}), "
                    f"sensors at {sensors or 'none yet'}")

    def take_commanded(self) -> List[str]:
        """The chains ``move`` wrote to since the last call, one per command written (a
        lockstep tick names them)."""
        with self._lock:
            chains, self._commanded = self._commanded, []
        return chains

    def sense_position(self) -> np.ndarray:
        with self._lock:
            return self._q.copy()

    def sense_velocity(self) -> np.ndarray:
        with self._lock:
            return self._qdot.copy()

    def sense_torque(self) -> np.ndarray:
        with self._lock:
            return self._tau.copy()

    def sense_temperature(self) -> np.ndarray:
        with self._lock:
            return self._temperature.copy()

    def sense_ft(self, sensor: str) -> np.ndarray:
        self._need_sensors()
        if sensor not in self._ft:
            return np.zeros(6)
        return self._ft[sensor].copy()

    def sense_imu(self) -> Optional[Tuple[List[float], List[float], List[float]]]:
        """(roll pitch yaw rad, acceleration m/s^2, angular velocity rad/s), if known."""
        self._need_sensors()
        return self._imu

    def _need_sensors(self) -> None:
        if not self.sensors:
            raise HalUsageError(f"{self.owner} opened the robot without its sensors "
                                "(Robot(sensors=False)); open it with sensors to read them")

    # -- moving ----------------------------------------------------------------------------------

    def check(self, q: Sequence[float]) -> np.ndarray:
        """Validate a whole-body reference; clamp it to the limits."""
        values = check_reference(q, self.joint_names, self.lower, self.upper)
        if not np.array_equal(values, np.asarray(q, dtype=float)):
            self.clamped += 1
        return values

    def move(self, q: Sequence[float], mode: str = "pos",
             joints: Optional[Sequence[str]] = None) -> bool:
        """Stream a whole-body position reference (rad).  False if the robot is away.

        With ``joints`` only those joints are commanded (the values for the
        others in ``q`` are ignored), so modules sharing the robot do not
        overwrite each other's joints.
        """
        if mode != "pos":
            raise HalUsageError(f"move streams positions (mode 'pos'), not {mode!r}")
        values = self.check(q)
        if not self.connected and not self.lockstep:  # in lockstep: the round it handles
            return False                              # is the robot's word that it is there
        selected = None if joints is None else {self.index[name] for name in joints}
        sent = True
        for chain, link in self._links.items():
            mine = [k for k, index in enumerate(link.indices)
                    if selected is None or index in selected]
            if not mine:
                continue
            if not link.wanted.issuperset(mine) or not link.direct.issuperset(mine):
                with self._lock:
                    link.wanted.update(mine)
                if self.lockstep:
                    self._switch_modes(link)
                else:
                    self._mode_wanted.set()  # the mode keeper switches them; we stream meanwhile
            refs = np.degrees(values[[link.indices[k] for k in mine]])
            bottle = controlboard.encode_stream(
                "direct", refs, None if len(mine) == len(link.indices) else mine,
                self.last_seq or None)
            written = link.command.write(bottle)
            # (a port with no output "writes" to nobody: a tick must not name that chain)
            if written and self.lockstep and link.command.has_outputs:
                with self._lock:
                    self._commanded.append(chain)
            sent = written and sent
        return sent

    def _keep_modes(self) -> None:
        """Switch the joints we command to position direct, off the control loop: a
        YARP board refuses [dpos] in any other mode, and an rpc may take milliseconds."""
        while not self._stop.is_set():
            self._mode_wanted.wait(1.0)
            self._mode_wanted.clear()
            for link in list(self._links.values()):
                if self._stop.is_set():
                    break
                if not self._switch_modes(link):
                    self._stop.wait(1.0)  # refused or away: ask again in a second
                    self._mode_wanted.set()

    def _switch_modes(self, link: _ChainLink) -> bool:
        """Ask for position direct on the joints of ``link`` we command and it has not
        switched; False if refused or the robot is away."""
        with self._lock:
            joints = sorted(link.wanted - link.direct)
        if not joints:
            return True
        reply = self._rpc(link, [Vocab("set"), Vocab("icmd"), Vocab("cmog"), len(joints),
                                 Bottle(joints), Bottle(Vocab("posd") for _ in joints)])
        if reply is None:
            return False
        with self._lock:
            link.direct.update(joints)
        return True
