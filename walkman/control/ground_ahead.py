"""The ground ahead of the feet, from the head camera's cloud, and footsteps placed on it.

Theory of operation
-------------------
A pilot places footsteps in the 3-D view (walking's ``footsteps``); this places
them from what the camera sees.  Pure: points in, footsteps or a refusal out.

1. :func:`profile` -- the cloud's points in the pelvis frame (x ahead, z up) inside
   a strip along the walking line are binned every :data:`BIN` m ahead; a bin's
   height is the median of its points (a kerb's face and a stray point do not move
   it), a bin with fewer than :data:`MIN_POINTS` is unseen.  Runs of seen bins whose
   heights follow on (across at most :data:`GAP_BINS` unseen ones; each within
   :data:`JUMP` of the last two: a bin that holds both
   sides of an edge, half kerb and half floor, would otherwise bridge it) are *surfaces*, each
   fitted with a line (a ramp's slope is its pitch); a jump or an unseen stretch
   ends one, and a run that bends (the floor running on into a ramp) is cut where two
   lines fit it best, into pieces within :data:`BEND` of their own lines.  A run shorter
   than a sole between two edges, at a height between its neighbours', is a kerb's face
   seen edge-on and is dropped; any other short run stays a surface (floor seen before a
   dip is still floor), one no foot lands on.
2. :func:`place` -- the feet take turns along the line, each sole landing whole on
   one surface: its toes no further than the surface's seen end, its heel at least
   :data:`HEEL_MARGIN` past the seen start of one it crosses onto (the edge itself is
   in the bin between: 4-6 cm past it; from 4 cm short of a kerb's far edge, a 0.33-m
   step down landing 3 cm past it caught its heel under load, fc21 of 2026-11-28), a
   stride at most :data:`STRIDE` ahead of the standing foot.  At an
   edge the feet come together as close to it as the toes may go, then cross one by
   one, the second landing beside the first (as walking's ``step_up``: a long swing
   onto higher ground left the ZMP 3.5 mm inside the feet), rising or dropping at most
   :data:`MAX_RISE` (walking's reach).  A surface shorter than a sole, raised off ground
   that goes on level beyond it, is a thing lying there (a board): measured from the
   points across both feet's lanes (:func:`_measured_things`), it is stepped over
   (:func:`_over`), the toes and the heel :data:`OVER_MARGIN` off it, if a swinging foot
   clears it and a level step reaches over it.  Heights are
   taken relative to the surface under the feet, so a camera's height error cancels.
   The camera does not see under the toes: the first surface seen is taken to go on
   back under the feet if it begins within :data:`MAX_UNSEEN` of the toes and lies
   within :data:`MAX_OFFSET` of the soles' height and slopes as they stand (within
   :data:`MAX_BEND_PITCH`).  Seen within :data:`EDGE_AT_TOES` of the toes at another
   height or slope, it is an edge or a bend right there (the feet at a kerb's far edge, or
   at a ramp's foot); further, an edge or a bend may hide in the stretch not seen, and the
   footsteps are refused.

:func:`footsteps_from_cloud` is both, from a whole cloud: the strip between the soles'
lines, without what is far above or below them (looking down, the camera sees the
robot's own knees) or over the feet where they stand (their own tops, 8 cm up) -- and then

3. :func:`footing_problem` -- each footstep against what the camera sees under its own
   sole, not the strip between the feet: the points inside its outline (inset by
   :data:`FOOTPRINT_INSET`: an edge's bin is 0-2 cm beyond the toes) must lie on the
   sole's plane within :data:`CLEARANCE`.  More than
   :data:`STRAY_SHARE` of them above it is something the sole would land on (debris beside
   the walking line, or higher ground beside an edge); so are :data:`CLUMP_POINTS` of them
   above it packed within :data:`CLUMP_RADIUS` (a stone too small for the share); below
   it, ground that falls away under part of the sole (a side edge).  A footprint seen by fewer than
   :data:`MIN_FOOTPRINT_POINTS` is not judged (the camera does not see next to the feet;
   the strip's ground is taken to go on there, as under them).  The first footstep found
   wanting refuses the walk, before any foot lifts: where it is, how high, which way.

What it will not do is said, with where: an edge higher than the legs climb, a
surface too short to stand on, a far side beyond a step's reach, ground not seen.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np

from walkman.control.balance import Sole
from walkman.control.footsteps import Reach, Timing

#: m: bin length along the walking line, and the strip's half width around it
BIN = 0.02
STRIP_HALF_WIDTH = 0.10
#: points a bin needs to be seen, and how many unseen bins a surface may span (far
#: ground is sampled sparsely: every other bin empty)
MIN_POINTS = 3
GAP_BINS = 2
#: m: the most two neighbouring bins of one surface differ (a 10-degree ramp: 0.35 cm)
JUMP = 0.012
#: m: a run of bins further than this from its line bends (a ramp's foot: one line through
#: 0.4 m of floor and 0.6 m of 10-degree ramp misses both by 2 cm); it is cut in straight
#: pieces, none shorter than MIN_PIECE_BINS
BEND = 0.008
MIN_PIECE_BINS = 5
#: m: the sole's half length and half width
SOLE_HALF_LENGTH = Sole.half_length
SOLE_HALF_WIDTH = Sole.half_width
#: m: a sole's toes short of a surface's seen end, its heel past a seen start.  A bin that
#: holds an edge is in neither surface, so the real edge is 0-2 cm (:data:`BIN`) beyond
#: what is seen: the toes end 0-2 cm short of it, the heel lands 4-6 cm past it
TOE_MARGIN = 0.0
HEEL_MARGIN = 0.04
#: m: how far a foot lands ahead of the other along one surface (as walking's own
#: strides), and the most a step across an edge may reach (2 cm inside the legs' reach)
STRIDE = Timing.max_stride[0]
CROSS_REACH = Reach.ahead - 0.02
#: m: the most a step rises or drops (the legs' reach)
MAX_RISE = Reach.height
#: m: how far ahead of the toes the ground may first be seen (the body hides what is
#: nearer; it is taken to go on under the feet), and how far its height may be off the
#: soles' (a camera's error; more is an edge in the unseen stretch)
MAX_UNSEEN = 0.30
MAX_OFFSET = 0.03
#: m: ground seen this close to the toes at another height is an edge right there
EDGE_AT_TOES = 0.05
#: rad: ground pitched this much other than the soles stand bends between them and it
MAX_BEND_PITCH = 0.05
#: m: a stride that would leave less than this before an edge or the goal goes all the way
MIN_STEP = 0.03
#: m: points further above or below the soles are no ground a foot could reach (the
#: robot's own knees and hands, looked down at; a wall)
BAND = 0.3
#: m: how far past the front toes the robot's own body is seen, looking down (the PI's look
#: from the kerb's top saw the knees 0.06-0.08 m past them, 0.5 m up); beyond, a point
#: higher than :data:`BAND` under a footstep is an obstacle, not the robot
OWN_BODY_REACH = 0.25
#: m: ... and only up to this high: above, the hands hang (0.7-0.9 m up, and what they
#: hold, ahead of the toes), or something the legs pass under
OBSTACLE_TOP = 0.6
#: m: how far beyond the goal the ground is looked at (the last steps need their footing)
BEYOND = 1.0
#: m: the tallest thing lying on the ground a foot steps over (its swing clears
#: ``Timing.lift`` over the ground), and how far a sole stays off its ends
STEP_OVER = Timing.lift - 0.015
OVER_MARGIN = 0.04
OVER_REACH = Reach.level_ahead - 0.01
#: m: the most floor a thing lying there hides beyond it from the camera (a 2.5-cm board
#: seen from 2 m ahead of a camera 1.5 m up hides 3.3 cm); the floor goes on under it
MAX_SHADOW = 0.05
#: m: two soles this close along the line stand together
TOGETHER = 0.006
#: m: a footstep this much lower than the last is a step down a drop (a ramp's strides
#: fall 2.6 cm at 10 degrees; the kerb's is 5)
MIN_DROP = 0.03

#: m: a point inside a footstep's outline further than this above or below its sole's
#: plane is not ground the sole lands flat on (the lowest debris block is 2 cm high; the
#: simulated camera's points lie within 0.5 cm) -- or further than NOISE_SIGMAS times the
#: camera's own noise, measured on the strip (a stereo camera's: about 1 cm)
CLEARANCE = 0.015
NOISE_SIGMAS = 4.0
#: the share of a footprint's points that may be off the plane (stray points, a kerb's face)
STRAY_SHARE = 0.05
#: ... but this many points above it within this radius of one of them are a stone, however
#: small a share of the footprint (a 3.5-cm block is 3 % of a sole's points; the camera sees
#: 0.4-0.5 points per cm2 0.3-0.5 m ahead, so a 4-cm stone shows about five): stray points
#: of a camera's noise are scattered, not packed
CLUMP_POINTS = 4
CLUMP_RADIUS = 0.025
#: ... the share of all the points within that radius that must be raised, and how far
#: apart (m) the raised ones must reach
CLUMP_MAJORITY = 0.5
CLUMP_EXTENT = 0.015
#: m: the footprint judged, inset from the sole's outline on every side
FOOTPRINT_INSET = 0.01
#: points a footprint needs to be judged at all
MIN_FOOTPRINT_POINTS = 12
#: m: around the soles where the feet stand now, points are the robot's own feet and shins
#: -- but ahead, only just past the toes: what lies there is the ground a step goes onto
OWN_FOOT_MARGIN = 0.03
OWN_TOES_MARGIN = 0.005

Pose = Tuple[float, float, float, float, float, float]   # x y z roll pitch yaw


class GroundError(ValueError):
    """Footsteps cannot be placed on the ground seen; the text says where and why, and
    ``footstep`` which of the footsteps placed (1 on) the ground under it refused, if one."""

    def __init__(self, text: str, footstep: Optional[int] = None) -> None:
        super().__init__(text)
        self.footstep = footstep


@dataclass(frozen=True)
class Surface:
    """Ground a sole can stand on, from ``start`` to ``end`` (m ahead, pelvis frame)."""

    start: float
    end: float
    z0: float        # height at ``start``
    slope: float     # dz/dx

    def z(self, x: float) -> float:
        return self.z0 + self.slope * (x - self.start)

    @property
    def pitch(self) -> float:
        """A sole's pitch standing on it (negative where it rises ahead, as walking's)."""
        return -math.atan(self.slope)


def _strip_bins(points: np.ndarray, line_y: float, x_from: float, x_to: float,
                half_width: float) -> Tuple[np.ndarray, np.ndarray, int]:
    """The finite points of the strip along ``y = line_y`` from ``x_from`` to ``x_to``,
    each one's bin, and how many bins there are."""
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    points = points[np.isfinite(points).all(axis=1)]
    inside = (np.abs(points[:, 1] - line_y) <= half_width) & (points[:, 0] >= x_from) & \
        (points[:, 0] < x_to)
    strip = points[inside]
    count = max(1, int(math.ceil((x_to - x_from) / BIN)))
    return strip, np.minimum(((strip[:, 0] - x_from) / BIN).astype(int), count - 1), count


