"""Inverse kinematics: damped least squares with joint limits, on the project's URDF.

Theory of operation
-------------------
Each iteration takes the 6-D error between the frame's pose and the target
(position, and the rotation error ``log3(R^T R*)`` expressed in the pelvis
frame), solves ``dq = J^T (J J^T + lambda^2 I)^-1 e`` over the allowed joints
(the chain's, or the whole body's), and clips ``q`` to the joint limits.  The
damping keeps the step bounded near singularities; joints pinned at a limit
are dropped from the next step so the others do the work.  The result says
whether the target was reached (< 1 mm, < 0.01 rad by default) and, if not,
how far it stayed -- an unreachable target is a clear failure, never a silently
wrong pose.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional, Sequence

import numpy as np
import pinocchio as pin

from walkman.control.kinematics import Kinematics

POSITION_TOLERANCE = 1e-3  # m
ROTATION_TOLERANCE = 1e-2  # rad
REST_GAIN = 0.1            # share of the way back to the rest posture per iteration


class IkError(Exception):
    """A target the solver cannot reach, or a request it cannot understand."""


@dataclass
class IkResult:
    q: np.ndarray
    position_error: float
    rotation_error: float
    iterations: int
    reached: bool


class InverseKinematics:
    def __init__(self, kinematics: Kinematics, damping: float = 0.05,
                 max_iterations: int = 200) -> None:
        self.kinematics = kinematics
        self.damping = damping
        self.max_iterations = max_iterations
        self._rest: Optional[np.ndarray] = None
        model = kinematics.model
        order = kinematics.to_pin
        self.lower = model.lowerPositionLimit[order].copy()
        self.upper = model.upperPositionLimit[order].copy()

    def joints_of(self, names: Sequence[str]) -> np.ndarray:
        index = {name: i for i, name in enumerate(self.kinematics.joint_names)}
        unknown = [name for name in names if name not in index]
        if unknown:
            raise IkError(f"unknown joints {unknown}")
        return np.array([index[name] for name in names])

    def solve(self, frame: str, position: Sequence[float], rotation: Optional[np.ndarray],
              q0: Sequence[float], joints: Optional[Sequence[str]] = None,
              position_tolerance: float = POSITION_TOLERANCE,
              rotation_tolerance: float = ROTATION_TOLERANCE, restarts: int = 4,
              offset: Optional[Sequence[float]] = None,
              rest: Optional[Sequence[float]] = None,
              max_iterations: Optional[int] = None) -> IkResult:
        """Joint positions putting ``frame`` at the target (``rotation`` None: position only).

        Starts from ``q0`` (a control loop's current posture: a few iterations);
        when that ends in a local minimum, tries again from ``restarts`` seeded
        random postures of the free joints and keeps the best.  ``offset`` (in the
        frame) moves the controlled point, e.g. from the hand link to its grip.
        ``rest`` is a posture the redundant joints drift back to (null space), so
        a hand tracked for a long time does not wander into the joint limits.
        ``max_iterations`` bounds the work per descent: a control tick passes a
        few, so a target it cannot reach costs a bounded time, not a whole tick.
        """
        iterations = max_iterations or self.max_iterations
        self._rest = None if rest is None else np.asarray(rest, dtype=float)
        point = np.zeros(3) if offset is None else np.asarray(offset, dtype=float)
        best = self._descend(frame, position, rotation, q0, joints, position_tolerance,
                             rotation_tolerance, point, iterations)
        rng = np.random.default_rng(0)
        free = self.joints_of(joints) if joints is not None else np.arange(len(self.lower))
        for _ in range(restarts):
            if best.reached:
                break
            seed = np.array(q0, dtype=float)
            seed[free] = rng.uniform(self.lower[free], self.upper[free])
            attempt = self._descend(frame, position, rotation, seed, joints,
                                    position_tolerance, rotation_tolerance, point, iterations)
            attempt.iterations += best.iterations
            if attempt.reached or attempt.position_error + attempt.rotation_error < \
                    best.position_error + best.rotation_error:
                best = attempt
            else:
                best.iterations = attempt.iterations
        return best

    def _descend(self, frame: str, position: Sequence[float], rotation: Optional[np.ndarray],
                 q0: Sequence[float], joints: Optional[Sequence[str]],
                 position_tolerance: float, rotation_tolerance: float,
                 point: np.ndarray, max_iterations: int) -> IkResult:
        try:
            self.kinematics.frame_id(frame)
        except KeyError as exc:
            raise IkError(str(exc.args[0])) from None
        target_p = np.asarray(position, dtype=float)
        if target_p.shape != (3,) or not np.all(np.isfinite(target_p)):
            raise IkError(f"target position must be 3 finite numbers, got {list(position)}")
        if rotation is not None:
            rotation = np.asarray(rotation, dtype=float)
            if rotation.shape != (3, 3) or not np.allclose(rotation.T @ rotation, np.eye(3),
                                                           atol=1e-6):
                raise IkError("target rotation must be a 3x3 rotation matrix")
        q = np.clip(np.asarray(q0, dtype=float), self.lower, self.upper)
        free = self.joints_of(joints) if joints is not None else np.arange(len(q))
        rows = slice(0, 6) if rotation is not None else slice(0, 3)
        error = np.zeros(6)
        for iteration in range(1, max_iterations + 1):
            p, r = self.kinematics.pose(q, frame)
            lever = r @ point
            error[:3] = target_p - (p + lever)
            error[3:] = r @ pin.log3(r.T @ rotation) if rotation is not None else 0.0
            if np.linalg.norm(error[:3]) < position_tolerance and \
                    np.linalg.norm(error[3:]) < rotation_tolerance:
                return IkResult(q, float(np.linalg.norm(error[:3])),
                                float(np.linalg.norm(error[3:])), iteration, True)
            jacobian = self.kinematics.jacobian(q, frame)
            if point.any():  # the point's velocity: v + w x lever
                jacobian = jacobian.copy()
                jacobian[:3] -= pin.skew(lever) @ jacobian[3:]
            jacobian = jacobian[rows]
            at_limit = ((q <= self.lower + 1e-9) | (q >= self.upper - 1e-9))
            active = free
            j = jacobian[:, active]
            e = error[rows]
            inverse = j.T @ np.linalg.inv(j @ j.T + self.damping ** 2 * np.eye(len(e)))
            step = inverse @ e
            if self._rest is not None:  # second task, in the first one's null space
                null = np.eye(len(active)) - inverse @ j
                step += null @ (REST_GAIN * (self._rest[active] - q[active]))
            # A joint at its limit that the step pushes further stays there.
            pushing = at_limit[active] & (((q[active] <= self.lower[active] + 1e-9) & (step < 0)) |
                                          ((q[active] >= self.upper[active] - 1e-9) & (step > 0)))
            step[pushing] = 0.0
            norm = np.linalg.norm(step)
            if norm > 0.5:  # keep the linearization honest
                step *= 0.5 / norm
            q = q.copy()
            q[active] = np.clip(q[active] + step, self.lower[active], self.upper[active])
        return IkResult(q, float(np.linalg.norm(error[:3])), float(np.linalg.norm(error[3:])),
                        max_iterations, False)

    def solve_or_raise(self, frame: str, position: Sequence[float],
                       rotation: Optional[np.ndarray], q0: Sequence[float],
                       joints: Optional[Sequence[str]] = None,
                       offset: Optional[Sequence[float]] = None) -> np.ndarray:
        result = self.solve(frame, position, rotation, q0, joints, offset=offset)
        if not result.reached:
            raise IkError(f"{frame} cannot reach {np.round(position, 3).tolist()}: best pose is "
                          f"{result.position_error * 1000:.1f} mm and "
                          f"{result.rotation_error:.3f} rad away")
        return result.q
