"""One HAL chain as a YARP control board: modes, references and the servo set-points.

Theory of operation
-------------------
:class:`ChainBoard` is the device behind one ``/<robot>/<chain>`` wrapper
(:mod:`walkman.hal.controlboard` speaks the protocol).  Requests arrive on
port threads; they only record intentions under the chain's lock.  The
physics thread calls :meth:`ChainBoard.step` once per tick, which turns the
intentions into the backend's position references, per joint, by control
mode -- as a motor board's firmware would:

``pos``   position control: go to the target at the reference speed
          (positionMove, relativeMove; IPositionControl)
``posd``  position direct: the streamed reference, applied at once
          (what the GYM modules stream at 500 Hz)
``vel``   velocity: the reference moves at the commanded speed; a joint
          whose velocity command is older than 0.1 s stops (YARP's watchdog)
``idl``   motors off: the joint is limp

A command for a joint in another mode is skipped, as a real board skips
it; the skip is logged and told to the sender (the HAL's ``warning:o``) once
per burst.  The robot boots in position-direct mode holding its posture:
Walk-Man's boards are position servos fed a reference every millisecond
(paper, Figure 4), so that is their natural mode, and a module's first
references are not lost while it switches modes.  Standard YARP clients set
the mode they need first (``yarpmotorgui`` and ``remote_controlboard`` users
do: a YARP robot may boot in any mode).  Every command names its owner (the
sender's port), and the HAL's joint arbitration decides which joints it may
move before anything is recorded.
"""

from __future__ import annotations

import logging
import math
import threading
from typing import Callable, Dict, List, Optional, Sequence, Set, Tuple

import numpy as np

from walkman.hal import controlboard as cb
from walkman.hal.backend import DEFAULT_REF_SPEED, Backend
from yarp_lite.bursts import Burst

log = logging.getLogger("walkman.hal")

VELOCITY_WATCHDOG_S = 0.1  # fakeMotionControl's VELOCITY_WATCHDOG
SETTABLE_MODES = {cb.MODE_POSITION, cb.MODE_DIRECT, cb.MODE_VELOCITY, cb.MODE_IDLE,
                  cb.MODE_FORCE_IDLE}
#: Which control mode each streamed or rpc move needs.
MODE_OF = {"position_move": cb.MODE_POSITION, "relative_move": cb.MODE_POSITION,
           "direct": cb.MODE_DIRECT, "velocity_move": cb.MODE_VELOCITY}
#: Position gains the servos emulate (kp N*m/deg, kd N*m*s/deg), for [get] [pid] (read-only).
SERVO_PID = (20.0, 0.2, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0)

#: arbitrate(owner, whole-body joint indices) -> the allowed subset.
Arbiter = Callable[[str, List[int]], Set[int]]


