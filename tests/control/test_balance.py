"""Balance from sensors, fed known values: the CoP under a foot from its ankle wrench, the
feet's ZMP and its margin to the support polygon, ankle compliance, the attitude loop, the guard."""

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from walkman.control.balance import (CONTACT_FORCE, SAFE_MARGIN, TRIP_TIME, AnkleCompliance,
                                     AttitudeLoop, BalanceGuard, Sole, combined_zmp, convex_hull,
                                     foot_zmp, margin, support_margin, to_local, to_world)

SOLE = Sole()


def wrench_for(px: float, py: float, fz: float, fx: float = 0.0, fy: float = 0.0) -> list:
    """What the ankle sensor reads (leg on foot) when the floor pushes up ``fz`` at
    (px, py) of the sole frame and sideways (fx, fy)."""
    sx, sy, d = SOLE.sensor
    # floor on foot: force (fx, fy, fz) at (px - sx, py - sy, -d) from the sensor
    r = np.array([px - sx, py - sy, -d])
    force = np.array([fx, fy, fz])
    torque = np.cross(r, force)
    return [*(-force), *(-torque)]        # the sensor reads the leg's push on the foot


@given(st.floats(-0.12, 0.12), st.floats(-0.06, 0.06), st.floats(60, 2000),
       st.floats(-100, 100), st.floats(-100, 100))
def test_the_cop_is_where_the_floor_pushes(px, py, fz, fx, fy):
    measured = foot_zmp(wrench_for(px, py, fz, fx, fy), SOLE)
    assert measured == pytest.approx((px, py, fz), abs=1e-9)


def test_a_foot_in_the_air_has_no_cop():
    assert foot_zmp(wrench_for(0.0, 0.0, CONTACT_FORCE - 1), SOLE) is None


def test_the_zmp_of_two_feet_is_weighted_by_their_load_and_its_margin_is_to_the_hull():
    feet = {"left": ((0.0, 0.11, 0.0), wrench_for(0.0, 0.0, 300.0)),
            "right": ((0.0, -0.11, 0.0), wrench_for(0.0, 0.0, 900.0))}
    zmp, contacts = combined_zmp(feet, SOLE)
    assert sorted(contacts) == ["left", "right"]
    assert zmp == pytest.approx([0.0, (0.11 * 300 - 0.11 * 900) / 1200])
    poses = {side: pose for side, (pose, _) in feet.items()}
    # the hull of both soles: the nearest edge is the right foot's outer side (y = -0.18),
    # 12.5 cm from the ZMP at y = -0.055 (the toe and heel lines are 13 cm away)
    assert support_margin(zmp, poses, contacts, SOLE) == pytest.approx(0.18 - 0.055)
    # on one foot only, the margin is to that foot's sides
    single = {"right": feet["right"], "left": ((0.0, 0.11, 0.0), wrench_for(0, 0, 10.0))}
    zmp, contacts = combined_zmp(single, SOLE)
    assert contacts == ["right"]
    assert support_margin(zmp, poses, contacts, SOLE) == pytest.approx(SOLE.half_width)


def test_no_foot_on_the_floor_gives_no_zmp():
    feet = {"left": ((0, 0.11, 0), [0.0] * 6), "right": ((0, -0.11, 0), [0.0] * 6)}
    assert combined_zmp(feet, SOLE) == (None, [])


def test_margin_is_negative_outside_and_the_hull_is_convex():
    square = [np.array(p, dtype=float) for p in ((0, 0), (1, 0), (1, 1), (0, 1), (0.5, 0.5))]
    hull = convex_hull(square)
    assert len(hull) == 4
    assert margin(np.array([0.5, 0.5]), hull) == pytest.approx(0.5)
    assert margin(np.array([1.2, 0.5]), hull) == pytest.approx(-0.2)
    assert margin(np.array([0.5, 0.5]), hull[:2]) == -math.inf


@given(st.tuples(st.floats(-2, 2), st.floats(-2, 2), st.floats(-3, 3)),
       st.tuples(st.floats(-1, 1), st.floats(-1, 1)))