def profile(points: np.ndarray, line_y: float, x_from: float, x_to: float,
            half_width: float = STRIP_HALF_WIDTH) -> List[Surface]:
    """The surfaces along the walking line ``y = line_y`` from ``x_from`` to ``x_to``."""
    strip, index, count = _strip_bins(points, line_y, x_from, x_to, half_width)
    heights: List[Optional[float]] = []
    for k in range(count):
        z = strip[index == k, 2]
        heights.append(float(np.median(z)) if z.size >= MIN_POINTS else None)
    runs: List[List[int]] = []
    for k, height in enumerate(heights):
        if height is None:
            continue
        run = runs[-1] if runs and k - runs[-1][-1] <= 1 + GAP_BINS else None
        if run is not None and (abs(height - heights[run[-1]]) > JUMP or  # type: ignore
                                len(run) >= 2 and abs(height - heights[run[-2]]) > JUMP):
            # an edge; a bin before it half way up holds both sides (the face): in neither
            before, last = heights[run[-2]] if len(run) >= 2 else None, heights[run[-1]]
            if before is not None and (last - before) * (height - before) > 0 and \
                    abs(last - before) > JUMP / 2:            # type: ignore[operator]
                run.pop()
            run = None
        if run is None:
            runs.append([k])
        else:
            run.append(k)
    def level(run: List[int]) -> float:
        return float(np.median([heights[k] for k in run]))

    surfaces = []
    for i, run in enumerate(runs):
        start, end = x_from + run[0] * BIN, x_from + (run[-1] + 1) * BIN
        if end - start < 2 * SOLE_HALF_LENGTH and 0 < i < len(runs) - 1 and \
                runs[i - 1][-1] == run[0] - 1 and runs[i + 1][0] == run[-1] + 1 and \
                min(level(runs[i - 1]), level(runs[i + 1])) < level(run) < \
                max(level(runs[i - 1]), level(runs[i + 1])):
            continue                 # a kerb's face seen edge-on: heights in between
        for piece in _straight_pieces(run, heights, x_from):
            start, end = x_from + piece[0] * BIN, x_from + (piece[-1] + 1) * BIN
            slope, intercept = _line(piece, heights, x_from)
            surfaces.append(Surface(start, end, intercept + slope * start, slope))
    return surfaces


