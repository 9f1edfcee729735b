"""Balance from the sensors: measured ZMP, ankle compliance, pelvis attitude, the guard (sans-IO).

Theory of operation
-------------------
The preview controller (:mod:`walkman.control.lipm`) plans a CoM that makes
the ZMP follow the plan on an ideal, rigid robot.  Walk-Man is neither: its
series-elastic joints give under load (the pelvis rolls towards the swing
leg), a foot lands on its heel or rocks onto its toe, somebody pushes.  The
corrections here close the loop, each a pure function of the sensors:

* **Measured ZMP** (:func:`foot_zmp`, :func:`combined_zmp`): each ankle's
  6-axis F/T sensor gives the centre of pressure (CoP) under its sole
  (``px = (-ty - d fx) / fz``, ``py = (tx - d fy) / fz`` with ``d`` the sensor's
  height above the sole); the feet's, weighted by their normal forces, is the
  ZMP.  Feet that carry less than :data:`CONTACT_FORCE` are in the air.
* **Ankle compliance** (:class:`AnkleCompliance`): Kajita et al.'s damping
  control of the ankles (IROS 2010): each foot in contact turns so that its
  measured CoP comes to the desired one.  Without it the sagittal sway that
  every step excites grows until a foot rocks on its toe (simulated: the ZMP
  on the toe edge for 0.6 s of each single support by the fifth step); with
  it the ZMP keeps 3 cm from every edge.
* **Attitude** (:class:`AttitudeLoop`): a PI loop on the pelvis IMU's roll and
  pitch tilts the commanded pelvis against what the legs' springs add; a robot
  standing still has the integral alone (on a ramp's bend, with 15-ms ticks,
  the proportional term rocked it onto its heels).
* **Guard** (:class:`BalanceGuard`): the measured ZMP's distance to the edge of
  the support polygon (the convex hull of the soles on the floor) and the
  torso's tilt.  Below :data:`SAFE_MARGIN`, or past :data:`MAX_TILT`, for
  :data:`TRIP_TIME`, the guard trips once: the walking module warns the pilot,
  drops the rest of the walk and stands.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np

#: N: a foot with less normal force is in the air (its F/T reading is noise).
CONTACT_FORCE = 50.0
#: m: the ZMP closer than this to the support polygon's edge is unsafe.
SAFE_MARGIN = 0.01
#: rad: the torso (pelvis IMU) tilted further than this is unsafe.
MAX_TILT = 0.2
#: s: an unsafe condition must last this long to trip the guard (one tick is noise).
TRIP_TIME = 0.1
#: s: safe for this long after a trip, the guard is armed again.
REARM_TIME = 1.0
#: rad: the most the attitude loop tilts the commanded pelvis.
MAX_ATTITUDE = 0.12
#: rad/s per m: how fast a foot turns against its centre-of-pressure error.
ANKLE_GAIN = 0.5
#: s: a foot's compliance angle decays back to flat with this time constant.
ANKLE_RETURN = 0.5
#: rad: the most a foot turns by compliance.
MAX_ANKLE = 0.1


@dataclass(frozen=True)
class Sole:
    """A foot's sole: half sizes (m) of its rectangle, centred on the sole point, and
    where the ankle's F/T sensor is from that point (sole frame: x ahead, z up)."""

    half_length: float = 0.13
    half_width: float = 0.07
    sensor: Tuple[float, float, float] = (-0.03, 0.0, 0.05)


def foot_zmp(wrench: Sequence[float], sole: Sole) -> Optional[Tuple[float, float, float]]:
    """(px, py, fz) of one foot in its sole frame, from the ankle sensor's wrench
    (force and torque that the leg exerts on the foot, as MuJoCo and the HAL give
    them); None if the foot carries less than :data:`CONTACT_FORCE`."""
    fx, fy, fz, tx, ty, _ = (-float(v) for v in wrench[:6])   # the floor's push on the foot
    if fz < CONTACT_FORCE:
        return None
    sx, sy, d = sole.sensor
    return sx + (-ty - d * fx) / fz, sy + (tx - d * fy) / fz, fz


