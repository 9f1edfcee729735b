"""walkman.control.ground_ahead: surfaces from a cloud, footsteps on them, refusals with where."""

from __future__ import annotations

import math
import re
from dataclasses import replace
from pathlib import Path
from typing import Callable, Dict, List

import numpy as np
import pytest
from hypothesis import example, given, settings, strategies as st

from walkman.control.ground_ahead import (CLUMP_POINTS, CROSS_REACH, FOOTPRINT_INSET,
                                          HEEL_MARGIN, MAX_RISE, OVER_MARGIN, OVER_REACH,
                                          SOLE_HALF_LENGTH, SOLE_HALF_WIDTH, STEP_OVER,
                                          STRAY_SHARE, TOE_MARGIN,
                                          GroundError, Pose, Surface,
                                          first_leg, footing_problem, footsteps_from_cloud,
                                          place, profile)
from walkman.control.ground_ahead import _without_own_feet

FLOOR = -1.03          # the soles' height in the pelvis frame, standing
SOLES: Dict[str, Pose] = {"left": (0.03, 0.11, FLOOR, 0.0, 0.0, 0.0),
                          "right": (0.03, -0.11, FLOOR, 0.0, 0.0, 0.0)}


def cloud(height: Callable[[float], float], x_to: float = 2.2, faces: List[float] = (),
          seed: int = 1) -> np.ndarray:
    """Ground points every 1 cm ahead (0.25 m on), 3 cm across, 2 mm of noise; points on
    the face at each x in ``faces`` (a kerb seen from above); a few strays."""
    rng = np.random.default_rng(seed)
    xs, ys = np.meshgrid(np.arange(0.25, x_to, 0.01), np.arange(-0.2, 0.21, 0.03))
    zs = np.vectorize(height)(xs) + rng.normal(0, 0.002, xs.shape)
    points = [np.stack([xs.ravel(), ys.ravel(), zs.ravel()], axis=1)]
    for x in faces:
        low, high = sorted((height(x - 0.005), height(x + 0.005)))
        fz, fy = np.meshgrid(np.arange(low, high, 0.005), np.arange(-0.2, 0.21, 0.03))
        points.append(np.stack([np.full(fz.size, x), fy.ravel(), fz.ravel()], axis=1))
    strays = np.column_stack([rng.uniform(0.3, x_to, 5), rng.uniform(-0.1, 0.1, 5),
                              rng.uniform(-0.5, 0.5, 5)])
    return np.concatenate(points + [strays, [[np.nan, np.nan, np.nan]]])


def kerb(start: float, end: float, rise: float) -> Callable[[float], float]:
    return lambda x: FLOOR + (rise if start <= x < end else 0.0)


def check_walk(steps: List[Pose], surfaces: List[Surface], soles=SOLES) -> None:
    """Every footstep: the sides take turns, each sole whole on one surface within its
    margins, at its height, never further than a step reaches from the other foot."""
    feet = {side: pose[0] for side, pose in soles.items()}
    side = "left" if steps[0][1] > 0 else "right"
    # the first surface goes on back under the feet (the camera does not see there)
    surfaces = [replace(surfaces[0], start=-1.0, z0=surfaces[0].z(-1.0)), *surfaces[1:]]
    for x, y, z, roll, pitch, yaw in steps:
        assert (y > 0) == (side == "left")
        other = feet["right" if side == "left" else "left"]
        assert x - other <= CROSS_REACH + 1e-9 and x >= feet[side] - 1e-9
        on = [s for s in surfaces if s.start + SOLE_HALF_LENGTH <= x + 1e-9 and
              x <= s.end - SOLE_HALF_LENGTH - TOE_MARGIN + 1e-9]
        assert len(on) == 1, (x, surfaces)
        assert z == pytest.approx(on[0].z(x), abs=0.006) and roll == yaw == 0.0
        assert pitch == pytest.approx(on[0].pitch)
        feet[side] = x
        side = "right" if side == "left" else "left"
    assert abs(steps[-1][0] - steps[-2][0]) < 0.006       # they end side by side


def test_a_kerb_seen_from_above_is_three_surfaces_at_their_heights():
    surfaces = profile(cloud(kerb(0.6, 1.4, 0.05), faces=[0.6, 1.4]), 0.0, -0.1, 2.2)
    # the bin holding a face is neither surface's (it mixes their heights)
    assert [(round(s.start, 2), round(s.end, 2)) for s in surfaces] == \
        [(0.24, 0.6), (0.62, 1.4), (1.42, 2.2)]
    assert [s.z(s.start + 0.1) for s in surfaces] == \
        pytest.approx([FLOOR, FLOOR + 0.05, FLOOR], abs=0.002)
    assert all(abs(s.slope) < 0.01 for s in surfaces)