def _line(run: List[int], heights: Sequence[Optional[float]],
          x_from: float) -> Tuple[float, float]:
    """(slope, height at x = 0) of the line through the bins ``run``."""
    if len(run) < 2:
        return 0.0, float(heights[run[0]])  # type: ignore[arg-type]
    xs = x_from + (np.array(run) + 0.5) * BIN
    slope, intercept = np.polyfit(xs, [heights[k] for k in run], 1)
    return float(slope), float(intercept)


def _straight_pieces(run: List[int], heights: Sequence[Optional[float]],
                     x_from: float) -> List[List[int]]:
    """``run`` cut where it bends (a ramp's foot or top) into pieces of at least
    :data:`MIN_PIECE_BINS` bins, each within :data:`BEND` of its own line, each cut where
    two lines fit best -- or whole, if it cannot be cut so (a bump, a cable across the
    floor: no bend; the footing check judges a sole on it).  Heights are judged through a
    median of three bins, so one bin's bump bends nothing."""
    if len(run) < 2 * MIN_PIECE_BINS:
        return [run]                          # too short to hold two pieces
    raw = np.array([heights[k] for k in run], dtype=float)
    smooth = np.array([np.median(raw[max(0, i - 1):i + 2]) for i in range(len(raw))])
    pieces = _cut(x_from + (np.array(run) + 0.5) * BIN, smooth, 0, len(run))
    return [run[a:b] for a, b in pieces] if pieces else [run]