def to_world(pose: Tuple[float, float, float], point: Tuple[float, float]) -> np.ndarray:
    x, y, yaw = pose
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([x + c * point[0] - s * point[1], y + s * point[0] + c * point[1]])


def combined_zmp(feet: Dict[str, Tuple[Tuple[float, float, float], Sequence[float]]],
                 sole: Sole) -> Tuple[Optional[np.ndarray], List[str]]:
    """The ZMP from each foot's (planar pose of its sole, wrench), in the frame of those
    poses, and the feet in contact; (None, []) when no foot carries weight."""
    total = 0.0
    weighted = np.zeros(2)
    contacts = []
    for side, (pose, wrench) in feet.items():
        local = foot_zmp(wrench, sole)
        if local is None:
            continue
        px, py, fz = local
        weighted += fz * to_world(pose, (px, py))
        total += fz
        contacts.append(side)
    if not contacts:
        return None, []
    return weighted / total, contacts


def to_local(pose: Tuple[float, float, float], point: Sequence[float]) -> np.ndarray:
    """A walk-frame point in the sole frame of a foot at ``pose``."""
    x, y, yaw = pose
    c, s = math.cos(yaw), math.sin(yaw)
    dx, dy = point[0] - x, point[1] - y
    return np.array([c * dx + s * dy, -s * dx + c * dy])


def sole_corners(pose: Tuple[float, float, float], sole: Sole) -> List[np.ndarray]:
    a, b = sole.half_length, sole.half_width
    return [to_world(pose, corner) for corner in ((a, b), (-a, b), (-a, -b), (a, -b))]


def convex_hull(points: List[np.ndarray]) -> List[np.ndarray]:
    """Counter-clockwise hull (Andrew's monotone chain)."""
    pts = sorted({(float(p[0]), float(p[1])) for p in points})
    if len(pts) <= 2:
        return [np.array(p) for p in pts]

    def cross(o, a, b) -> float:
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    lower: List[Tuple[float, float]] = []
    for p in pts:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], p) <= 0:
            lower.pop()
        lower.append(p)
    upper: List[Tuple[float, float]] = []
    for p in reversed(pts):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], p) <= 0:
            upper.pop()
        upper.append(p)
    return [np.array(p) for p in lower[:-1] + upper[:-1]]


def margin(point: np.ndarray, hull: List[np.ndarray]) -> float:
    """Signed distance from ``point`` to the hull's edge: positive inside, negative outside."""
    if len(hull) < 3:
        return -math.inf
    inside = math.inf
    for a, b in zip(hull, hull[1:] + hull[:1]):
        edge = b - a
        normal = np.array([-edge[1], edge[0]]) / float(np.linalg.norm(edge))  # inward (ccw)
        inside = min(inside, float(normal @ (point - a)))
    return inside


def support_margin(zmp: np.ndarray, poses: Dict[str, Tuple[float, float, float]],
                   contacts: Sequence[str], sole: Sole) -> float:
    corners = [c for side in contacts for c in sole_corners(poses[side], sole)]
    return margin(zmp, convex_hull(corners))