def test_up_a_kerb_along_it_and_down_the_far_side():
    surfaces = profile(cloud(kerb(0.6, 1.4, 0.05), faces=[0.6, 1.4]), 0.0, -0.1, 2.2)
    steps = place(surfaces, SOLES, 1.8)
    check_walk(steps, surfaces)
    # strides of 0.15 (walking's own; one of 0.18 rather than a 3-cm shuffle), together
    # with the toes at the last floor bin before the kerb's face (0.60: 0-2 cm from it),
    # over it heel 6 cm past the edge, the second foot beside the first, along, together
    # at the far edge (1.40), down, on to the goal side by side
    assert [round(step[0], 2) for step in steps] == \
        [0.18, 0.33, 0.47, 0.47, 0.79, 0.79, 0.94, 1.09, 1.27, 1.27, 1.59, 1.59, 1.74, 1.83,
         1.83]
    assert [round(step[2] - FLOOR, 2) for step in steps] == [0.0] * 4 + [0.05] * 6 + [0.0] * 5


def test_a_drop_s_shadow_puts_the_heel_on_the_first_ground_seen_past_it():
    """Looking down from a kerb, the floor just past its far edge is hidden by the kerb
    (6 cm of it, the click test of 2026-11-28): the heel lands on the first floor seen,
    which is more than 4 cm past the edge already, and within a step's reach."""
    points = cloud(kerb(-1.0, 0.8, 0.05))
    points = points[(points[:, 0] < 0.8) | (points[:, 0] >= 0.86)]
    on_kerb = {side: (x, y, z + 0.05, *rest) for side, (x, y, z, *rest) in SOLES.items()}
    surfaces = profile(points, 0.0, -0.1, 2.2)
    steps = place(surfaces, on_kerb, 0.9)
    check_walk(steps, surfaces, on_kerb)
    down = next(step for step in steps if step[2] < FLOOR + 0.01)
    assert down[0] - SOLE_HALF_LENGTH == pytest.approx(0.86, abs=0.005)


def test_a_leg_ends_at_the_foot_of_a_rise_and_goes_on_over_a_drop():
    """Look, walk a leg, look again: the top of a rise is best seen from its foot; the
    ground past a drop from before it (from its edge the body hides it)."""
    surfaces = profile(cloud(kerb(0.6, 1.4, 0.05), faces=[0.6, 1.4]), 0.0, -0.1, 2.2)
    steps = place(surfaces, SOLES, 1.8)
    legs = []
    while steps:
        legs.append([round(step[0], 2) for step in first_leg(steps)])
        steps = steps[len(legs[-1]):]
    assert legs == [[0.18, 0.33, 0.47, 0.47],                  # together at the kerb's foot
                    [0.79, 0.79],                              # up: look along its top
                    [0.94, 1.09, 1.27, 1.27, 1.59, 1.59],      # along, and down its far side
                    [1.74, 1.83, 1.83]]


DATA = Path(__file__).parent / "data"


def pi_look(name: str):
    """A cloud the PI's click test took (``tests/system/pi_driver.py``'s camera_leg: the
    80 x 30 points of the lower half of a 640 x 480 render over the DRC link, the head bent
    to 0.985 rad) with the joint state it was taken at: in the pelvis frame, and the soles."""
    from walkman.control.kinematics import Kinematics
    from walkman.head_camera import optical_to
    from walkman.modules.walking import sole_poses

    look, kinematics = np.load(DATA / name), Kinematics()
    points = optical_to(look["xyz"], *kinematics.pose(look["posture"], "multisense_frame"))
    return points, sole_poses(kinematics, look["posture"])


def test_the_pis_look_from_the_kerbs_top_places_the_steps_down_its_far_side():
    """On the terrain station's kerb, 5 cm up, its far edge 0.5 m ahead: the look from
    the feet up on the kerb sees the floor past the edge, and the leg walks there and down,
    the heels at least 4 cm past the edge.  From the edge itself the body hides the floor
    for 0.10 m past the toes, and the look is refused -- the look before was the one to go
    down by."""
    points, soles = pi_look("pi-look-from-the-kerb-top.npz")
    top = float(np.mean([pose[2] for pose in soles.values()]))
    leg = first_leg(footsteps_from_cloud(points, soles, 1.0))
    assert [round(step[2] - top, 2) for step in leg] == [0.0] * 4 + [-0.05] * 2, leg
    surfaces = profile(points, 0.0, 0.0, 1.5)
    edge = next(s.end for s in surfaces if abs(s.z(s.end) - top) < 0.01)
    assert all(step[0] - SOLE_HALF_LENGTH >= edge + HEEL_MARGIN for step in leg[4:]), (edge, leg)
    points, soles = pi_look("pi-look-from-the-far-edge.npz")
    with pytest.raises(GroundError, match="an edge out of sight"):
        footsteps_from_cloud(points, soles, 0.4)