def _cut(xs: np.ndarray, zs: np.ndarray, begin: int, end: int) -> Optional[List[Tuple[int, int]]]:
    """The pieces ``[a, b)`` of ``begin..end`` each within :data:`BEND` of its line, cut
    where two lines fit best; None if some piece cannot be made so."""
    def fit(a: int, b: int) -> Tuple[float, float]:
        """(squared error, largest miss) of one line through ``a..b``."""
        line = np.polyval(np.polyfit(xs[a:b], zs[a:b], 1), xs[a:b])
        return float(np.sum((zs[a:b] - line) ** 2)), float(np.max(np.abs(zs[a:b] - line)))

    if fit(begin, end)[1] <= BEND:
        return [(begin, end)]
    if end - begin < 2 * MIN_PIECE_BINS:
        return None
    cut = min(range(begin + MIN_PIECE_BINS, end - MIN_PIECE_BINS + 1),
              key=lambda k: fit(begin, k)[0] + fit(k, end)[0])
    before, after = _cut(xs, zs, begin, cut), _cut(xs, zs, cut, end)
    return before + after if before is not None and after is not None else None


@dataclass
class _Foot:
    side: str
    x: float
    y: float
    surface: int


def place(surfaces: Sequence[Surface], soles: Dict[str, Pose],
          distance: float) -> List[Pose]:
    """Footsteps (sole poses in the pelvis frame, the feet taking turns, the rear one first)
    that walk the feet ``distance`` m ahead along the pelvis's x over ``surfaces``, ending
    side by side; :class:`GroundError` when the ground does not allow it."""
    return _place(surfaces, soles, distance)[0]


def _place(surfaces: Sequence[Surface], soles: Dict[str, Pose],
           distance: float) -> Tuple[List[Pose], float]:
    """:func:`place`, and how far the soles stand above the ground seen (the camera's
    error, which the footsteps' heights take out)."""
    if not surfaces:
        raise GroundError("no ground seen ahead of the feet")
    if not 0.0 < distance <= 5.0:
        raise GroundError(f"walk 0-5 m ahead, not {distance:g}")
    feet = {side: _Foot(side, float(pose[0]), float(pose[1]), 0) for side, pose in soles.items()}
    here = min(feet.values(), key=lambda foot: foot.x).x
    surfaces, offset = _from_under_the_feet(surfaces, soles)
    goal = here + distance
    steps: List[Pose] = []
    mover = min(feet.values(), key=lambda foot: (foot.x, foot.side != "left"))
    while len(steps) < 40:
        stand = next(foot for foot in feet.values() if foot is not mover)
        index = stand.surface
        surface = surfaces[index]
        last = surface.end - SOLE_HALF_LENGTH - TOE_MARGIN     # the toes short of its end
        limit = min(last, goal)
        x = stand.x + STRIDE
        if x >= limit - MIN_STEP:                             # no shuffle before a limit
            x = limit
        if mover.surface != index:      # the other foot across the edge: beside it, as
            x = stand.x                 # walking's step_up lands its second foot
        if x <= mover.x + 0.005:
            if stand.x < min(last, goal) - 0.005 or goal <= stand.x + 0.005:
                break                                         # side by side at the goal
            x, index = _across(surfaces, stand, here)         # together at the edge: over
        landing = surfaces[index]
        rise = landing.z(x) - surfaces[mover.surface].z(mover.x)
        if abs(rise) > MAX_RISE + 1e-9:
            raise GroundError(f"an edge {abs(rise) * 100:.0f} cm {'up' if rise > 0 else 'down'} "
                              f"{landing.start - here:.2f} m ahead: the legs climb at most "
                              f"{MAX_RISE * 100:.0f} cm")
        mover.x, mover.surface = x, index
        steps.append((x, mover.y, landing.z(x) + offset, 0.0, landing.pitch, 0.0))
        mover = stand
    return steps, offset