def test_to_local_undoes_to_world(pose, point):
    assert to_local(pose, to_world(pose, point)) == pytest.approx(point, abs=1e-9)


def test_an_ankle_turns_its_foot_against_the_cop_error_and_back_to_flat():
    ankle = AnkleCompliance()
    for _ in range(50):   # CoP 5 cm ahead and 2 cm left of where it should be, for 0.5 s
        roll, pitch = ankle.update(0.01, (0.05, 0.02), (0.0, 0.0))
    assert pitch < -0.005 and roll > 0.002     # toes up, left edge up: the CoP moves back
    for _ in range(300):  # in the air: back to flat
        roll, pitch = ankle.update(0.01, None, (0.0, 0.0))
    assert abs(roll) < 1e-3 and abs(pitch) < 1e-3


def test_the_attitude_loop_tilts_the_pelvis_against_the_measured_tilt():
    loop = AttitudeLoop()
    for _ in range(100):
        roll, pitch = loop.update(0.01, 0.02, -0.01)
    assert roll < -0.02 and pitch > 0.01
    for _ in range(1000):
        loop.update(0.01, 1.0, 1.0)   # a wild reading is bounded
    assert np.all(np.abs(loop.attitude) <= 0.12 + 1e-12)


def test_the_attitude_turns_at_once_with_the_soles_and_stays_bounded():
    """Soles seated as they rest turn the legs' frame: the commanded tilt turns as much at
    once (the IMU level), within the loop's bound."""
    loop = AttitudeLoop()
    loop.update(0.01, 0.0, 0.0)
    loop.turn(-0.04)
    assert loop.update(0.01, 0.0, 0.0)[1] == pytest.approx(-0.04)
    loop.turn(-1.0)
    assert loop.update(0.01, 0.0, 0.0)[1] == pytest.approx(-0.12)


def test_standing_still_the_attitude_is_the_integral_alone_and_the_same_integral_goes_on():
    """A robot standing still levels its pelvis by the integral alone (its proportional term
    fed the robot's own sway back on a ramp's bend); a walk has the same integral back,
    with the proportional term on top."""
    still, moving = AttitudeLoop(), AttitudeLoop()
    for _ in range(50):
        still.update(0.01, 0.0, 0.02, proportional=False)
        moving.update(0.01, 0.0, 0.02)
    assert still.attitude[1] == pytest.approx(-2.0 * 0.02 * 0.5)        # integral: 1/s * s
    assert moving.attitude[1] == pytest.approx(still.attitude[1] - 0.3 * 0.02)
    assert still.update(0.0, 0.0, 0.02)[1] == pytest.approx(moving.attitude[1])


def test_the_guard_trips_once_on_a_lasting_problem_and_rearms_after_a_safe_second():
    guard = BalanceGuard()
    assert guard.update(0.0, SAFE_MARGIN / 2, 0.0) is None          # one tick is noise
    problem = guard.update(TRIP_TIME, SAFE_MARGIN / 2, 0.0)
    assert problem is not None and "from the edge of the feet" in problem
    assert guard.update(TRIP_TIME + 0.5, SAFE_MARGIN / 2, 0.0) is None   # once
    assert guard.update(0.7, 0.05, 0.0) is None      # safe for less than REARM_TIME ...
    assert guard.update(1.0, SAFE_MARGIN / 2, 0.0) is None
    assert guard.update(1.0 + 2 * TRIP_TIME, SAFE_MARGIN / 2, 0.0) is None   # ... not rearmed
    for t in np.arange(1.3, 2.4, 0.1):               # safe for more: rearmed
        assert guard.update(t, 0.05, 0.0) is None
    assert guard.update(2.3, 0.05, 0.3) is None
    problem = guard.update(2.3 + TRIP_TIME, 0.05, 0.3)
    assert problem is not None and "tilted 17 degrees" in problem
    assert guard.update(3.0, None, 0.0) is None     # no ZMP (in the air) is not a problem