class ChainBoard(cb.ControlBoardDevice):
    def __init__(self, name: str, joints: List[str], backend: Backend,
                 arbitrate: Arbiter = lambda owner, joints: set(joints),
                 on_seq: Callable[[int], None] = lambda seq: None,
                 on_refused: Callable[[str, str], None] = lambda owner, text: None,
                 boot_mode: str = cb.MODE_DIRECT,
                 on_halted: Callable[[str, str], None] = lambda owner, text: None) -> None:
        self.name = name
        #: The pilot's stop-all holds every joint where its servo is: nothing moves them.
        self.halted = False
        self.on_halted = on_halted
        self._halt_refusals: Dict[str, Burst] = {}
        self.joints = joints
        self.backend = backend
        self.indices = np.array([backend.index[j] for j in joints])
        self.arbitrate = arbitrate
        self.on_seq = on_seq
        self.on_refused = on_refused  # (owner, text): tell the owner (the HAL's warning:o)
        count = len(joints)
        self.lock = threading.Lock()
        self.modes: List[str] = [boot_mode] * count
        self.targets = np.degrees(backend.reference[self.indices])      # pos mode goals
        self.ref_speed = np.full(count, math.degrees(DEFAULT_REF_SPEED))
        self.ref_acceleration = np.full(count, 1e9)                        # not modelled
        self.direct = self.targets.copy()                                  # posd references
        self.velocity = np.zeros(count)                                    # vel references
        self.velocity_at = np.zeros(count)
        self._moving = np.zeros(count, dtype=bool)
        self._dirty = np.zeros(count, dtype=bool)   # direct references not yet applied
        self._idle_changed = False
        #: something for :meth:`step` to do (a reference, a move, a mode): without it, and
        #: with no joint in velocity mode, a tick costs one test -- most chains, most ticks
        self._work = False
        self._velocity_joints: List[int] = []
        self.commands = 0
        self.refused = 0  # commands skipped because a joint was in another mode
        self._refusals: Dict[str, Burst] = {}

    # -- reading (ControlBoardDevice) -----------------------------------------------------

    def axes(self) -> int:
        return len(self.joints)

    def vector(self, name: str) -> List[float]:
        backend, idx = self.backend, self.indices
        if name == "encoders":
            return np.degrees(backend.positions()[idx]).tolist()
        if name == "encoder_speeds":
            return np.degrees(backend.velocities()[idx]).tolist()
        if name == "encoder_accelerations":
            return [0.0] * len(idx)
        if name == "temperatures":
            return backend.temperatures()[idx].tolist()
        with self.lock:
            vectors = {"target_positions": self.targets, "direct_references": self.direct,
                       "velocity_references": self.velocity, "ref_speeds": self.ref_speed,
                       "ref_accelerations": self.ref_acceleration}
            if name in vectors:
                return vectors[name].tolist()
        raise cb.ControlBoardError(f"{self.name} has no {name}")

    def axis_name(self, axis: int) -> str:
        return self.joints[axis]

    def limits(self, axis: int) -> Tuple[float, float]:
        index = self.indices[axis]
        return (math.degrees(self.backend.lower[index]), math.degrees(self.backend.upper[index]))

    def torques(self) -> List[float]:
        return self.backend.torques()[self.indices].tolist()

    def torque_range(self, axis: int) -> Tuple[float, float]:
        effort = self.backend.model.joint(self.joints[axis]).effort
        return (-effort, effort)

    def control_modes(self) -> List[str]:
        with self.lock:
            return list(self.modes)

    def pid(self, pid_type: str, axis: int) -> List[float]:
        if pid_type != "pos":
            raise cb.ControlBoardError(f"{self.name} runs position servos only: no {pid_type} PID")
        return list(SERVO_PID)

    def motion_done(self, joints: Sequence[int]) -> bool:
        with self.lock:
            return not bool(self._moving[list(joints)].any())

    # -- commanding (ControlBoardDevice) ---------------------------------------------------

    def set_control_modes(self, joints: Sequence[int], modes: Sequence[str],
                          owner: str = "") -> None:
        """Change modes; a joint another module holds is refused, like any command."""
        unknown = [m for m in modes if m not in SETTABLE_MODES]
        if unknown:
            raise cb.ControlBoardError(f"{self.name}: control mode {unknown[0]!r} is not offered; "
                                       f"try {', '.join(sorted(SETTABLE_MODES))}")
        joints = list(joints)
        if self.halted:   # idle would drop the torque that holds the robot
            raise cb.ControlBoardError(f"{self.name}: control modes cannot change while the "
                                       f"pilot's stop-all holds the joints")
        if owner:
            allowed = self.arbitrate(owner, [int(self.indices[j]) for j in joints])
            held = [self.joints[j] for j in joints if int(self.indices[j]) not in allowed]
            if held:
                raise cb.ControlBoardError(f"{self.name}: {owner} may not change the mode of "
                                           f"{', '.join(held)}: another module holds it")
        measured = np.degrees(self.backend.positions()[self.indices])
        with self.lock:
            for joint, mode in zip(joints, modes):
                mode = cb.MODE_IDLE if mode == cb.MODE_FORCE_IDLE else mode
                if mode == self.modes[joint]:
                    continue
                # A new mode starts from the servo's reference (not the measured position,
                # which a loaded compliant joint holds below it), or from where a limp
                # joint hangs.
                start = measured[joint] if self.modes[joint] == cb.MODE_IDLE \
                    else self._reference(joint)
                self.modes[joint] = mode
                self.targets[joint] = self.direct[joint] = start
                self.velocity[joint] = 0.0
                self._moving[joint] = False
                self._dirty[joint] = mode != cb.MODE_IDLE
            self._idle_changed = self._work = True
            self._velocity_joints = [k for k, m in enumerate(self.modes)
                                     if m == cb.MODE_VELOCITY]

    def command(self, what: str, joints: Sequence[int], values: Sequence[float],
                owner: str = "", seq: Optional[int] = None) -> None:
        joints = list(joints)
        if seq is not None:
            self.on_seq(seq)
        if self.halted and what not in ("set_ref_speeds", "set_ref_accelerations"):
            self._refuse_halted(owner, what)
            return
        if what in ("set_ref_speeds", "set_ref_accelerations") and not all(v > 0 for v in values):
            raise cb.ControlBoardError(f"{what} needs positive values: {list(values)}")
        need = MODE_OF.get(what)
        with self.lock:
            wrong = [j for j in joints if need is not None and self.modes[j] != need]
            modes = [self.modes[j] for j in wrong]
        if wrong:  # as a motor board: a command for another mode is skipped
            self._refuse(owner, what, need, wrong, modes)
        candidates = [k for k, j in enumerate(joints) if j not in wrong]
        if not candidates:
            return
        # Only then arbitration: a command the mode refuses does not claim its joints.
        allowed = self.arbitrate(owner, [int(self.indices[joints[k]]) for k in candidates])
        keep = [k for k in candidates if int(self.indices[joints[k]]) in allowed]
        with self.lock:
            self.commands += 1
            for k in keep:
                self._record(what, joints[k], values[k] if values else 0.0)

    def halt(self, on: bool) -> None:
        """The pilot's stop-all (``on``): every joint holds what its servo holds now, and
        commands are refused until it is released (each owner told, once per burst)."""
        with self.lock:
            if on and not self.halted:
                for joint in range(len(self.joints)):
                    self._record("stop", joint, 0.0)
            self.halted = on
            self._halt_refusals = {}

    def _refuse_halted(self, owner: str, what: str) -> None:
        with self.lock:
            self.refused += 1
            burst = self._halt_refusals.setdefault(owner, Burst())
        if burst.record():
            text = (f"HAL: {what} from {owner or '?'} not applied: {self.name} is held by the "
                    f"pilot's stop-all (#{burst.count} of this burst)")
            log.warning("%s: %s", self.name, text)
            self.on_halted(owner, text)

    def _record(self, what: str, joint: int, value: float) -> None:
        self._work = True
        lower, upper = self.limits(joint)
        if what == "direct":
            self.direct[joint] = min(max(value, lower), upper)
            self._dirty[joint] = True
        elif what in ("position_move", "relative_move"):
            base = self.targets[joint] if what == "relative_move" else 0.0
            self.targets[joint] = min(max(base + value, lower), upper)
            self._moving[joint] = True
        elif what == "velocity_move":
            self.velocity[joint] = value
            self.velocity_at[joint] = self.backend.time
        elif what == "set_ref_speeds":
            self.ref_speed[joint] = value
        elif what == "set_ref_accelerations":
            self.ref_acceleration[joint] = value
        elif what == "stop":  # hold what the servo holds now
            here = self._reference(joint)
            self.targets[joint] = self.direct[joint] = here
            self.velocity[joint] = 0.0
            self._moving[joint] = False
        else:
            raise cb.ControlBoardError(f"{self.name}: {what} is not offered")

    def resync(self) -> None:
        """The robot was set down in a new posture (a simulated station): every goal and
        reference is the servo's new one, nothing moving -- an old goal would walk the
        joints back to where they were."""
        with self.lock:
            self.targets[:] = self.direct[:] = np.degrees(self.backend.reference[self.indices])
            self.velocity[:] = 0.0
            self._moving[:] = False
            self._dirty[:] = False

    def _reference(self, joint: int) -> float:
        """The servo's reference (degrees): where a new mode or a stop starts from."""
        return math.degrees(self.backend.reference[self.indices[joint]])

    def _refuse(self, owner: str, what: str, need: Optional[str], joints: List[int],
                modes: List[str]) -> None:
        """Count, log and report (once per burst per owner) commands the mode refused."""
        with self.lock:
            self.refused += 1
            burst = self._refusals.setdefault(owner, Burst())
        if burst.record():
            text = (f"HAL: {what} from {owner or '?'} skipped for "
                    f"{', '.join(self.joints[j] for j in joints)}: not in [{need}] mode but "
                    f"[{'], ['.join(modes)}] (#{burst.count} of this burst)")
            log.warning("%s: %s", self.name, text)
            self.on_refused(owner, text)

    # -- the physics thread ---------------------------------------------------------------

    def step(self, dt: float) -> None:
        """Turn this tick's intentions into servo references (called before each step)."""
        backend, idx = self.backend, self.indices
        with self.lock:
            if not self._work and not self._velocity_joints:
                return
            modes = self.modes
            idle_changed, self._idle_changed = self._idle_changed, False
            if idle_changed:
                idle = [k for k, m in enumerate(modes) if m == cb.MODE_IDLE]
                if idle:
                    backend.set_idle(idx[idle])
            dirty = np.flatnonzero(self._dirty)
            if dirty.size:
                backend.set_references(idx[dirty], np.radians(self.direct[dirty]))
                self._dirty[dirty] = False
            moving = np.flatnonzero(self._moving)
            if moving.size:
                current = np.degrees(backend.reference[idx[moving]])
                limit = self.ref_speed[moving] * dt
                step = np.clip(self.targets[moving] - current, -limit, limit)
                backend.set_references(idx[moving], np.radians(current + step))
                self._moving[moving] = np.abs(self.targets[moving] - current - step) > 1e-9
            self._work = bool(self._moving.any())      # a move goes on next tick
            velocity = self._velocity_joints
            if velocity:
                stale = backend.time - self.velocity_at[velocity] > VELOCITY_WATCHDOG_S
                self.velocity[np.array(velocity)[stale]] = 0.0
                current = np.degrees(backend.reference[idx[velocity]])
                backend.set_references(idx[velocity],
                                       np.radians(current + self.velocity[velocity] * dt))