def _from_under_the_feet(surfaces: Sequence[Surface],
                         soles: Dict[str, Pose]) -> Tuple[List[Surface], float]:
    """The surfaces from under the feet on, and how far the soles stand above the ground
    seen (the camera's error): the camera does not see under the toes, so the first surface
    seen goes on back under the feet -- or the feet stand at an edge or a bend right
    there; :class:`GroundError` where what lies between is out of sight."""
    here = min(float(pose[0]) for pose in soles.values())
    toes = max(float(pose[0]) for pose in soles.values()) + SOLE_HALF_LENGTH
    ahead = [s for s in surfaces if s.end > toes]
    if not ahead or ahead[0].start > toes + MAX_UNSEEN:
        seen = f"only from {ahead[0].start - toes:.2f} m" if ahead else "nowhere"
        raise GroundError(f"the ground under the feet is not seen: the camera sees it {seen} "
                          f"ahead of the toes (at most {MAX_UNSEEN:.2f}): look down or walk on")
    # the camera cannot see under the toes: the first surface goes on back under the feet,
    # the soles' heights over it a camera's error, cancelled -- unless that is more than a
    # camera errs: seen right at the toes, it is an edge there (they stand at a kerb's
    # far edge); further, an edge may hide anywhere in the stretch not seen
    first = ahead[0]
    back = min(first.start, here - SOLE_HALF_LENGTH)
    own_pitch = float(np.mean([pose[4] for pose in soles.values()]))
    short = first.end - first.start < MIN_PIECE_BINS * BIN   # its slope is a few bins' noise
    if short:
        middle = (first.start + first.end) / 2
        first = Surface(first.start, first.end, first.z(middle) - math.tan(-own_pitch) *
                        (middle - first.start), math.tan(-own_pitch))
        ahead = [first, *ahead[1:]]
    under = replace(first, start=back, z0=first.z(back))
    offset = float(np.mean([soles[s][2] - under.z(soles[s][0]) for s in soles]))
    # ... unless it slopes other than the soles stand: then it bends somewhere out of sight
    bent = abs(first.pitch - own_pitch) > MAX_BEND_PITCH
    if abs(offset) <= MAX_OFFSET and not bent:
        surfaces = [under, *ahead[1:]]
    elif first.start - toes <= EDGE_AT_TOES:            # the edge, or the bend, at the toes
        own = Surface(here - SOLE_HALF_LENGTH, min(first.start, toes), 0.0,
                      -math.tan(own_pitch))
        sole = next(iter(soles.values()))
        bend = bent and abs(sole[2] - own.z(sole[0]) - first.z0 + own.z(own.end)) <= MAX_OFFSET
        if bend:      # no jump: the feet's ground meets the slope's start, a camera's error off
            own = replace(own, z0=first.z0 - own.z(own.end))
            offset = float(np.mean([pose[2] - own.z(pose[0]) for pose in soles.values()]))
        else:         # an edge: how high the feet stand above its foot is not seen
            own = replace(own, z0=sole[2] - own.z(sole[0]))
            offset = 0.0
        surfaces = [own, *ahead]
    elif bent:
        raise GroundError(f"the ground seen {first.start - toes:.2f} m ahead of the toes slopes "
                          f"{math.degrees(-first.pitch):+.0f} degrees where the feet stand at "
                          f"{math.degrees(-own_pitch):+.0f}: where the slope begins is out of "
                          f"sight; look from before it (a leg goes on over a bend) or place "
                          f"the footsteps by hand")
    else:
        raise GroundError(f"the ground seen {first.start - toes:.2f} m ahead of the toes is "
                          f"{-offset * 100:+.0f} cm from the soles' own: an edge out of sight "
                          f"or a camera out of calibration; place the footsteps by hand")
    return list(surfaces), offset


def _across(surfaces: Sequence[Surface], stand: _Foot, here: float) -> Tuple[float, int]:
    """Where the moving foot lands past the edge the standing foot is at: its heel
    :data:`HEEL_MARGIN` past it and on ground seen, the next surface's first footing
    (``here``: where the feet stand now, what a refusal says how far ahead from)."""
    after = stand.surface + 1
    standing = surfaces[stand.surface]
    edge = standing.end
    if after >= len(surfaces):
        raise GroundError(f"no ground seen beyond {edge - here:.2f} m ahead of the feet: the "
                          f"footsteps end at the edge")
    landing = surfaces[after]
    # the heel on ground seen, and 4 cm past the edge, which lies in the bin after the
    # standing surface's seen end (a drop's shadow, ground the kerb hides from the camera,
    # may already put the first ground seen further)
    x = max(landing.start, edge + BIN + HEEL_MARGIN) + SOLE_HALF_LENGTH
    if x - stand.x > CROSS_REACH:
        raise GroundError(f"the ground past the edge {edge - here:.2f} m ahead begins "
                          f"{landing.start - edge:.2f} m beyond it: a step reaches "
                          f"{CROSS_REACH:.2f} m")
    height = _lying_thing(surfaces, after)
    if height is not None:
        return _over(surfaces, stand, after, height, here)
    if x > landing.end - SOLE_HALF_LENGTH - TOE_MARGIN:
        length = landing.end - landing.start
        raise GroundError(f"the surface {landing.start - here:.2f} m ahead is {length:.2f} m "
                          f"long: too short for a sole and its margins")
    return x, after


