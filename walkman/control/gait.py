"""A step planner and foot trajectories for walking with a level pelvis (sans-IO).

Theory of operation
-------------------
Feet are planar poses ``(x, y, yaw)`` in the pelvis frame plus a height.  A
walk of ``(dx, dy, dyaw)`` is cut into ``m`` equal strides ``g`` (each within
the step limits) and played as ``m + 1`` steps: a half stride, ``m - 1`` full
strides, a half stride.  During a step the *stance* foot stays on the floor and
slides back by the step's pelvis displacement (``(s g)^-1 * start``, s the
quintic law) -- the foot holds the ground, so the pelvis moves forward -- while
the *swing* foot rises by ``lift`` in the first fifth of the step, travels
while up, and comes straight down in the last 30 %, landing half a stride
ahead of its nominal place (on the last step: at its nominal place).  Landing
vertically matters: a loaded stance leg sags, and a foot that skims the floor
while travelling would carry weight and push the pelvis back.  In
steady state each foot alternates between half a stride ahead and behind, and
the walk ends with both feet side by side.

Each step starts with ``double_support`` seconds of both feet down: the only
moments a walk may be paused (:meth:`Gait.can_pause`), so a pause always
leaves both feet on the floor.  :meth:`Gait.hold` and :meth:`Gait.resume`
shift the remaining steps in time.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import List, Optional, Tuple

import numpy as np

from walkman.control.trajectory import quintic

Planar = Tuple[float, float, float]  # x, y, yaw
RISE, DESCEND = 0.2, 0.7  # swing phases: up until RISE, travel, down from DESCEND


def compose(a: Planar, b: Planar) -> Planar:
    """``a * b``: b expressed in a's frame, then in a's parent."""
    ax, ay, at = a
    bx, by, bt = b
    c, s = math.cos(at), math.sin(at)
    return ax + c * bx - s * by, ay + s * bx + c * by, at + bt


def inverse(a: Planar) -> Planar:
    x, y, t = a
    c, s = math.cos(t), math.sin(t)
    return -c * x - s * y, s * x - c * y, -t


def scale(a: Planar, s: float) -> Planar:
    return a[0] * s, a[1] * s, a[2] * s


@dataclass
class Step:
    swing: str              # "left" or "right"
    stride: Planar          # the pelvis displacement over this step
    start: dict             # side -> planar pose at the step's start
    end: dict               # side -> planar pose at its end
    t0: float = 0.0


@dataclass
class Gait:
    """Plans and plays a walk; feet are ``{"left": ..., "right": ...}``."""

    half_width: float = 0.11       # m, nominal foot offset from the pelvis's mid-plane
    forward: float = 0.0           # m, nominal foot x in the pelvis frame
    ground: float = -1.11          # m, sole height in the pelvis frame
    lift: float = 0.05             # m, swing foot clearance
    step_time: float = 1.0         # s, single support
    double_support: float = 0.3    # s, both feet down before each step
    max_stride: Planar = (0.2, 0.08, 0.3)
    steps: List[Step] = field(default_factory=list)
    feet: dict = field(default_factory=dict)
    travelled: Planar = (0.0, 0.0, 0.0)
    _held_at: Optional[float] = None

    def __post_init__(self) -> None:
        if not self.feet:
            self.feet = {side: self.nominal(side) for side in ("left", "right")}

    def nominal(self, side: str) -> Planar:
        return self.forward, self.half_width if side == "left" else -self.half_width, 0.0

    @property
    def walking(self) -> bool:
        return bool(self.steps)

    @property
    def held(self) -> bool:
        return self._held_at is not None

    def plan(self, dx: float, dy: float, dyaw: float, t0: float) -> int:
        """Plan a walk from both feet side by side; returns the number of steps."""
        if self.steps:
            raise ValueError("already walking: wait for the walk to end")
        if not all(math.isfinite(v) for v in (dx, dy, dyaw)):
            raise ValueError("the walk must be finite numbers")
        strides = max(1, max(math.ceil(abs(v) / limit - 1e-9)
                             for v, limit in zip((dx, dy, dyaw), self.max_stride)))
        stride = (dx / strides, dy / strides, dyaw / strides)
        lead = "left" if (dy > 0 or (dy == 0 and dyaw >= 0)) else "right"
        factors = [0.5] + [1.0] * (strides - 1) + [0.5]
        feet = dict(self.feet)
        t = t0
        for index, factor in enumerate(factors):
            swing = lead if index % 2 == 0 else ("right" if lead == "left" else "left")
            stance = "right" if swing == "left" else "left"
            motion = scale(stride, factor)
            last = index == len(factors) - 1
            lands = self.nominal(swing) if last else compose(scale(stride, 0.5),
                                                             self.nominal(swing))
            end = {stance: compose(inverse(motion), feet[stance]), swing: lands}
            self.steps.append(Step(swing, motion, dict(feet), end, t))
            feet = end
            t += self.double_support + self.step_time
        return len(factors)

    def _phase(self, step: Step, t: float) -> float:
        """0 during double support, then 0..1 through single support."""
        return min(max((t - step.t0 - self.double_support) / self.step_time, 0.0), 1.0)

    def update(self, t: float) -> Optional[Step]:
        """Advance to time ``t``; returns the step that just ended, if one did."""
        if not self.steps or self._held_at is not None:
            return None
        step = self.steps[0]
        if t < step.t0 + self.double_support + self.step_time:
            return None
        self.steps.pop(0)
        self.feet = step.end
        self.travelled = compose(self.travelled, step.stride)
        return step

    def foot(self, side: str, t: float) -> Tuple[Planar, float]:
        """A foot's planar pose and sole height at ``t``."""
        if not self.steps or self._held_at is not None:
            return self.feet[side], self.ground
        step = self.steps[0]
        s = quintic(self._phase(step, t))
        if side == step.swing:
            phase = self._phase(step, t)
            a, b = step.start[side], step.end[side]
            h = quintic((phase - RISE) / (DESCEND - RISE))
            pose = (a[0] + h * (b[0] - a[0]), a[1] + h * (b[1] - a[1]), a[2] + h * (b[2] - a[2]))
            height = quintic(phase / RISE) if phase < DESCEND else \
                1.0 - quintic((phase - DESCEND) / (1.0 - DESCEND))
            return pose, self.ground + self.lift * height
        return compose(inverse(scale(step.stride, s)), step.start[side]), self.ground

    def can_pause(self, t: float) -> bool:
        """True when both feet are down: not walking, or in a step's double support."""
        return not self.steps or self._held_at is not None or self._phase(self.steps[0], t) == 0.0

    def hold(self, t: float) -> None:
        """Freeze the walk (call when :meth:`can_pause`); the rest of it waits."""
        if self.steps and self._held_at is None:
            self._held_at = t

    def resume(self, t: float) -> None:
        if self._held_at is None:
            return
        shift = t - self._held_at
        self._held_at = None
        for step in self.steps:
            step.t0 += shift

    def cancel(self) -> None:
        """Drop the steps not started (feet stay where they are)."""
        self.steps.clear()
        self._held_at = None


def foot_rotation(yaw: float) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
