"""Trajectories with the quintic time law of the Walk-Man modules.

``s(tau) = 10 tau^3 - 15 tau^4 + 6 tau^5`` with ``tau = t / T`` goes from 0
to 1 with zero velocity and acceleration at both ends.  Linear trajectories
interpolate positions (and, for Cartesian poses, orientations on SO(3));
circular ones rotate about an axis by ``s * angle`` -- the pose turning with
the arc (a hand on a valve), or only the position, the orientation kept (a
drill cutting a circle: section 2.5's circular trajectory of a tool).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional, Tuple

import numpy as np
import pinocchio as pin

Pose = Tuple[np.ndarray, np.ndarray]  # (position (3,), rotation matrix (3, 3))


def quintic(tau: float) -> float:
    tau = min(max(tau, 0.0), 1.0)
    return tau ** 3 * (10.0 - 15.0 * tau + 6.0 * tau * tau)


def quintic_velocity(tau: float) -> float:
    """ds/dtau."""
    tau = min(max(tau, 0.0), 1.0)
    return 30.0 * tau * tau * (1.0 - tau) ** 2


def quintic_acceleration(tau: float) -> float:
    """d2s/dtau2."""
    tau = min(max(tau, 0.0), 1.0)
    return 60.0 * tau * (1.0 - tau) * (1.0 - 2.0 * tau)


@dataclass
class JointTrajectory:
    """From ``start`` to ``goal`` in ``duration`` seconds, quintic in time."""

    start: np.ndarray
    goal: np.ndarray
    duration: float
    t0: float = 0.0

    def __post_init__(self) -> None:
        self.start = np.asarray(self.start, dtype=float)
        self.goal = np.asarray(self.goal, dtype=float)
        if self.duration <= 0:
            raise ValueError(f"trajectory duration must be positive, got {self.duration}")

    def at(self, t: float) -> np.ndarray:
        return self.start + (self.goal - self.start) * quintic((t - self.t0) / self.duration)

    def done(self, t: float) -> bool:
        return t - self.t0 >= self.duration


def duration_for(distance: float, max_speed: float, minimum: float = 0.2) -> float:
    """Shortest quintic duration whose peak speed (1.875 d / T) stays under max_speed."""
    return max(minimum, 1.875 * abs(distance) / max_speed)


def _rotation(rotation: np.ndarray, where: str) -> np.ndarray:
    rotation = np.asarray(rotation, dtype=float)
    if rotation.shape != (3, 3) or not np.all(np.isfinite(rotation)):
        raise ValueError(f"{where}: a rotation is a finite 3x3 matrix, got shape {rotation.shape}")
    if not np.allclose(rotation.T @ rotation, np.eye(3), atol=1e-6) or \
            np.linalg.det(rotation) < 0:
        raise ValueError(f"{where}: not a rotation matrix (R^T R != I or det < 0)")
    return rotation


def _vector(value, where: str) -> np.ndarray:
    value = np.asarray(value, dtype=float)
    if value.shape != (3,) or not np.all(np.isfinite(value)):
        raise ValueError(f"{where}: need 3 finite numbers, got {value.tolist()}")
    return value


class CartesianTrajectory:
    """A pose trajectory with the quintic law: linear, or circular about an axis.

    The generator of the DRC modules: :meth:`set_linear` or :meth:`set_circular`
    with a start time, then :meth:`at` any time (clamped to the ends), :meth:`reset`
    to drop it.  Orientation follows the SO(3) geodesic (``R0 exp(s log(R0^T R1))``)
    on linear paths and turns with the arc on circular ones, so a hand that grasps
    a valve keeps its grasp while turning it.
    """

    def __init__(self) -> None:
        self.duration = 0.0
        self.t0 = 0.0
        self._at = None

    @property
    def active(self) -> bool:
        return self._at is not None

    def set_linear(self, start: Pose, goal: Pose, duration: float, t0: float = 0.0) -> None:
        p0, r0 = _vector(start[0], "start position"), _rotation(start[1], "start rotation")
        p1, r1 = _vector(goal[0], "goal position"), _rotation(goal[1], "goal rotation")
        self._start(duration, t0)
        twist = pin.log3(r0.T @ r1)
        self._at = lambda s: (p0 + s * (p1 - p0), r0 @ pin.exp3(s * twist))

    def set_circular(self, start: Pose, center, axis, angle: float, duration: float,
                     t0: float = 0.0, turn_orientation: bool = True) -> None:
        """Rotate ``start`` about the line through ``center`` along ``axis`` by ``angle`` rad
        (its orientation too, unless ``turn_orientation`` is False: then only its point
        goes round, the frame keeps the start's orientation)."""
        p0, r0 = _vector(start[0], "start position"), _rotation(start[1], "start rotation")
        center = _vector(center, "circle center")
        axis = _vector(axis, "circle axis")
        norm = np.linalg.norm(axis)
        if norm < 1e-9:
            raise ValueError("circle axis: must not be zero")
        if not np.isfinite(angle):
            raise ValueError(f"circle angle: must be finite, got {angle}")
        axis = axis / norm
        self._start(duration, t0)

        def at(s: float) -> Pose:
            turn = pin.exp3(axis * (s * angle))
            return center + turn @ (p0 - center), (turn @ r0 if turn_orientation else r0)

        self._at = at

    def _start(self, duration: float, t0: float) -> None:
        if not duration > 0 or not np.isfinite(duration):
            raise ValueError(f"trajectory duration must be positive, got {duration}")
        self.duration, self.t0 = float(duration), float(t0)

    def reset(self) -> None:
        self._at = None

    def at(self, t: float) -> Pose:
        if self._at is None:
            raise RuntimeError("no trajectory set: call set_linear or set_circular first")
        position, rotation = self._at(quintic((t - self.t0) / self.duration))
        return position.copy(), rotation.copy()

    def done(self, t: float) -> bool:
        return self._at is not None and t - self.t0 >= self.duration

    def goal(self) -> Optional[Pose]:
        return self._at(1.0) if self._at is not None else None