def test_the_pis_look_at_the_debris_lane_is_refused_naming_what_lies_in_the_way():
    """Station ``debris`` through the PI: a block of the lane lies across the walking line
    between the feet, 0.37 m ahead.  The strip's profile sees it as a 2-cm surface 3-4 cm up
    with the floor on both sides -- not ground to stand on, not an edge to climb: something
    lying there, measured across both feet's lanes, too high for a swinging foot to clear:
    refused with its size and where."""
    points, soles = pi_look("pi-look-at-debris.npz")
    for distance in (0.3, 1.0):
        with pytest.raises(GroundError, match=r"^something [34] cm high and [23] cm long lies "
                                              r"on the walking line 0\.3[78] m ahead.*"
                                              r"\(debris\?\): a swinging foot clears 2\.5 cm"):
            footsteps_from_cloud(points, soles, distance)


@pytest.mark.parametrize("ground, what", [
    (kerb(0.6, 0.62, 0.04), "something 4 cm high and 2 cm long lies on the walking line 0.57 m"),
    (kerb(0.6, 0.62, -0.04), "a dip 4 cm deep and 2 cm long lies on the walking line 0.57 m"),
    # the ground beyond 2 cm higher than the feet's: a short surface between two edges
    (lambda x: FLOOR + (0.05 if 0.6 <= x < 0.7 else 0.02 if x >= 0.7 else 0.0),
     "the surface 0.57 m ahead is 0.10 m long: too short for a sole"),
])
def test_a_short_bump_or_dip_with_level_ground_beyond_is_named_not_called_a_surface(ground,
                                                                                  what):
    """A block, a cable, a groove across the way: shorter than a sole, the ground beyond it
    as high as the feet's.  With ground at another height beyond, or longer than a sole (a
    low platform: ``test_what_cannot_be_walked_is_refused_with_where``), it is a surface too
    short for a sole."""
    with pytest.raises(GroundError, match="^" + re.escape(what)):
        place(profile(cloud(ground), 0.0, -0.1, 2.2), SOLES, 1.0)


def board(at: float, width: float, height: float = 0.02,
          yaw: float = 0.0) -> Callable[[float, float], float]:
    """A board lying across the way: its near edge ``at`` m ahead on the walking line,
    ``width`` wide, turned ``yaw`` from square to the way (its edges run along
    x = at + y tan(yaw))."""
    def ground(x: float, y: float = 0.0) -> float:
        near = at + y * math.tan(yaw)
        return FLOOR + (height if near <= x < near + width / math.cos(yaw) else 0.0)
    return ground


def board_cloud(ground: Callable[[float, float], float]) -> np.ndarray:
    """:func:`cloud`'s points over ground whose height varies across the way as well."""
    points = cloud(lambda x: FLOOR)
    points[:, 2] += [ground(x, y) - FLOOR if np.isfinite(x) else 0.0
                     for x, y in points[:, :2]]
    return points


@settings(max_examples=30)
@given(at=st.floats(0.45, 1.2), width=st.floats(0.03, 0.04), yaw=st.floats(-0.025, 0.025))
@example(at=0.45, width=0.04, yaw=0.025)
def test_a_board_lying_across_the_way_is_stepped_over_each_sole_clear_of_it(at, width, yaw):
    """Issue 66, debris: a board 2 cm high lying across the way, 3-4 cm wide (narrower, the
    strip's 2-cm bins take it for a bump, and the footing check refuses a sole on it),
    nearly square to it (its edges 5 cm apart at most across both feet's lanes), the floor
    before it seen (the camera sees from 0.2 m past the toes).  The feet come together
    before it, then each steps over it in one step within a level step's reach, every
    sole at least :data:`OVER_MARGIN` off the board in its own lane (less the cloud's 1-cm
    spacing); the first leg goes on over it -- from its foot the body hides it -- and ends
    with the feet together past it."""
    ground = board(at, width, yaw=yaw)
    steps = footsteps_from_cloud(board_cloud(ground), SOLES, 1.4)
    feet = {"left": SOLES["left"][0], "right": SOLES["right"][0]}
    crossings = 0
    for x, y, *_ in steps:
        side, other = ("left", "right") if y > 0 else ("right", "left")
        lane = [y - SOLE_HALF_WIDTH, y + SOLE_HALF_WIDTH]
        near = at + min(v * math.tan(yaw) for v in lane)
        far = at + max(v * math.tan(yaw) for v in lane) + width / math.cos(yaw)
        clear = OVER_MARGIN - 0.011
        assert x + SOLE_HALF_LENGTH <= near - clear or x - SOLE_HALF_LENGTH >= far + clear, \
            (x, near, far, steps)
        if feet[side] < near <= x:
            crossings += 1
            assert x - feet[other] <= OVER_REACH + 1e-9, (x, feet, steps)
        feet[side] = x
    assert crossings == 2, steps
    leg = first_leg(steps)
    assert min(step[0] for step in leg[-2:]) - SOLE_HALF_LENGTH > at, leg
    assert abs(leg[-1][0] - leg[-2][0]) < 0.006, leg


