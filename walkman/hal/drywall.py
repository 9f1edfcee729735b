"""The drywall of the wall task: what a running drill's bit cuts, judged against the circle.

Theory of operation
-------------------
The simulator does not carve the panel: the bit touches nothing (a hand that
pushed a real drill through drywall meets little force), so the cut is judged
from the bit's path.  Every time the simulator feeds the tip's position and
whether the drill runs, a tip *inside* the panel (past its face) of a running
drill cuts there.  A cut point is on the circle when its distance from the
circle's centre, in the panel's plane, is the radius within ``tolerance``; the
circle is divided into 360 one-degree sectors, and it is cut out once every
sector holds a point on the circle.  Points off the circle are cuts too (a
wrong hole), and the largest miss over the whole cut is kept: a cut out circle
with a stray gash is still reported with that gash.

The bit cuts all along its path, not only where it is sampled: between two
samples (10 ms apart in the simulator) it went straight, and the sectors that
straight line crosses within ``tolerance`` of the circle are cut too.  Sampled
points alone left sectors uncut wherever the tip moved more than a degree in
10 ms -- a module that stalled under load and caught up its trajectory: a whole
cut, entered at 1 degree and left at 16 past a full turn, was judged 340 of 360
degrees.  The largest miss stays that of the sampled points (the chord between
two of them is the model's, not the tip's).

Pure computation over positions: the simulator (:mod:`walkman.hal.sim`) feeds it
and turns what it returns into the HAL's log lines and status.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import List, Optional, Sequence, Tuple

import numpy as np

SECTORS = 360
DEFAULT_TOLERANCE = 0.015   # m a cut may stray from the circle and still follow it
#: Points checked along the path between two samples: every half a sector's arc.
SWEEP_STEP_DEG = 0.5


@dataclass
class Drywall:
    """A panel whose face passes through ``centre`` with outward ``normal`` (toward the
    robot), a circle of ``radius`` marked on it round ``centre``."""

    centre: Sequence[float]
    normal: Sequence[float]
    radius: float
    tolerance: float = DEFAULT_TOLERANCE
    sectors: List[bool] = field(default_factory=lambda: [False] * SECTORS)
    largest_miss: float = 0.0
    cut_points: int = 0
    _inside: bool = False
    _last_cut: Optional[Tuple[float, float]] = None   # the previous sample, while cutting
    _cut_out: bool = False
    _told_off: bool = False

    def __post_init__(self) -> None:
        self.centre = np.asarray(self.centre, dtype=float)
        normal = np.asarray(self.normal, dtype=float)
        self.normal = normal / np.linalg.norm(normal)
        # Two directions in the panel's plane: "up" (world z made normal to the panel)
        # and "left" (normal x up), so angles read like a clock seen from the robot.
        up = np.array([0.0, 0.0, 1.0]) - self.normal * self.normal[2]
        self.up = up / np.linalg.norm(up)
        self.left = np.cross(self.normal, self.up)

    @property
    def cut_degrees(self) -> int:
        """How much of the circle is cut (one-degree sectors)."""
        return sum(self.sectors)

    @property
    def cut_out(self) -> bool:
        return self._cut_out

    def feed(self, tip: Sequence[float], running: bool) -> List[str]:
        """The bit's tip now (world, m) and whether the drill runs; what happened, in words."""
        offset = np.asarray(tip, dtype=float) - self.centre
        depth = -float(offset @ self.normal)
        inside = depth > 0.0
        events: List[str] = []
        if inside and not self._inside:
            if running:
                events.append(f"drywall: the bit goes in {self._where(offset)}")
            elif not self._told_off:
                self._told_off = True
                events.append("drywall: the bit pushes on the panel with the drill off "
                              "(it cuts nothing)")
        elif self._inside and not inside:
            events.append(f"drywall: the bit comes out {self._where(offset)} "
                          f"({self.cut_degrees} degrees of the circle cut)")
        self._inside = inside
        if not (inside and running):
            self._last_cut = None
            return events
        up, left = float(offset @ self.up), float(offset @ self.left)
        self.cut_points += 1
        self.largest_miss = max(self.largest_miss,
                                abs(math.hypot(up, left) - self.radius))
        if self._last_cut is not None:
            self._sweep(self._last_cut, (up, left))
        self._mark(up, left)
        self._last_cut = (up, left)
        if not self._cut_out and all(self.sectors):
            self._cut_out = True
            events.append(f"drywall: the circle is cut out ({SECTORS} degrees, largest miss "
                          f"{self.largest_miss * 100:.1f} cm)")
        return events

    def summary(self) -> str:
        """One line for the HAL's status: how much is cut, and how far from the circle."""
        return (f"{self.cut_degrees} degrees cut, largest miss "
                f"{self.largest_miss * 100:.1f} cm{', cut out' if self._cut_out else ''}")

    def _mark(self, up: float, left: float) -> None:
        """A point the bit went through: its sector is cut if it is on the circle."""
        if abs(math.hypot(up, left) - self.radius) <= self.tolerance:
            self.sectors[int(self._angle(up, left) % SECTORS)] = True

    def _sweep(self, start: Tuple[float, float], end: Tuple[float, float]) -> None:
        """The straight path from the previous sample to this one (both ends excluded)."""
        length = math.hypot(end[0] - start[0], end[1] - start[1])
        steps = math.ceil(length / (self.radius * math.radians(SWEEP_STEP_DEG)))
        for k in range(1, steps):
            share = k / steps
            self._mark(start[0] + (end[0] - start[0]) * share,
                       start[1] + (end[1] - start[1]) * share)

    @staticmethod
    def _angle(up: float, left: float) -> float:
        """Degrees from the top of the circle, clockwise as the robot sees the panel."""
        return math.degrees(math.atan2(-left, up)) % 360.0

    def _where(self, offset: np.ndarray) -> str:
        up, left = float(offset @ self.up), float(offset @ self.left)
        return (f"{math.hypot(up, left) * 100:.1f} cm from the circle's centre at "
                f"{self._angle(up, left):.0f} degrees")