def _lying_thing(surfaces: Sequence[Surface], index: int) -> Optional[float]:
    """How high the thing ``surfaces[index]`` is, if it is one lying on the ground: shorter
    than a sole, raised (or sunk: a groove) off the ground before it by more than
    :data:`JUMP`, that ground going on level beyond it; None if it is not such a thing."""
    if not 0 < index < len(surfaces) - 1:
        return None
    before, thing, beyond = surfaces[index - 1:index + 2]
    middle = (thing.start + thing.end) / 2
    height = thing.z(middle) - before.z(middle)
    if thing.end - thing.start < 2 * SOLE_HALF_LENGTH and abs(height) > JUMP and \
            abs(beyond.z(beyond.start) - before.z(beyond.start)) <= JUMP:
        return height
    return None


def _over(surfaces: Sequence[Surface], stand: _Foot, index: int, height: float,
          here: float) -> Tuple[float, int]:
    """Where the moving foot lands stepping over the thing ``surfaces[index]`` lying on the
    ground (a board, :func:`_lying_thing`), the standing foot's toes before it: its heel past
    the thing's far end by :data:`OVER_MARGIN` (:func:`_measured_things` measured both ends
    over both feet's lanes) on the ground beyond, within a step's reach; what it will not
    step over is refused, saying why."""
    thing, beyond = surfaces[index], surfaces[index + 1]
    length = thing.end - thing.start
    size = f"something {height * 100:.0f} cm high" if height > 0 else \
        f"a dip {-height * 100:.0f} cm deep"
    what = (f"{size} and {length * 100:.0f} cm long lies on the walking line "
            f"{thing.start - here:.2f} m ahead, the ground beyond it level with the feet's")
    if height < 0:
        raise GroundError(f"{what} (a groove?): footsteps from the camera do not step over a "
                          f"dip; place the footsteps by hand")
    if height > STEP_OVER:
        raise GroundError(f"{what} (debris?): a swinging foot clears "
                          f"{STEP_OVER * 100:.1f} cm; place the footsteps by hand")
    x = max(beyond.start, thing.end + OVER_MARGIN) + SOLE_HALF_LENGTH
    if x - stand.x > OVER_REACH:
        raise GroundError(f"{what} (debris?): stepping over it reaches "
                          f"{x - stand.x:.2f} m, a step at most {OVER_REACH:.2f}; clear it "
                          f"aside or place the footsteps by hand")
    if x > beyond.end - SOLE_HALF_LENGTH - TOE_MARGIN:
        raise GroundError(f"{what} (debris?): the ground seen past it, "
                          f"{beyond.end - beyond.start:.2f} m, is too short for a sole")
    return x, index + 1


def _measured_things(surfaces: List[Surface], points: np.ndarray, line_y: float,
                     half_width: float, clearance: float) -> List[Surface]:
    """``surfaces`` with each thing lying on the ground (:func:`_lying_thing`) measured
    from the points themselves, not the strip's bins: from the nearest to the furthest
    point raised off the ground before it by more than ``clearance``, across the lanes
    ``half_width`` either side of the walking line (a board lying aslant reaches further
    in a foot's lane than between the feet).  The ground before it then ends
    :data:`OVER_MARGIN` short of it, the ground beyond begins as far past it, so a toe
    stopping before it and a heel landing past it miss it by that much."""
    out = list(surfaces)
    for index in range(1, len(out) - 1):
        height = _lying_thing(out, index)
        if height is None or height < 0:
            continue
        before, thing, beyond = out[index - 1], out[index], out[index + 1]
        near = points[(np.abs(points[:, 1] - line_y) <= half_width) &
                      (points[:, 0] > before.end - 2 * BIN) &
                      (points[:, 0] < beyond.start + 2 * BIN)]
        raised = near[near[:, 2] - before.z(near[:, 0]) > clearance]
        if len(raised) < MIN_POINTS:
            continue
        start, end = float(raised[:, 0].min()), float(raised[:, 0].max())
        out[index - 1] = replace(before, end=min(before.end, start - OVER_MARGIN))
        out[index] = replace(thing, start=start, end=end, z0=thing.z(start))
        # the ground the thing hides from the camera, beyond it, is the ground going on
        after = end + OVER_MARGIN if beyond.start - end <= MAX_SHADOW else beyond.start
        out[index + 1] = replace(beyond, start=after, z0=beyond.z(after))
    return out