@pytest.mark.parametrize("ground, why", [
    (board(0.6, 0.04, height=STEP_OVER + 0.01),
     r"\(debris\?\): a swinging foot clears 2\.5 cm"),
    (board(0.6, 0.12), r"\(debris\?\): stepping over it reaches 0\.4\d m, a step at most "
                       r"0\.39; clear it aside"),
])
def test_a_board_too_high_or_too_wide_to_step_over_is_refused_saying_why(ground, why):
    """Higher than a swinging foot clears over the ground, or wider than a level step
    reaches over: refused before a foot lifts, with what lies where and why."""
    with pytest.raises(GroundError, match=r"^something \d cm high and \d+ cm long lies on the "
                                          r"walking line 0\.\d\d m ahead.*" + why):
        footsteps_from_cloud(board_cloud(ground), SOLES, 1.4)


def test_a_patch_of_floor_seen_between_two_stretches_not_seen_is_no_dip():
    """The floor seen only in a 4-cm patch (the stretches before and after it not seen): the
    patch is no lower than the feet's ground -- not named as something lying there."""
    points = cloud(lambda x: FLOOR)
    points = points[((points[:, 0] < 0.58) | (points[:, 0] >= 0.66)) &
                    ((points[:, 0] < 0.70) | (points[:, 0] >= 0.78))]
    with pytest.raises(GroundError) as refused:
        place(profile(points, 0.0, -0.1, 2.2), SOLES, 1.0)
    assert "a dip" not in str(refused.value) and "something" not in str(refused.value)


def test_a_camera_that_reads_the_ground_2_cm_high_places_the_same_footsteps():
    true = place(profile(cloud(kerb(0.6, 1.4, 0.05)), 0.0, -0.1, 2.2), SOLES, 1.8)
    biased = place(profile(cloud(kerb(0.6, 1.4, 0.05)) + [0, 0, 0.02], 0.0, -0.1, 2.2),
                   SOLES, 1.8)
    assert np.allclose(np.array(true), np.array(biased), atol=0.004)


def test_a_ramp_is_a_surface_of_its_own_whose_slope_pitches_the_soles():
    """The floor runs on into the ramp without a jump: one line through both misses each
    by 2 cm (a sole pitched by their mean lands on its heel on the floor, on its toes on
    the ramp).  The run is cut at the bend: the floor, level, and the ramp, 10 degrees."""
    slope = math.tan(math.radians(10))
    ground = lambda x: FLOOR + max(0.0, x - 0.7) * slope   # noqa: E731
    surfaces = profile(cloud(ground, x_to=1.6), 0.0, -0.1, 1.6)
    assert [(round(s.start, 2), round(s.end, 2)) for s in surfaces] == [(0.24, 0.7), (0.7, 1.6)]
    assert [s.pitch for s in surfaces] == pytest.approx([0.0, -math.radians(10)], abs=0.01)
    steps = place(surfaces, SOLES, 1.0)
    check_walk(steps, surfaces)
    on_the_ramp = [step for step in steps if step[0] - SOLE_HALF_LENGTH > 0.7]
    assert on_the_ramp and all(step[4] == pytest.approx(-math.radians(10), abs=0.01)
                               for step in on_the_ramp)
    assert all(step[4] == pytest.approx(0.0, abs=0.01) for step in steps
               if step[0] + SOLE_HALF_LENGTH <= 0.7)
    # each footstep lands flat on the ground it is placed on (theory, 3)
    from_cloud = footsteps_from_cloud(cloud(ground, x_to=2.2), SOLES, 1.0)
    assert np.allclose(np.array(from_cloud), np.array(steps), atol=0.005)


@given(bend=st.floats(0.4, 1.2), degrees=st.floats(-12, 12), distance=st.floats(0.3, 1.5))
def test_any_bend_is_walked_with_every_sole_flat_on_the_ground_or_refused(bend, degrees,
                                                                         distance):
    """Floor, then a slope up or down from ``bend``: the footing check (theory, 3) finds no
    sole off its ground -- one line through both would pitch them wrong."""
    slope = math.tan(math.radians(degrees))
    ground = lambda x: FLOOR + max(0.0, x - bend) * slope   # noqa: E731
    points = cloud(ground, x_to=3.0)
    try:
        footsteps_from_cloud(points, SOLES, distance)
    except GroundError as exc:           # never a sole planned off the ground it lands on
        assert exc.footstep is None, str(exc)


@pytest.mark.parametrize("ground, distance, problem", [
    (kerb(0.6, 1.4, 0.12), 1.0, "an edge 12 cm up 0.57 m ahead: the legs climb at most 8 cm"),
    (kerb(0.6, 0.9, 0.05), 1.0, "is 0.30 m long: too short for a sole and its margins"),
    (kerb(0.6, 1.4, 0.05), 2.5, "no ground seen beyond"),
])
def test_what_cannot_be_walked_is_refused_with_where(ground, distance, problem):
    surfaces = profile(cloud(ground), 0.0, -0.1, 2.2)
    with pytest.raises(GroundError, match=problem):
        place(surfaces, SOLES, distance)