def rotation_rpy(roll: float, pitch: float, yaw: float) -> np.ndarray:
    cr, sr, cp, sp, cy, sy = (math.cos(roll), math.sin(roll), math.cos(pitch),
                              math.sin(pitch), math.cos(yaw), math.sin(yaw))
    return np.array([[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                     [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                     [-sp, cp * sr, cp * cr]])


@dataclass
class AttitudeLoop:
    """A PI loop on the pelvis IMU's roll and pitch: the tilt to command so that the pelvis
    stays level while the loaded legs' springs give."""

    proportional: float = 0.3
    integral: float = 2.0       # 1/s: 4 made a robot standing on the 5-cm kerb rock ever wider
    attitude: np.ndarray = field(default_factory=lambda: np.zeros(2))   # roll, pitch
    _sum: np.ndarray = field(default_factory=lambda: np.zeros(2))

    def update(self, dt: float, roll: float, pitch: float,
               proportional: bool = True) -> np.ndarray:
        """The pelvis tilt (roll, pitch) to command after ``dt`` s of reading ``roll, pitch``;
        ``proportional`` False: the integral alone (a robot standing still, see
        :meth:`walkman.modules.walking.Module.standing_still`)."""
        error = np.array([roll, pitch])
        self._sum = np.clip(self._sum - self.integral * error * dt, -MAX_ATTITUDE, MAX_ATTITUDE)
        gain = self.proportional if proportional else 0.0
        self.attitude = np.clip(self._sum - gain * error, -MAX_ATTITUDE, MAX_ATTITUDE)
        return self.attitude

    def turn(self, pitch: float) -> None:
        """The soles' commanded pitch turns by ``pitch`` under a pelvis that stays where it
        is (the soles seated as they rest): the commanded tilt turns with them at once, not
        after the IMU has seen the pelvis tip."""
        self._sum[1] = float(np.clip(self._sum[1] + pitch, -MAX_ATTITUDE, MAX_ATTITUDE))


@dataclass
class AnkleCompliance:
    """Damping control of one ankle (Kajita et al., "Biped walking stabilization based on
    linear inverted pendulum tracking", IROS 2010): the foot turns (roll, pitch, in its sole
    frame) at a rate proportional to how far its measured centre of pressure is from the
    desired one, and drifts back to flat when they agree.  A foot on its toe or heel thus
    comes back flat on the floor instead of tipping the robot; a foot that lands on its
    heel rolls flat."""

    gain: float = ANKLE_GAIN             # rad/s per m of CoP error
    time_constant: float = ANKLE_RETURN  # s
    angles: np.ndarray = field(default_factory=lambda: np.zeros(2))   # roll, pitch

    def update(self, dt: float, measured: Optional[Tuple[float, float]],
               desired: Tuple[float, float]) -> np.ndarray:
        """The foot's extra (roll, pitch) after ``dt``; ``measured`` None (foot in the air)
        lets it drift back to flat."""
        rate = -self.angles / self.time_constant
        if measured is not None:
            ex, ey = measured[0] - desired[0], measured[1] - desired[1]
            # CoP ahead of where it should be: toes up (pitch < 0); to the left: roll right.
            rate = rate + self.gain * np.array([ey, -ex])
        self.angles = np.clip(self.angles + rate * dt, -MAX_ANKLE, MAX_ANKLE)
        return self.angles


@dataclass
class BalanceGuard:
    """Trips once when the ZMP's margin or the torso's tilt stays unsafe for a while."""

    safe_margin: float = SAFE_MARGIN
    max_tilt: float = MAX_TILT
    trip_time: float = TRIP_TIME
    margin: float = math.nan
    tilt: float = 0.0
    tripped: Optional[str] = None
    _unsafe_since: Optional[float] = None
    _safe_since: Optional[float] = None

    def update(self, now: float, margin: Optional[float], tilt: float) -> Optional[str]:
        """Feed the figures; returns why, the first time the guard trips."""
        self.margin = math.nan if margin is None else margin
        self.tilt = tilt
        problem = None
        if margin is not None and margin < self.safe_margin:
            problem = (f"the measured ZMP is {margin * 100:.1f} cm from the edge of the feet "
                       f"(safe margin {self.safe_margin * 100:.0f} cm)")
        elif tilt > self.max_tilt:
            problem = (f"the torso is tilted {math.degrees(tilt):.0f} degrees "
                       f"(limit {math.degrees(self.max_tilt):.0f})")
        if problem is None:
            self._unsafe_since = None
            if self._safe_since is None:
                self._safe_since = now
            if self.tripped is not None and now - self._safe_since >= REARM_TIME:
                self.tripped = None
            return None
        self._safe_since = None
        if self._unsafe_since is None:
            self._unsafe_since = now
        if self.tripped is None and now - self._unsafe_since >= self.trip_time:
            self.tripped = problem
            return problem
        return None

    def reset(self) -> None:
        self.tripped = None
        self._unsafe_since = self._safe_since = None