def footsteps_from_cloud(points: np.ndarray, soles: Dict[str, Pose],
                         distance: float) -> List[Pose]:
    """From a cloud in the pelvis frame to footsteps, the whole way: the strip along the
    line between the soles, from their heels to :data:`BEYOND` past the goal, without what
    lies more than :data:`BAND` above or below them; then each footstep's own ground,
    however far below the soles (a drop) and up to :data:`BAND` above them near the feet
    (higher, in the PI's looks, are the robot's own knees, 50 cm up over the first
    footstep), up to :data:`OBSTACLE_TOP` beyond :data:`OWN_BODY_REACH` past the toes (a
    tall box; higher are the robot's hands)."""
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    points = _without_own_feet(points[np.isfinite(points).all(axis=1)], soles)
    height = float(np.mean([pose[2] for pose in soles.values()]))
    line = float(np.mean([pose[1] for pose in soles.values()]))
    toes = max(pose[0] for pose in soles.values()) + SOLE_HALF_LENGTH
    above = points[:, 2] - height
    judged = points[(above <= BAND) |
                    ((points[:, 0] > toes + OWN_BODY_REACH) & (above <= OBSTACLE_TOP))]
    near = points[np.abs(above) <= BAND]
    x_from = min(pose[0] for pose in soles.values()) - SOLE_HALF_LENGTH
    x_to = max(pose[0] for pose in soles.values()) + distance + BEYOND
    clearance = max(CLEARANCE, NOISE_SIGMAS * camera_noise(near, line, x_from, x_to))
    lanes = max(abs(pose[1] - line) for pose in soles.values()) + SOLE_HALF_WIDTH
    surfaces = _measured_things(profile(near, line, x_from, x_to), near, line, lanes, clearance)
    steps, offset = _place(surfaces, soles, distance)
    here = min(pose[0] for pose in soles.values())
    for number, step in enumerate(steps, 1):
        problem = footing_problem(judged, step, offset, clearance)
        if problem:
            side = "left" if step[1] > line else "right"
            raise GroundError(f"footstep {number} ({side}, {step[0] - here:.2f} m ahead): "
                              f"{problem}; place the footsteps by hand", footstep=number)
    return steps


def _in_sole_frame(points: np.ndarray, sole: Pose) -> Tuple[np.ndarray, np.ndarray]:
    """How far each point lies ahead of the sole's centre along its yaw, and to its left."""
    dx, dy = points[:, 0] - sole[0], points[:, 1] - sole[1]
    cos, sin = math.cos(sole[5]), math.sin(sole[5])
    return cos * dx + sin * dy, cos * dy - sin * dx


def _without_own_feet(points: np.ndarray, soles: Dict[str, Pose]) -> np.ndarray:
    """``points`` but those over the feet where they stand (their tops, the shins): up to
    :data:`OWN_FOOT_MARGIN` around each sole, only :data:`OWN_TOES_MARGIN` past its toes."""
    for sole in soles.values():
        along, across = _in_sole_frame(points, sole)
        behind = -along > SOLE_HALF_LENGTH + OWN_FOOT_MARGIN
        ahead = along > SOLE_HALF_LENGTH + OWN_TOES_MARGIN
        beside = np.abs(across) > SOLE_HALF_WIDTH + OWN_FOOT_MARGIN
        points = points[behind | ahead | beside]
    return points


def camera_noise(points: np.ndarray, line_y: float, x_from: float, x_to: float,
                 half_width: float = STRIP_HALF_WIDTH) -> float:
    """The camera's height noise (m, one sigma) on the strip's ground: the median absolute
    deviation of the points from their bins' medians (edges and strays do not move it)."""
    strip, index, _ = _strip_bins(points, line_y, x_from, x_to, half_width)
    deviations = []
    for k in np.unique(index):
        z = strip[index == k, 2]
        if z.size >= MIN_POINTS:
            deviations.append(np.abs(z - np.median(z)))
    return 1.4826 * float(np.median(np.concatenate(deviations))) if deviations else 0.0