def test_a_gap_wider_than_a_step_reaches_is_refused():
    points = cloud(lambda x: FLOOR)
    points = points[(points[:, 0] < 0.8) | (points[:, 0] > 1.1)]   # a ditch, unseen
    with pytest.raises(GroundError, match=r"begins 0\.30 m beyond it: a step reaches 0\.34 m"):
        place(profile(points, 0.0, -0.1, 2.2), SOLES, 1.5)


def test_ground_not_seen_under_the_feet_is_refused():
    with pytest.raises(GroundError, match="the ground under the feet is not seen"):
        place(profile(cloud(lambda x: FLOOR), 0.0, 0.6, 2.2), SOLES, 1.0)
    with pytest.raises(GroundError, match="no ground seen ahead"):
        place([], SOLES, 1.0)


@given(start=st.floats(0.45, 1.2), length=st.floats(0.35, 1.0),
       rise=st.one_of(st.just(0.0), st.floats(0.02, 0.1), st.floats(-0.1, -0.02)),
       distance=st.floats(0.2, 2.4))
def test_any_kerb_is_walked_within_the_rules_or_refused_with_a_reason(start, length, rise,
                                                                      distance):
    surfaces = profile(cloud(kerb(start, start + length, rise), x_to=3.0), 0.0, -0.1, 3.0)
    try:
        steps = place(surfaces, SOLES, distance)
    except GroundError as exc:
        assert str(exc)
        return
    if steps:
        check_walk(steps, surfaces)
        heights = [step[2] for step in steps]
        assert max(abs(b - a) for a, b in zip([FLOOR] + heights, heights)) <= MAX_RISE + 0.006
        assert max(b[0] - a[0] for a, b in zip(steps, steps[1:])) <= CROSS_REACH + 1e-9


def with_block(points: np.ndarray, x: float, y: float, size: float, height: float,
               depth: float = 0.0) -> np.ndarray:
    """``points`` where ground inside the square (``size`` a side, centred at x, y) is
    raised by ``height`` (debris; negative: a hole), or beyond ``y`` when ``size`` is 0
    (higher or lower ground to the left from ``x`` on: a side edge)."""
    points = points.copy()
    if size:
        inside = (np.abs(points[:, 0] - x) <= size / 2) & (np.abs(points[:, 1] - y) <= size / 2)
    else:
        inside = (points[:, 0] >= x) & (points[:, 1] >= y)
    points[inside, 2] += height
    return points


def raised_in_outline(points: np.ndarray, step: Pose, raised: np.ndarray) -> np.ndarray:
    """``raised`` for the points inside a footstep's judged outline (inset, yaw 0)."""
    inside = (np.abs(points[:, 0] - step[0]) <= SOLE_HALF_LENGTH - FOOTPRINT_INSET) & \
        (np.abs(points[:, 1] - step[1]) <= SOLE_HALF_WIDTH - FOOTPRINT_INSET)
    return raised[inside]


def footprint_share(points: np.ndarray, step: Pose, raised: np.ndarray) -> float:
    """The share of a footstep's judged outline whose points were raised."""
    under = raised_in_outline(points, step, raised)
    return float(under.mean()) if under.size else 0.0


def raised_under(points: np.ndarray, step: Pose, raised: np.ndarray) -> int:
    """How many of a footstep's judged points were raised."""
    return int(raised_in_outline(points, step, raised).sum())


def test_debris_under_a_sole_beside_the_walking_line_is_refused_before_a_foot_lifts():
    """The strip between the feet sees flat floor; the left sole's own ground holds a
    4-cm block: the walk is refused, naming the footstep, its side, where and how high."""
    flat = cloud(lambda x: FLOOR)
    assert len(footsteps_from_cloud(flat, SOLES, 1.2)) > 4
    # the block is outside the strip the surfaces are taken from (|y| <= 0.10)
    assert len(profile(with_block(flat, 0.75, 0.145, 0.06, 0.04), 0.0, -0.1, 2.2)) == 1
    with pytest.raises(GroundError, match=r"footstep \d+ \(left, 0\.\d\d m ahead\): \d+% of the "
                       r"ground seen under the sole stands up to 4 cm above where it would "
                       r"land: debris.*place the footsteps by hand"):
        footsteps_from_cloud(with_block(flat, 0.75, 0.145, 0.06, 0.04), SOLES, 1.2)
    # short of the block, the walk is made
    assert footsteps_from_cloud(with_block(flat, 0.75, 0.145, 0.06, 0.04), SOLES, 0.3)


@pytest.mark.parametrize("height, problem", [
    (0.05, r"stands up to 5 cm above where it would land: debris, or higher ground beside an "
           r"edge"),
    (-0.10, r"the ground falls away 10 cm under \d+% of the sole: an edge beside or under it"),
])
def test_a_side_edge_under_the_left_soles_is_refused(height, problem):
    """From 0.5 m on, the ground left of y = 0.14 is higher (or lower): the left soles
    would land half on it."""
    edged = with_block(cloud(lambda x: FLOOR), 0.5, 0.135, 0.0, height)
    with pytest.raises(GroundError, match=r"footstep \d+ \(left, .*" + problem):
        footsteps_from_cloud(edged, SOLES, 1.2)


