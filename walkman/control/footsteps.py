"""Footsteps, swing-foot paths and the ZMP plan of a walk, in the walk's own frame (sans-IO).

Theory of operation
-------------------
Poses are planar ``(x, y, yaw)`` of a sole's centre in the *walk frame*: the
floor, fixed when the module starts, x ahead of the robot.  Feet that stand
do not slip, so the plan is also where the feet are.

A walk of ``(dx, dy, dyaw)`` is cut into ``m`` equal strides ``g`` within
the step limits.  The robot's centre frame goes ``C0, C1 = C0 g, ... Cm``; step
``k`` (``k = 1..m``) puts a foot at ``Ck * nominal(side)``, the feet taking
turns, and a last step brings the other foot beside it at ``Cm``: ``m + 1``
steps, both feet side by side at the end.  The first foot to move is the one on
the side the walk goes (left for a left turn or a step to the left).

Each step is two phases, and the walk ends with a third:

* *shift* (double support): the ZMP moves from where it is to the centre of the
  foot that will stand (the first shift of a walk is longer: the whole weight
  moves onto one leg);
* *swing* (single support): the ZMP stays on the stance foot, the swing foot
  rises by ``lift`` in the first fifth of the phase, travels while up and comes
  straight down in the last 30 % (landing vertically: a foot that skims the
  floor would carry weight and push the robot back);
* after the last step a final shift brings the ZMP between the feet, where it
  stays.

The ground need not be flat: each foot stands on a :class:`Ground` -- its
height above the walk frame's floor and its pitch (a ramp).  A walk on a ramp
goes on up (or down) its slope: each foot lands where the ground under the one
that stands would be, continued ahead.  A step that changes it (:meth:`WalkPlan.step_to`:
``step_up``/``step_down``; :meth:`WalkPlan.place`: footsteps a pilot placed)
rises to ``lift`` above the higher of its two grounds before it travels, so the
toe clears a kerb going up and the heel its edge going down, and comes straight
down onto the new ground.  :meth:`WalkPlan.ground_level` is the mean of the two
feet's grounds, the swing foot's taken along its travel: the pelvis rises and
sinks with it (the pendulum's height above the feet stays constant).  A sole may
rest otherwise than its ground says -- one that crept onto the bend at a ramp's foot
rests flatter than the slope: :meth:`WalkPlan.seat` turns its planned pitch to the
measured one (:attr:`Ground.seat`, the sole's, not continued ahead) and its next step sets
out from there.  Every
landing is checked against :class:`Reach` -- how far a foot can go from the
one that stands -- *before* the first foot lifts: a walk with a step the legs
cannot make is refused whole, saying which step and why.  A step onto
higher ground lands heel first and the weight waits on the other foot for
``Timing.foothold_wait`` while the walking module checks from the first touch that the
heel bears (:mod:`walkman.control.foothold`); :meth:`WalkPlan.retreat` puts a foot
whose heel does not bear back where it was.  A step down is watched on its way, and a sole
that meets the ground it leaves before its landing (a ``step_down`` sent before the kerb's
far edge) stays there and goes back (:meth:`WalkPlan.strike`).

:meth:`WalkPlan.zmp` samples that plan at any times (the preview controller of
:mod:`walkman.control.lipm` looks 1.6 s ahead).  :meth:`WalkPlan.halt` keeps
the step in the air (it must land) and sets the steps not started aside: the
walk then ends at the next double support with both feet down and the ZMP
between them -- the pilot's ``pause``, and the balance guard's stop.
:meth:`WalkPlan.resume` plays the steps set aside from where the feet are.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Dict, List, Optional, Tuple

import numpy as np

from walkman.control.foothold import WAIT as FOOTHOLD_WAIT
from walkman.control.trajectory import quintic

Planar = Tuple[float, float, float]  # x, y, yaw


@dataclass(frozen=True)
class Ground:
    """The ground under a sole: its height (m above the walk frame's floor) and its pitch
    (rad, the sole's pitch standing on it: negative where it rises ahead, a ramp up)."""

    z: float = 0.0
    pitch: float = 0.0
    #: rad the sole standing here rests pitched off the ground's own pitch, as measured
    #: (:meth:`WalkPlan.seat`: a sole that crept across the bend at a ramp's foot); the
    #: sole's, not the ground's: not continued ahead
    seat: float = 0.0

    @property
    def sole_pitch(self) -> float:
        """The pitch of a sole standing here."""
        return self.pitch + self.seat

    def ahead(self, distance: float) -> "Ground":
        """The same slope ``distance`` m further along it (horizontally)."""
        return Ground(self.z - distance * math.tan(self.pitch), self.pitch)


FLAT = Ground()
#: a step to play: the foot, where it lands, the ground there, its stride (or None)
Landing = Tuple[str, Planar, Ground, Optional[Planar]]
SIDES = ("left", "right")
RISE, DESCEND = 0.2, 0.7  # swing phases: up until RISE, travel, down from DESCEND
#: m: a foot swung further than this ahead of where it lifted strides over something (a
#: walk's foot travels at most twice its stride, 0.30)
LONG_SWING = 0.32
#: m along the standing sole within which a landing is beside it
BESIDE = 0.05
#: m, rad: grounds this close in height, in pitch, are the same ground to a step (a step
#: that rises or drops more climbs; one that drops more is a step down)
SAME_HEIGHT, SAME_PITCH = 0.005, 0.05


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


def midpoint(a: Planar, b: Planar) -> Planar:
    """Half-way between two poses (yaw by the shorter way)."""
    turn = math.atan2(math.sin(b[2] - a[2]), math.cos(b[2] - a[2]))
    return (a[0] + b[0]) / 2, (a[1] + b[1]) / 2, a[2] + turn / 2


def other(side: str) -> str:
    return "right" if side == "left" else "left"


@dataclass(frozen=True)
class Timing:
    """Durations (s) and sizes (m, rad) of the walk."""

    swing: float = 0.8            # single support
    shift: float = 0.4            # double support between two steps
    first_shift: float = 1.0      # the first weight shift of a walk
    last_shift: float = 0.8       # back between the feet at the end
    lift: float = 0.04            # swing foot clearance
    #: a step up or down swings this much longer (its foot goes further up and down, and
    #: lands late on the loaded, springy legs), and the weight shift after it is the slow one
    climb: float = 0.6
    #: s the weight waits on the standing foot after a step onto higher ground lands heel
    #: first, while the walking module checks that the heel bears
    #: (:mod:`walkman.control.foothold`); 0: lands flat, unchecked
    foothold_wait: float = FOOTHOLD_WAIT
    #: the ZMP stands this far inside the stance foot's centre, towards the other foot: the
    #: CoM then sways less, and compliance (which leans the robot outwards) has room
    inward: float = 0.01
    max_stride: Planar = (0.15, 0.06, 0.25)


@dataclass(frozen=True)
class Reach:
    """Where a landing sole's centre may be in the standing sole's frame (m, rad): the
    legs' reach with the knees bent as walking bends them.  Tried on the simulated robot:
    every stride the planner makes, and a 5-cm step up and down 0.33 m ahead (the ZMP at
    least 3.3 cm inside the feet, ``bench/bench_walking.py``); ``height`` leaves 3 cm of
    margin over that, what is higher is untried and refused.  ``width`` bounds the
    distance across (the feet are 0.14 m wide; ``cross`` is the least the planner's turns
    come to, the soles' edges then 2 cm apart at their closest)."""

    ahead: float = 0.36
    #: ... and onto ground level with the other foot's, swung slowly (:attr:`Step.strides_over`):
    #: over a board lying on the floor, 0.38 m tried (the debris field, tests/modules/
    #: test_walking.py)
    level_ahead: float = 0.40
    behind: float = 0.20
    cross: float = 0.12
    width: float = 0.34
    turn: float = 0.45
    height: float = 0.08
    #: rad: the steepest ground a sole stands on, and the most a step changes its pitch (a
    #: 10-degree ramp is 0.175)
    pitch: float = 0.2


@dataclass(frozen=True)
class Step:
    side: str                     # the foot that moves
    start: Planar                 # where it lifts off
    land: Planar                  # where it lands
    stride: Planar                # the centre frame's motion this step stands for
    shift_at: float               # double support begins: the ZMP moves to the stance foot
    lift_at: float                # single support begins
    land_at: float                # single support ends
    start_ground: Ground = FLAT   # the ground under it when it lifts off
    land_ground: Ground = FLAT    # and where it lands
    #: its landing on higher ground is checked (False: it lands beside a sole that was)
    check: bool = True
    #: swings as slowly as a step up or down (a foot going back where it lifted from,
    #: after it struck the ground it left)
    slow: bool = False
    #: a foot going back where it lifted from (:meth:`FootstepPlan.retreat`,
    #: :meth:`FootstepPlan.strike`): not watched for a strike on its way down -- it sets out
    #: from where it met ground, often above where it goes back to, and such a watch found
    #: the ground the foot stood on and put it back again, fifty times over
    returning: bool = False

    @property
    def start_z(self) -> float:
        return self.start_ground.z

    @property
    def land_z(self) -> float:
        return self.land_ground.z

    @property
    def climbs(self) -> bool:
        """The step goes up or down (more than 5 mm), or onto ground pitched otherwise."""
        return abs(self.land_z - self.start_z) > SAME_HEIGHT or \
            abs(self.land_ground.pitch - self.start_ground.pitch) > SAME_PITCH

    @property
    def strides_over(self) -> bool:
        """The foot travels further than a walk's swing (over a thing lying on the
        ground): it swings as slowly as a climb, so it keeps to its way down (at a walk's
        pace a foot swung 0.37 m came down 3 cm short of its plan, on a board's edge)."""
        return compose(inverse(self.start), self.land)[0] > LONG_SWING

    @property
    def checked_on_landing(self) -> bool:
        """The step lands on other ground than the one it left, continued, and not lower:
        onto a kerb, onto a ramp or its top (not a step up a ramp's slope, nor a step down):
        it lands heel first and the sole is checked (:mod:`walkman.control.foothold`).

        Not lower than the ground continued, nor than where it lifted: off a ramp's slope
        onto the floor at its foot, the floor lies above the slope continued, yet the step
        goes down -- watched on its way (:class:`walkman.control.foothold.DescentCheck`),
        onto ground that goes on back under the slope's end: no edge a heel could hang
        over.  Checked, a sole that touched there toes first (the swing leg placed in the
        commanded pelvis tilt, 2-3 degrees off the IMU's) was taken for a heel over an edge
        and put back, and the guard tripped (a PI run of the ramp down, 1 in 10)."""
        if not self.check or self.land_z < self.start_z - SAME_HEIGHT:
            return False
        ahead = compose(inverse(self.start), self.land)[0]
        continued = self.start_ground.ahead(ahead)
        rise = self.land_z - continued.z
        return rise > SAME_HEIGHT or (rise > -SAME_HEIGHT and
                                abs(self.land_ground.pitch - continued.pitch) > SAME_PITCH)

    def pitch(self, t: float) -> float:
        """The sole's pitch at ``t``: turned from the old ground's to the new one's on the
        way (before it comes down)."""
        a, b = self.start_ground.sole_pitch, self.land_ground.sole_pitch
        return a + self.travel(t) * (b - a)

    def travel(self, t: float) -> float:
        """How far along (0..1) its way the foot is at ``t``."""
        phase = min(max((t - self.lift_at) / (self.land_at - self.lift_at), 0.0), 1.0)
        return quintic((phase - RISE) / (DESCEND - RISE))


@dataclass
class WalkPlan:
    """Plans and plays walks; ``feet`` are where the soles stand (walk frame)."""

    feet: Dict[str, Planar]
    timing: Timing = field(default_factory=Timing)
    steps: List[Step] = field(default_factory=list)
    set_aside: List[Step] = field(default_factory=list)
    travelled: Planar = (0.0, 0.0, 0.0)
    #: the ground under each sole
    ground: Dict[str, Ground] = field(default_factory=lambda: {side: FLAT for side in SIDES})
    reach: Reach = field(default_factory=Reach)
    #: ZMP knots (t, x, y): linear between them, constant before the first and after the last
    _knots: List[Tuple[float, float, float]] = field(default_factory=list)
    #: the standing soles turning onto their seats (:meth:`seat`): from, until, and each
    #: one's pitch before
    _seating: Optional[Tuple[float, float, Dict[str, float]]] = None

    def __post_init__(self) -> None:
        left, right = self.feet["left"], self.feet["right"]
        #: half the distance between the feet standing side by side
        self.half_width = math.hypot(left[0] - right[0], left[1] - right[1]) / 2
        if not self._knots:
            centre = midpoint(self.feet["left"], self.feet["right"])
            self._knots = [(0.0, centre[0], centre[1])]

    # -- what the plan says --------------------------------------------------------------

    @property
    def walking(self) -> bool:
        return bool(self.steps)

    @property
    def halted(self) -> bool:
        """A walk was halted with steps left to play (:meth:`resume` plays them)."""
        return bool(self.set_aside)

    @property
    def centre(self) -> Planar:
        """Between the feet: the robot's place and heading when it stands."""
        return midpoint(self.feet["left"], self.feet["right"])

    def zmp(self, times: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
        """The planned ZMP (x, y) at each of ``times``."""
        knots = np.array(self._knots)
        return (np.interp(times, knots[:, 0], knots[:, 1]),
                np.interp(times, knots[:, 0], knots[:, 2]))

    def end_time(self) -> float:
        """When the plan's last motion (step or shift) ends."""
        return self._knots[-1][0]

    def foot(self, side: str, t: float) -> Tuple[Planar, float]:
        """A foot's planar pose and its sole's height above the floor at ``t``."""
        step = self._in_air(side, t)
        if step is None:
            return self.feet[side], self.ground[side].z
        phase = min((t - step.lift_at) / (step.land_at - step.lift_at), 1.0)
        travel = step.travel(t)
        a, b = step.start, step.land
        turn = math.atan2(math.sin(b[2] - a[2]), math.cos(b[2] - a[2]))
        pose = (a[0] + travel * (b[0] - a[0]), a[1] + travel * (b[1] - a[1]),
                a[2] + travel * turn)
        top = max(step.start_z, step.land_z) + self.timing.lift
        if phase < DESCEND:   # up from where it stood, then along at the top
            height = step.start_z + (top - step.start_z) * quintic(phase / RISE)
        else:                 # straight down onto where it lands
            height = top + (step.land_z - top) * quintic((phase - DESCEND) / (1.0 - DESCEND))
        return pose, height

    def foot_pitch(self, side: str, t: float) -> float:
        """The sole's pitch at ``t`` (the ground's where it stands, and its seat)."""
        step = self._in_air(side, t)
        if step is not None:
            return step.pitch(t)
        pitch = self.ground[side].sole_pitch
        if self._seating is not None and side in self._seating[2]:
            t0, t1, before = self._seating
            pitch = before[side] + (pitch - before[side]) * quintic((t - t0) / (t1 - t0))
        return pitch

    @property
    def heights(self) -> Dict[str, float]:
        """Each sole's ground height (m)."""
        return {side: ground.z for side, ground in self.ground.items()}

    def ground_level(self, t: float) -> float:
        """The mean of the feet's grounds at ``t``, a swing foot's taken along its travel:
        the height the pelvis keeps its crouch above."""
        level = 0.0
        for side in SIDES:
            step = self._in_air(side, t)
            level += self.ground[side].z if step is None else \
                step.start_z + step.travel(t) * (step.land_z - step.start_z)
        return level / len(SIDES)

    def _in_air(self, side: str, t: float) -> Optional[Step]:
        """The step of ``side`` under way at ``t`` (lifted, not yet landed for the plan)."""
        for step in self.steps:
            if step.side == side and t >= step.lift_at:
                return step
        return None

    def in_air(self, t: float) -> Optional[Step]:
        """The step whose foot is in the air at ``t`` (None in double support)."""
        for step in self.steps:
            if step.lift_at <= t < step.land_at:
                return step
        return None

    def swinging(self, t: float) -> Optional[str]:
        """The foot in the air at ``t`` (None in double support)."""
        step = self.in_air(t)
        return None if step is None else step.side

    # -- planning ----------------------------------------------------------------------

    def settle(self, start: Tuple[float, float], t0: float, t1: float) -> None:
        """Before any walk: the ZMP goes from ``start`` (where the CoM stands when the
        module starts) to between the feet, from ``t0`` to ``t1``."""
        centre = self.centre
        self._knots = [(t0, float(start[0]), float(start[1])), (t1, centre[0], centre[1])]

    def seat(self, pitches: Dict[str, float], t0: float, t1: float) -> None:
        """The standing soles rest pitched ``pitches`` (measured), not as their grounds say:
        from ``t0`` to ``t1`` each one's planned pitch turns to it, and its steps set out from
        it.  Only standing, before a walk: a step then lifts after ``t1``."""
        if self.steps:
            raise ValueError("the soles are seated standing, not while walking")
        self._seating = (t0, t1, {side: self.foot_pitch(side, t0) for side in pitches})
        self.ground = {side: replace(ground, seat=pitches[side] - ground.pitch)
                       if side in pitches else ground for side, ground in self.ground.items()}

    def nominal(self, centre: Planar, side: str) -> Planar:
        """Where the ``side`` foot stands in a centre frame (feet side by side)."""
        return compose(centre, (0.0, self.half_width if side == "left" else -self.half_width,
                                0.0))

    def plan(self, dx: float, dy: float, dyaw: float, t: float) -> int:
        """Plan a walk of (dx, dy, dyaw) in the robot's centre frame; returns its steps."""
        if self.steps:
            raise ValueError("already walking: wait for the walk to end")
        if not all(math.isfinite(v) for v in (dx, dy, dyaw)):
            raise ValueError("the walk must be finite numbers")
        self.set_aside = []
        limits = self.timing.max_stride
        strides = max(1, max(math.ceil(abs(v) / limit - 1e-9)
                             for v, limit in zip((dx, dy, dyaw), limits)))
        stride = (dx / strides, dy / strides, dyaw / strides)
        centre = self.centre
        side = "left" if (dy > 0 or (dy == 0 and dyaw >= 0)) else "right"
        landings: List[Landing] = []
        for index in range(strides + 1):
            if index < strides:
                centre = compose(centre, stride)
            landings.append((side, self.nominal(centre, side), None,
                             stride if index < strides else (0.0, 0.0, 0.0)))
            side = other(side)
        return self._play(landings, t)

    def step_to(self, forward: float, height: float, t: float) -> int:
        """Onto ground ``height`` higher (lower if negative) ``forward`` ahead: the left
        foot lands there, the right one beside it (``step_up``/``step_down``)."""
        if not all(math.isfinite(v) for v in (forward, height)):
            raise ValueError("the step must be finite numbers")
        ahead = compose(self.centre, (forward, 0.0, 0.0))
        heights = self.heights.values()
        level = max(heights) if height >= 0 else min(heights)
        # The kerb runs across the walk: the right sole lands beside the left one, as far past
        # its edge, and only the left one's landing is checked (checking both cost the step
        # a centimetre of ZMP margin: the weight's second wait, tried)
        return self._play([(side, self.nominal(ahead, side), Ground(level + height), None)
                           for side in SIDES], t, check_first_only=True)

    def place(self, footsteps: List[Tuple[float, float, float, float, float]],
              t: float) -> int:
        """Play footsteps a pilot placed: each ``(x, y, yaw, z, pitch)`` of a sole's centre
        in the walk frame, the feet taking turns, the first the one on the side of the first
        footstep (left of the line between the feet or right)."""
        if not footsteps:
            raise ValueError("no footsteps")
        if not all(math.isfinite(v) for footstep in footsteps for v in footstep):
            raise ValueError("the footsteps must be finite numbers")
        first = compose(inverse(self.centre), footsteps[0][:3])
        side = "left" if first[1] >= 0 else "right"
        landings: List[Landing] = []
        for x, y, yaw, z, pitch in footsteps:
            landings.append((side, (x, y, yaw), Ground(z, pitch), None))
            side = other(side)
        return self._play(landings, t)

    def _play(self, landings: List[Landing], t: float, check_first_only: bool = False) -> int:
        """Check every landing against :attr:`reach` from the foot that will stand, then
        schedule them all; returns the number of steps.  A landing's ground is, if not
        given, the standing foot's continued to where it lands (level ground stays level,
        a ramp goes on); its stride (the odometry it stands for), if not given, how far it
        moves the point between the feet.  ``check_first_only``: the landings after the first
        go beside it, and only its landing is checked (:attr:`Step.check`).  Nor is one
        landing beside the standing sole (within :data:`BESIDE` along it) on the ground
        that sole stands on: it bears there (footsteps up a kerb, the second foot beside
        the first, as ``step_up``'s: checked too, its wait left the ZMP 1.7 cm inside the
        feet, 3.0 without)."""
        if self.steps:
            raise ValueError("already walking: wait for the walk to end")
        feet, ground = dict(self.feet), dict(self.ground)
        steps: List[Step] = []
        for number, (side, land, land_ground, stride) in enumerate(landings, 1):
            stance = feet[other(side)]
            if land_ground is None:
                ahead = compose(inverse(stance), land)[0]
                land_ground = ground[other(side)].ahead(ahead)
            problem = self.unreachable(side, land, land_ground, stance, ground[other(side)])
            if problem:
                raise ValueError(f"step {number} of {len(landings)} ({side} foot) cannot "
                                 f"be made: {problem}")
            before, start = midpoint(feet["left"], feet["right"]), feet[side]
            feet[side] = land
            if stride is None:
                stride = compose(inverse(before), midpoint(feet["left"], feet["right"]))
            # beside the standing sole, on the ground it stands on: that ground bears
            beside = abs(compose(inverse(stance), land)[0]) < BESIDE and \
                abs(land_ground.z - ground[other(side)].z) < SAME_HEIGHT and \
                abs(land_ground.pitch - ground[other(side)].pitch) < SAME_PITCH
            steps.append(Step(side, start, land, stride, 0.0, 0.0, 0.0, ground[side],
                              land_ground, check=(number == 1 or not check_first_only) and
                              not beside))
            ground[side] = land_ground
        self.set_aside = []
        self._schedule(steps, t)
        return len(steps)

    def unreachable(self, side: str, land: Planar, land_ground: Ground, stance: Planar,
                    stance_ground: Ground) -> str:
        """Why the ``side`` sole cannot land at ``land`` (on ``land_ground``) from the other
        one standing at ``stance`` -- '' if it can."""
        reach = self.reach
        x, y, yaw = compose(inverse(stance), land)
        across = y if side == "left" else -y
        turn = math.atan2(math.sin(yaw), math.cos(yaw))
        rise = land_ground.z - stance_ground.ahead(x).z   # over what the slope gives
        level = abs(land_ground.z - stance_ground.z) <= SAME_HEIGHT and \
            abs(land_ground.pitch - stance_ground.pitch) <= SAME_PITCH
        ahead = reach.level_ahead if level else reach.ahead
        if x > ahead:
            return f"{x:.2f} m ahead of the other foot (at most {ahead:.2f})"
        if x < -reach.behind:
            return f"{-x:.2f} m behind the other foot (at most {reach.behind:.2f})"
        if across < reach.cross:
            return (f"{across:.2f} m beside the other foot: the feet would touch "
                    f"(at least {reach.cross:.2f})")
        if across > reach.width:
            return f"{across:.2f} m beside the other foot (at most {reach.width:.2f})"
        if abs(turn) > reach.turn:
            return f"turned {turn:.2f} rad from the other foot (at most {reach.turn:.2f})"
        if abs(rise) > reach.height:
            return (f"{abs(rise):.2f} m {'above' if rise > 0 else 'below'} the other foot "
                    f"(at most {reach.height:.2f})")
        if abs(land_ground.pitch) > reach.pitch:
            return (f"on ground pitched {abs(land_ground.pitch):.2f} rad (at most "
                    f"{reach.pitch:.2f})")
        if abs(land_ground.pitch - stance_ground.pitch) > reach.pitch:
            return (f"pitched {abs(land_ground.pitch - stance_ground.pitch):.2f} rad from the "
                    f"other foot (at most {reach.pitch:.2f})")
        return ""

    def _schedule(self, steps: List[Step], t: float, from_standing: bool = True) -> None:
        """Give ``steps`` their times from ``t`` on and rebuild the ZMP plan (the first
        weight shift is the slow one when the robot starts ``from_standing``)."""
        timing = self.timing
        zmp_x, zmp_y = (float(v[0]) for v in self.zmp(np.array([t])))
        knots = [k for k in self._knots if k[0] < t] + [(t, zmp_x, zmp_y)]
        feet = dict(self.feet)
        for step in self.steps:   # a step in the air lands first
            feet[step.side] = step.land
        now = max(t, self.steps[-1].land_at if self.steps else t)
        timed: List[Step] = []
        for index, step in enumerate(steps):
            after_climb = bool(timed) and timed[-1].climbs
            shift = timing.first_shift if (index == 0 and from_standing) or after_climb \
                else timing.shift
            swing = timing.swing + (timing.climb if step.climbs or step.slow or
                                    step.strides_over else 0.0)
            stance = compose(feet[other(step.side)],
                             (0.0, timing.inward if step.side == "left" else -timing.inward,
                              0.0))
            timed.append(replace(step, shift_at=now, lift_at=now + shift,
                                 land_at=now + shift + swing))
            knots += [(now + shift, stance[0], stance[1]),
                      (now + shift + swing, stance[0], stance[1])]
            feet[step.side] = step.land
            now += shift + swing
            if step.checked_on_landing and timing.foothold_wait > 0:
                # the weight waits on the standing foot while the landed sole is checked
                now += timing.foothold_wait
                knots.append((now, stance[0], stance[1]))
        centre = midpoint(feet["left"], feet["right"])
        knots.append((now + timing.last_shift, centre[0], centre[1]))
        self.steps += timed
        self._knots = knots

    # -- playing ----------------------------------------------------------------------------

    def update(self, t: float) -> List[Step]:
        """Advance to ``t``; returns the steps that landed since the last call."""
        landed = []
        while self.steps and t >= self.steps[0].land_at:
            step = self.steps.pop(0)
            self.feet = {**self.feet, step.side: step.land}
            self.ground = {**self.ground, step.side: step.land_ground}
            self.travelled = compose(self.travelled, step.stride)
            landed.append(step)
        return landed

    def halt(self, t: float) -> None:
        """End the walk soon, both feet down and side by side: a step in the air lands; if
        the feet are then apart, one *closing* step brings the next foot beside the other
        (the ZMP keeps the walk's rhythm: changing where it goes while the CoM swings
        towards the next stance foot would throw the robot sideways); the ZMP goes back
        between the feet.  The steps not taken are set aside for :meth:`resume`."""
        flying = [step for step in self.steps if step.lift_at <= t]
        rest = [step for step in self.steps if step.lift_at > t]
        if not rest:
            return
        feet, ground = dict(self.feet), dict(self.ground)
        for step in flying:
            feet[step.side], ground[step.side] = step.land, step.land_ground
        side = rest[0].side
        beside = self.beside(feet[other(side)], side)
        apart = math.hypot(beside[0] - feet[side][0], beside[1] - feet[side][1]) > 0.01 or \
            abs(beside[2] - feet[side][2]) > 0.02 or \
            abs(ground["left"].z - ground["right"].z) > SAME_HEIGHT or \
            abs(ground["left"].pitch - ground["right"].pitch) > 0.01
        # Once its weight shift has begun, the next step is taken (in place if the feet
        # are together): turning the CoM back at once would be the same jolt.  Halfway up
        # (or down) a step, the closing step joins the foot already there.
        closing = [replace(rest[0], start=feet[side], land=beside, stride=(0.0, 0.0, 0.0),
                           start_ground=ground[side],
                           land_ground=replace(ground[other(side)], seat=0.0))] \
            if apart or rest[0].shift_at <= t else []
        self.set_aside = rest + self.set_aside
        self.steps = flying
        zmp_x, zmp_y = (float(v[0]) for v in self.zmp(np.array([t])))
        if closing and rest[0].shift_at <= t:
            # its weight shift has begun: keep its times and ZMP knots, land beside
            self.steps += closing
            feet[side] = beside
            end = closing[0].land_at
        else:
            end = max([t] + [step.land_at for step in flying])
        kept = [k for k in self._knots if t < k[0] <= end]
        centre = midpoint(feet["left"], feet["right"])
        self._knots = [k for k in self._knots if k[0] < t] + [(t, zmp_x, zmp_y)] + kept + \
            [(end + self.timing.last_shift, centre[0], centre[1])]
        if closing and rest[0].shift_at > t:
            self._schedule(closing, end, from_standing=False)

    def beside(self, foot: Planar, side: str) -> Planar:
        """Where the ``side`` foot stands beside ``foot`` (the other one), feet together."""
        return self.nominal(self.nominal(foot, side), side)   # via the centre frame

    def resume(self, t: float) -> int:
        """Play the steps :meth:`halt` set aside, from ``t``; returns how many."""
        if self.steps:
            raise ValueError("still walking: wait for the halt to finish")
        steps, self.set_aside = self.set_aside, []
        if not steps:
            return 0
        # The first step set aside may have been planned from a foot that landed since.
        steps[0] = replace(steps[0], start=self.feet[steps[0].side],
                           start_ground=self.ground[steps[0].side])
        self._schedule(steps, t)
        return len(steps)

    def retreat(self, step: Step, t: float) -> int:
        """``step`` landed where its sole does not bear: drop the rest of the walk and put
        the foot back where it lifted from (from ``t``, the weight still on the other foot);
        returns the number of steps (1)."""
        self.steps, self.set_aside = [], []
        feet = {**self.feet, step.side: step.start}
        stride = compose(inverse(self.centre), midpoint(feet["left"], feet["right"]))
        # where the foot stood a moment ago: no reach to check
        self._schedule([Step(step.side, self.feet[step.side], step.start, stride, 0.0, 0.0,
                             0.0, self.ground[step.side], step.start_ground,
                             returning=True)], t)
        return 1

    def strike(self, step: Step, t: float) -> int:
        """``step``'s sole met ground on its way down, above where it was going (a step down
        sent before the kerb's far edge): from ``t`` it stands where it is, on what it met,
        and goes back where it lifted from, the weight still on the other foot; the rest of
        the walk is dropped; returns the number of steps (1)."""
        where, height = self.foot(step.side, t)
        # The sole lags the plan coming down: what it met is at least the ground it left
        # (touching a 5-cm kerb's top, the plan had it 1.3 cm above the floor); held at the
        # plan's height, the leg would go on pressing down into it
        met = Ground(max(height, step.start_z), step.pitch(t))
        self.steps, self.set_aside = [], []
        self.feet = {**self.feet, step.side: where}
        self.ground = {**self.ground, step.side: met}
        # where it stood a moment ago (no reach to check, nor its landing: it stood there)
        self._schedule([Step(step.side, where, step.start, (0.0, 0.0, 0.0), 0.0, 0.0, 0.0,
                             met, step.start_ground, check=False, slow=True,
                             returning=True)], t,
                       from_standing=False)
        return 1

    def cancel(self, t: float) -> None:
        """Halt and forget the rest of the walk."""
        self.halt(t)
        self.set_aside = []
