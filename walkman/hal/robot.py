"""The whole-body interface: the robot as one kinematic chain, in SI units.

Upper tier of the HAL (the paper's *WholeBodyInterface*): modules call
``sense_position()`` and ``move(q)`` on 33-element vectors in the model's
joint order and never see how the HAL groups joints into chains, nor YARP.
The grouping is asked of the HAL (``/<robot>/rpc:i [get] [chains]``) when
the interface connects, so regrouping the HAL changes nothing here.

Connections are persistent (made by the name server), so a module can start
before the HAL, and survives the HAL restarting.  ``move`` refuses what would
be unsafe -- wrong length, NaN -- with :class:`HalUsageError`, clamps
references to the joint limits and reports it, and sends nothing when the
HAL is not there.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np

from walkman.hal import protocol
from walkman.hal.protocol import Command, HalProtocolError, HalUsageError
from walkman.model.description import Robot as RobotModel
from walkman.model.description import walkman
from yarp_lite import network
from yarp_lite.bottle import Bottle, Vocab
from yarp_lite.buffered_port import BufferedPort
from yarp_lite.errors import NetworkError, YarpError
from yarp_lite.nameclient import NameClient
from yarp_lite.port import Port

log = logging.getLogger("walkman.robot")

#: State older than this means the HAL is gone.
STALE_AFTER = 0.5


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


class Robot:
    """Whole-body access to a HAL, for one module (``owner`` prefixes its ports)."""

    def __init__(self, owner: str, robot: str = "walkman", model: Optional[RobotModel] = None,
                 nameclient: Optional[NameClient] = None, connect_timeout: float = 30.0,
                 carrier: str = "fast_tcp") -> None:
        self.owner = owner.rstrip("/")
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
        self._stamp: Dict[str, Tuple[int, float]] = {}
        self._updated = 0.0
        self._lock = threading.Lock()
        self._ft: Dict[str, np.ndarray] = {}
        self._imu: Optional[Tuple[List[float], List[float], List[float]]] = None
        self.chains: Dict[str, List[int]] = {}
        self._ports: List[Port] = []
        self._command_ports: Dict[str, Port] = {}
        self.clamped = 0
        self.last_seq = 0
        self._hal_warnings: List[str] = []
        self._connect(connect_timeout)

    # -- connecting ----------------------------------------------------------------------

    def _connect(self, timeout: float) -> None:
        grouping = self._ask_grouping(timeout)
        for chain, joints in grouping.items():
            unknown = [j for j in joints if j not in self.index]
            if unknown:
                raise HalProtocolError(f"HAL chain {chain} has joints this model lacks: {unknown}")
            self.chains[chain] = [self.index[j] for j in joints]
        missing = set(self.joint_names) - {j for joints in grouping.values() for j in joints}
        if missing:
            raise HalProtocolError(f"the HAL does not expose joints {sorted(missing)}")
        for chain, indices in self.chains.items():
            names = protocol.port_names(self.robot, chain)
            state = BufferedPort(nameclient=self.nameclient,
                                 on_read=lambda b, chain=chain, idx=indices: self._on_state(
                                     chain, idx, b))
            state.open(f"{self.owner}/robot/{chain}/state:i")
            command = Port(nameclient=self.nameclient)
            command.open(f"{self.owner}/robot/{chain}/command:o")
            self._ports += [state, command]
            self._command_ports[chain] = command
            self._persist(names["state_ext"], state.name)
            self._persist(command.name, names["command"])
        for sensor in (s.name for s in self.model.sensors if s.kind == "ft"):
            port = BufferedPort(nameclient=self.nameclient,
                                on_read=lambda b, sensor=sensor: self._on_ft(sensor, b))
            port.open(f"{self.owner}/robot/{sensor}:i")
            self._ports.append(port)
            self._persist(protocol.ft_port_name(self.robot, sensor), port.name)
        warnings = BufferedPort(nameclient=self.nameclient, strict=True,
                                on_read=self._on_hal_warning)
        warnings.open(f"{self.owner}/robot/warning:i")
        self._ports.append(warnings)
        self._persist(protocol.hal_warning_port_name(self.robot), warnings.name)
        imu = BufferedPort(nameclient=self.nameclient, on_read=self._on_imu)
        imu.open(f"{self.owner}/robot/inertial:i")
        self._ports.append(imu)
        self._persist(protocol.imu_port_name(self.robot), imu.name)

    def _ask_grouping(self, timeout: float) -> Dict[str, List[str]]:
        deadline = time.monotonic() + timeout
        said = 0.0
        answer = ""
        rpc_name = protocol.robot_rpc_name(self.robot)
        while True:
            try:
                contact = self.nameclient.query(rpc_name)
                if contact is not None:
                    reply = network.request(contact, [Vocab("get"), "chains"], timeout=5)
                    grouping = {str(group[0]): [str(j) for j in group[1:]] for group in reply
                                if isinstance(group, list) and group}
                    if grouping:
                        return grouping
                    # A HAL (or a bridge's copy of it) that is not ready yet: ask again.
                    answer = f"; it answered {str(reply)[:120]}"
            except YarpError:
                pass
            now = time.monotonic()
            if now > deadline:
                raise NetworkError(f"no HAL answered at {rpc_name} within {timeout:g} s")
            if now - said > 5:
                log.info("%s: waiting for the HAL (%s)%s", self.owner, rpc_name, answer)
                said = now
            time.sleep(0.3)

    def _persist(self, source: str, target: str) -> None:
        """Ask the name server to keep this connection up (HAL restarts included)."""
        if not self.nameclient.subscribe(source, f"{self.carrier}:/{target}"):
            raise NetworkError(f"name server refused the connection {source} -> {target}")
        self._subscriptions.append((source, f"{self.carrier}:/{target}"))

    @property
    def _subscriptions(self) -> List[Tuple[str, str]]:
        if not hasattr(self, "_subs"):
            self._subs: List[Tuple[str, str]] = []
        return self._subs

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
        for source, target in self._subscriptions:
            try:
                self.nameclient.unsubscribe(source, target)
            except YarpError:
                pass
        for port in self._ports:
            port.close()

    # -- incoming state --------------------------------------------------------------------

    def _on_state(self, chain: str, indices: List[int], bottle: Bottle) -> None:
        try:
            state = protocol.decode_state_ext(bottle, len(indices))
        except HalProtocolError as exc:
            log.warning("%s: bad state from the HAL on %s: %s", self.owner, chain, exc)
            return
        with self._lock:
            self._q[indices] = state.q
            self._qdot[indices] = state.qdot
            self._tau[indices] = state.tau
            self._temperature[indices] = state.temperature
            self._seen[indices] = True
            self._stamp[chain] = (state.seq, state.time)
            self.last_seq = max(self.last_seq, state.seq)
            self._updated = time.monotonic()

    def _on_ft(self, sensor: str, bottle: Bottle) -> None:
        if len(bottle) >= 6:
            self._ft[sensor] = np.array([float(v) for v in bottle[:6]])

    def _on_hal_warning(self, bottle: Bottle) -> None:
        """Keep what the HAL says about this module's own commands (arbitration)."""
        if len(bottle) >= 3 and str(bottle[2]) == self.owner:
            with self._lock:
                self._hal_warnings.append(str(bottle[1]))
                del self._hal_warnings[:-20]

    def take_hal_warnings(self) -> List[str]:
        """What the HAL refused or overrode of this module's commands since last asked."""
        with self._lock:
            warnings, self._hal_warnings = self._hal_warnings, []
        return warnings

    def _on_imu(self, bottle: Bottle) -> None:
        try:
            self._imu = protocol.decode_inertial(bottle)
        except HalProtocolError as exc:
            log.warning("%s: bad inertial message: %s", self.owner, exc)

    # -- sensing ------------------------------------------------------------------------------

    @property
    def connected(self) -> bool:
        """True while the HAL's state is fresh."""
        return self._updated > 0 and time.monotonic() - self._updated < STALE_AFTER

    @property
    def state_age(self) -> float:
        return time.monotonic() - self._updated if self._updated else math.inf

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
        if sensor not in self._ft:
            return np.zeros(6)
        return self._ft[sensor].copy()

    def sense_imu(self) -> Optional[Tuple[List[float], List[float], List[float]]]:
        """(roll pitch yaw rad, acceleration m/s^2, angular velocity rad/s), if known."""
        return self._imu

    # -- moving ----------------------------------------------------------------------------------

    def check(self, q: Sequence[float]) -> np.ndarray:
        """Validate a whole-body reference; clamp it to the limits."""
        values = check_reference(q, self.joint_names, self.lower, self.upper)
        if not np.array_equal(values, np.asarray(q, dtype=float)):
            self.clamped += 1
        return values

    def move(self, q: Sequence[float], mode: str = "pos",
             joints: Optional[Sequence[str]] = None) -> bool:
        """Stream a whole-body position reference (rad).  False if the HAL is away.

        With ``joints`` only those joints are commanded (the values for the
        others in ``q`` are ignored), so modules sharing the robot do not
        overwrite each other's joints.
        """
        values = self.check(q)
        selected = None if joints is None else {self.index[name] for name in joints}
        sent = True
        for chain, indices in self.chains.items():
            if selected is None:
                command = Command(mode, tuple(values[indices]), self.last_seq or None)
            else:
                mine = [k for k, index in enumerate(indices) if index in selected]
                if not mine:
                    continue
                command = Command("pjnt", tuple(values[[indices[k] for k in mine]]),
                                  self.last_seq or None, tuple(mine))
            sent = self._command_ports[chain].write(protocol.encode_command(command)) and sent
        return sent and self.connected

    def move_to(self, q: Sequence[float]) -> bool:
        """Go to ``q`` at the reference speed (the HAL interpolates)."""
        return self.move(q, mode="move")

    def set_ref_speed(self, speed: float) -> None:
        for chain, indices in self.chains.items():
            contact = self.nameclient.query(protocol.port_names(self.robot, chain)["rpc"])
            if contact is not None:
                network.request(contact, [Vocab("set"), Vocab("vels"),
                                          Bottle([float(speed)] * len(indices))])

    def hold(self) -> bool:
        """Keep the current position (the safe answer to anything unexpected)."""
        if not self.connected:
            return False
        return self.move(np.clip(self.sense_position(), self.lower, self.upper))