def test_the_robots_own_feet_are_not_debris():
    """Looking down, the camera sees the feet where they stand, 8 cm high: the first
    footsteps overlap those outlines, and are not refused for them."""
    flat = cloud(lambda x: FLOOR, x_to=2.2)
    feet = []
    for sole in SOLES.values():
        fx, fy = np.meshgrid(np.arange(sole[0] - 0.13, sole[0] + 0.131, 0.01),
                             np.arange(sole[1] - 0.07, sole[1] + 0.07, 0.01))
        feet.append(np.column_stack([fx.ravel(), fy.ravel(), np.full(fx.size, FLOOR + 0.08)]))
    seen = np.concatenate([flat, *feet])
    steps = footsteps_from_cloud(seen, SOLES, 1.0)
    assert steps == footsteps_from_cloud(flat, SOLES, 1.0)
    assert "debris" in footing_problem(seen, steps[0])       # the feet, were they not left out


def test_a_turned_sole_is_judged_on_its_own_outline():
    """A footstep turned 90 degrees lies across the way: a block under its toes is refused,
    one beside it (inside the outline it would have facing ahead) is not."""
    flat = cloud(lambda x: FLOOR)
    step = (0.75, 0.11, FLOOR, 0.0, 0.0, math.pi / 2)
    assert footing_problem(flat, step) == ""
    assert "debris" in footing_problem(with_block(flat, 0.75, 0.11 + 0.09, 0.05, 0.04), step)
    assert footing_problem(with_block(flat, 0.75 + 0.09, 0.11, 0.05, 0.04), step) == ""


def test_a_turned_foot_where_it_stands_is_left_out_along_its_own_outline():
    """The top of a foot turned 90 degrees reaches 13 cm to its left; ground 12 cm to its
    right is no longer under it."""
    sole = (0.03, 0.11, FLOOR, 0.0, 0.0, math.pi / 2)
    fx, fy = np.meshgrid(np.arange(-0.07, 0.071, 0.01), np.arange(-0.13, 0.131, 0.01))
    top = np.column_stack([0.03 + fx.ravel(), 0.11 + fy.ravel(), np.full(fx.size, FLOOR + 0.08)])
    beside = np.array([[0.03 + 0.12, 0.11, FLOOR]])
    kept = _without_own_feet(np.concatenate([top, beside]), {"left": sole})
    assert kept.tolist() == beside.tolist()