def footing_problem(points: np.ndarray, step: Pose, offset: float = 0.0,
                    clearance: float = CLEARANCE) -> str:
    """What is wrong with the ground the camera sees under the sole of ``step`` (a pose
    in the pelvis frame, its height ``offset`` above the cloud's), "" if nothing: see the
    module's theory, 3.  ``clearance``: how far off the sole's plane a point may lie."""
    z, pitch = step[2], step[4]
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    along, across = _in_sole_frame(points, step)
    inside = (np.abs(along) <= SOLE_HALF_LENGTH - FOOTPRINT_INSET) & \
        (np.abs(across) <= SOLE_HALF_WIDTH - FOOTPRINT_INSET)
    under = points[inside]
    if len(under) < MIN_FOOTPRINT_POINTS:
        return ""
    # the sole's plane, in the cloud's heights: it rises ahead by the pitch (walking's sign)
    rise = under[:, 2] - (z - offset - math.tan(pitch) * along[inside])
    above, below = rise[rise > clearance], rise[rise < -clearance]
    if len(above) > STRAY_SHARE * len(under):
        top = float(np.percentile(above, 90))
        return (f"{len(above) / len(under):.0%} of the ground seen under the sole stands up "
                f"to {top * 100:.0f} cm above where it would land: " +
                ("an obstacle taller than a step" if top > BAND else
                 "debris, or higher ground beside an edge"))
    clump = _clump(under[:, :2], rise > clearance)
    if clump is not None:
        return (f"{int(clump.sum())} points seen together under the sole, "
                f"{_extent(under[clump, :2]) * 100:.0f} cm across, stand up to "
                f"{float(rise[clump].max()) * 100:.0f} cm above where it would land: a stone "
                f"or debris")
    if len(below) > STRAY_SHARE * len(under):
        return (f"the ground falls away {-float(np.percentile(below, 10)) * 100:.0f} cm under "
                f"{len(below) / len(under):.0%} of the sole: an edge beside or under it")
    return ""


def _clump(points: np.ndarray, raised: np.ndarray) -> Optional[np.ndarray]:
    """Which of ``points`` (x, y) are a stone: the raised ones within :data:`CLUMP_RADIUS` of
    a raised one, if they are :data:`CLUMP_POINTS` or more, most of all the points seen
    around it (a camera's strays are scattered among the ground's points, however dense the
    cloud), and :data:`CLUMP_EXTENT` across or more (not one mismatched patch of pixels);
    None if no such group."""
    centres = np.flatnonzero(raised)
    if len(centres) < CLUMP_POINTS:
        return None
    near = np.linalg.norm(points[centres, None, :] - points[None, :, :], axis=2) <= CLUMP_RADIUS
    raised_near = near & raised[None, :]
    counts = raised_near.sum(axis=1)
    for index in np.argsort(-counts):
        if counts[index] < CLUMP_POINTS:
            return None
        if counts[index] > CLUMP_MAJORITY * near[index].sum() and \
                _extent(points[raised_near[index]]) >= CLUMP_EXTENT:
            return raised_near[index]
    return None


def _extent(points: np.ndarray) -> float:
    """The largest distance (m) between two of ``points`` (x, y)."""
    return float(np.linalg.norm(points[:, None, :] - points[None, :, :], axis=2).max())


def first_leg(steps: Sequence[Pose]) -> List[Pose]:
    """The footsteps up to where the feet next stand together -- at an edge, or the goal:
    what to walk before looking again.

    The top of a rise is best seen from its foot, so the leg ends there.  The ground past a
    drop is best seen from *before* it: from its edge the body hides the first 0.2 m beyond
    the toes (the PI's look from a kerb's far edge saw the floor only from 0.10 m on, and
    the footsteps down were refused), so the leg goes on over a drop, the second foot
    beside the first, placed by the look that found it.  So it does over a bend (a ramp's
    foot or top): from the bend the camera sees only the slope beyond, not where it
    begins; and over a thing lying on the ground (a board, :func:`_over`): from its foot
    the body hides it."""
    for end in range(2, len(steps) + 1):
        if abs(steps[end - 1][0] - steps[end - 2][0]) >= TOGETHER:
            continue
        if end < len(steps) and steps[end][2] < steps[end - 1][2] - MIN_DROP:
            continue                                  # together at a drop: on over it
        if end < len(steps) and abs(steps[end][4] - steps[end - 1][4]) > MAX_BEND_PITCH and \
                _along_the_slope(steps[end - 1], steps[end]):
            continue                                  # together at a bend: on over it
        if end < len(steps) and abs(steps[end][2] - steps[end - 1][2]) <= JUMP and \
                steps[end][0] - steps[end - 1][0] > STRIDE + TOGETHER:
            continue                   # together before a thing lying there: on over it
        return list(steps[:end])
    return list(steps)


def _along_the_slope(before: Pose, after: Pose) -> bool:
    """Whether the step from ``before`` to ``after`` rises or drops no more than the slopes
    they stand on account for (a bend), not by a kerb's height on top of them."""
    run = after[0] - before[0]
    slope = max(abs(math.tan(before[4])), abs(math.tan(after[4])))
    return abs(after[2] - before[2]) <= slope * run + MIN_DROP / 3