def test_a_stone_too_small_for_the_stray_share_is_refused():
    """A 3.5-cm stone under the left sole is 4 % of its points, under the stray share; its
    points are packed together, not scattered as strays are."""
    flat = cloud(lambda x: FLOOR)
    stone = with_block(flat, 0.755, 0.14, 0.035, 0.03)
    step = (0.75, 0.11, FLOOR, 0.0, 0.0, 0.0)
    raised = stone[:, 2] > flat[:, 2] + 0.01
    assert 0 < footprint_share(stone, step, raised) < STRAY_SHARE
    assert re.fullmatch(r"\d points seen together under the sole, [23] cm across, stand up to 3 "
                        r"cm above where it would land: a stone or debris",
                        footing_problem(stone, step))
    scattered = flat.copy()
    inside = np.flatnonzero((np.abs(flat[:, 0] - 0.75) < 0.11) &
                            (np.abs(flat[:, 1] - 0.11) < 0.05))
    scattered[inside[::len(inside) // 4][:4], 2] += 0.03    # as many strays, far apart
    assert footing_problem(scattered, step) == ""
    # the height said is the stone's own, not a stray's elsewhere under the sole
    stray = np.array([[0.66, 0.08, FLOOR + 0.25]] +          # (with ground seen beside it,
                     [[0.66 + 0.005 * i, 0.09, FLOOR] for i in range(4)])   # under 5 %)
    assert "stand up to 3 cm above" in footing_problem(np.concatenate([stone, stray]), step)


def test_a_dense_noisy_camera_s_strays_and_a_patch_of_bad_pixels_are_no_stone():
    """A camera four times as dense as the simulated one, its heights heavy-tailed (1 cm):
    its strays come packed by density alone, but among many ground points; four mismatched
    pixels 1 mm apart are no stone either."""
    rng = np.random.default_rng(7)
    step = (0.75, 0.11, FLOOR, 0.0, 0.0, 0.0)
    clearance = 0.04                                    # 4 sigma of the camera's noise
    refused = 0
    for _ in range(40):
        xy = np.column_stack([rng.uniform(0.62, 0.88, 1300), rng.uniform(0.04, 0.18, 1300)])
        z = FLOOR + 0.01 * rng.standard_t(3, len(xy))
        refused += footing_problem(np.column_stack([xy, z]), step, clearance=clearance) != ""
    assert refused == 0
    ground = np.column_stack([xy, np.full(len(xy), FLOOR)])
    patch = np.array([[0.75 + 0.001 * i, 0.12, FLOOR + 0.05] for i in range(4)])
    assert footing_problem(np.concatenate([ground, patch]), step) == ""


@pytest.mark.parametrize("x, height, refused", [(0.75, 0.40, True), (0.30, 0.40, False),
                                               (0.75, 0.85, False)])
def test_a_box_taller_than_the_legs_reach_is_refused_where_it_is_no_knee(x, height, refused):
    """Points 40 cm up under a footstep 0.6 m ahead are a box; 0.14 m past the toes, where
    looking down the camera sees the robot's own knees, they are left out, and so are
    points 85 cm up further on (the hands, or what they hold)."""
    flat = cloud(lambda x: FLOOR)
    boxed = with_block(flat, x, 0.145, 0.06, height)
    if refused:
        with pytest.raises(GroundError, match=r"footstep \d+ \(left, .*stands up to 40 cm "
                                              r"above where it would land: an obstacle taller "
                                              r"than a step"):
            footsteps_from_cloud(boxed, SOLES, 1.2)
    else:
        assert footsteps_from_cloud(boxed, SOLES, 1.2) == footsteps_from_cloud(flat, SOLES, 1.2)


def test_a_footprint_the_camera_barely_sees_is_not_judged():
    sparse = with_block(cloud(lambda x: FLOOR), 0.75, 0.145, 0.06, 0.04)
    step = (0.75, 0.11, FLOOR, 0.0, 0.0, 0.0)
    assert "debris" in footing_problem(sparse, step)
    near = np.abs(sparse[:, 0] - 0.75) < 0.05               # 5 x 4 points left under it
    assert footing_problem(sparse[~near | (np.arange(len(sparse)) % 10 == 0)], step) == ""


@settings(derandomize=True, max_examples=60)
@given(x=st.floats(0.3, 1.5), y=st.floats(-0.2, 0.2), size=st.floats(0.03, 0.12),
       height=st.floats(0.02, 0.08))
@example(x=0.755, y=0.155, size=0.04, height=0.03)   # a stone under the stray share
def test_debris_is_refused_exactly_where_a_sole_would_land_on_it(x, y, size, height):
    """Any block on flat ground: walked with every sole's outline (bar a stray share) clear
    of it, or refused.  A block beside the strip between the feet is refused by the
    footstep whose sole lands on it; one in the strip is ground seen, and may be taken for
    a kerb, the floor's tilt or the camera's error (all refused, on the safe side)."""
    flat = cloud(lambda x: FLOOR)
    littered = with_block(flat, x, y, size, height)
    raised = littered[:, 2] > flat[:, 2] + 0.01
    try:
        steps = footsteps_from_cloud(littered, SOLES, 1.5)
    except GroundError as exc:
        if abs(y) - size / 2 < 0.10:        # in the strip: ground seen, whatever it is taken for
            return
        assert exc.footstep is not None, str(exc)
        found = re.search(r"footstep (\d+) \((left|right), ", str(exc))
        assert found and int(found.group(1)) == exc.footstep, str(exc)
        step = place(profile(littered, 0.0, -0.1, 2.53), SOLES, 1.5)[exc.footstep - 1]
        assert (step[1] > 0) == (found.group(2) == "left")
        assert footprint_share(littered, step, raised) > STRAY_SHARE or \
            raised_under(littered, step, raised) >= CLUMP_POINTS, (step, str(exc))
        return
    assert all(footprint_share(littered, step, raised) <= STRAY_SHARE + 0.01
               for step in steps), steps
    # nor a stone 4 cm along and 3 cm across under any sole: a row of 4 points at least
    for step in steps:
        along, across = (min(x + size / 2, step[0] + SOLE_HALF_LENGTH - FOOTPRINT_INSET) -
                         max(x - size / 2, step[0] - SOLE_HALF_LENGTH + FOOTPRINT_INSET),
                         min(y + size / 2, step[1] + SOLE_HALF_WIDTH - FOOTPRINT_INSET) -
                         max(y - size / 2, step[1] - SOLE_HALF_WIDTH + FOOTPRINT_INSET))
        assert along < 0.04 or across < 0.03, (step, along, across)


def test_a_cable_across_the_floor_bends_nothing():
    """A 1-cm strip 2 cm wide across the way is no bend: one bin's bump is smoothed away
    (cut around it, the floor became a 6-degree piece too short to step onto)."""
    cable = lambda x: FLOOR + (0.01 if 0.9 <= x < 0.92 else 0.0)   # noqa: E731
    assert all(abs(s.pitch) < 0.02 for s in profile(cloud(cable), 0.0, -0.1, 2.2))
    assert len(footsteps_from_cloud(cloud(cable), SOLES, 1.5)) > 8


@pytest.mark.parametrize("depth", [0.25, 0.35, 1.0])
def test_a_drop_beside_the_walking_line_is_refused_however_deep(depth):
    """The ground beyond y = 0.105 falls away from 0.5 m on: the left soles would land half
    over it -- refused, even deeper than the strip's band (a platform's edge)."""
    with pytest.raises(GroundError, match=rf"footstep \d+ \(left, .* falls away {depth * 100:.0f} "
                                          r"cm under"):
        footsteps_from_cloud(with_block(cloud(lambda x: FLOOR), 0.5, 0.105, 0.0, -depth),
                             SOLES, 1.2)


def test_on_a_kerb_top_with_its_far_edge_near_the_toes_the_walk_goes_down():
    """Standing on a kerb, its far edge 4-5 cm past the toes: the kerb's top seen is two
    bins, whose slope is noise -- not a bend (the feet would have been sent onto a 4-cm
    surface); the feet go down past the edge."""
    top = {side: (pose[0], pose[1], FLOOR + 0.05, 0.0, 0.0, 0.0) for side, pose in SOLES.items()}
    for seed in range(4):
        points = cloud(lambda x: FLOOR + (0.05 if x - 0.3 < 0.20 else 0.0), x_to=2.5, seed=seed)
        points[:, 0] -= 0.3
        steps = footsteps_from_cloud(points, top, 0.8)
        assert steps[-1][2] == pytest.approx(FLOOR, abs=0.006), (seed, steps)


def test_a_slope_seen_beyond_level_feet_is_refused_unless_seen_at_the_toes():
    """From a ramp's foot the camera sees the slope, not where it begins: taken to run on
    under the level feet, the first footsteps were pitched into the floor."""
    slope = math.tan(math.radians(10))
    ramp = lambda x: FLOOR + max(0.0, x - 0.2) * slope            # noqa: E731
    points = cloud(ramp)
    with pytest.raises(GroundError, match=r"slopes \+10 degrees where the feet stand at "
                                          r"[+-]0: where the slope begins is out of sight"):
        footsteps_from_cloud(points[points[:, 0] > 0.45], SOLES, 1.0)
    # seen from the toes on (0.16 m): the bend is there, and the feet step onto the slope
    seen = cloud(lambda x: FLOOR + (x - 0.25) * slope)
    seen[:, 0] -= 0.08                                   # the ramp from 0.17 m on
    steps = footsteps_from_cloud(seen, SOLES, 1.0)
    assert steps[0][4] == pytest.approx(-math.radians(10), abs=0.02), steps
    # the slope starts at the feet's own height: a camera reading 2 cm high is cancelled
    biased = footsteps_from_cloud(seen + [0.0, 0.0, 0.02], SOLES, 1.0)
    assert np.allclose(np.array(biased), np.array(steps), atol=0.004), (biased, steps)


def test_ground_seen_from_the_toes_is_stepped_onto_without_a_shuffle():
    """A kerb that begins at the toes, seen from there: the feet stand at its edge, so the
    first footstep is onto it (the edge's surface once ended where the kerb was first seen,
    and the feet shuffled 2-5 cm toward it, look after look)."""
    toes = SOLES["left"][0] + SOLE_HALF_LENGTH
    points = cloud(lambda x: FLOOR + 0.05, x_to=2.2)
    points[:, 0] += toes + 0.03 - 0.25                       # first seen 3 cm past the toes
    steps = footsteps_from_cloud(points, SOLES, 0.6)
    assert steps[0][2] == pytest.approx(FLOOR + 0.05, abs=0.006), steps


def test_a_leg_goes_on_over_a_ramp_s_foot_but_not_up_a_kerb_with_a_sloped_top():
    slope = math.tan(math.radians(10))
    ramp = lambda x: FLOOR + max(0.0, x - 0.6) * slope            # noqa: E731
    leg = first_leg(footsteps_from_cloud(cloud(ramp), SOLES, 1.2))
    assert leg[-1][4] == pytest.approx(-math.radians(10), abs=0.02), leg   # onto the ramp
    tilted = lambda x: FLOOR + (0.05 + (x - 0.6) * math.tan(math.radians(6)) if x >= 0.6  # noqa: E731
                                else 0.0)
    leg = first_leg(footsteps_from_cloud(cloud(tilted, faces=[0.6]), SOLES, 1.2))
    assert all(step[2] == pytest.approx(FLOOR, abs=0.006) for step in leg), leg  # at its foot


def test_a_noisy_camera_s_flat_floor_is_walked_and_its_debris_still_found():
    """Points 8 mm off at one sigma (a stereo camera's): the clearance grows with the noise
    measured on the strip, so the floor is not refused; a 4-cm block still is."""
    rng = np.random.default_rng(7)
    noisy = cloud(lambda x: FLOOR)
    noisy[:, 2] += rng.normal(0, 0.008, len(noisy))
    assert len(footsteps_from_cloud(noisy, SOLES, 1.5)) > 8
    with pytest.raises(GroundError, match="debris"):
        footsteps_from_cloud(with_block(noisy, 0.75, 0.145, 0.08, 0.06), SOLES, 1.2)
