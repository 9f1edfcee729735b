"""Footstep plans: strides within limits, feet side by side at the end, the ZMP on the stance
foot, swing paths that land vertically, and halt/resume/cancel (pause, stop, the guard)."""

import math
import re

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from walkman.control.footsteps import Ground, Reach, Timing, WalkPlan, compose, inverse

FEET = {"left": (0.0, 0.11, 0.0), "right": (0.0, -0.11, 0.0)}
planar = st.tuples(st.floats(-3, 3), st.floats(-3, 3), st.floats(-math.pi, math.pi))


@given(planar, planar)
def test_compose_and_inverse_undo_each_other(a, b):
    back = compose(compose(a, b), inverse(b))
    assert np.allclose(back[:2], a[:2], atol=1e-9)
    assert math.isclose(math.remainder(back[2] - a[2], 2 * math.pi), 0.0, abs_tol=1e-9)


def play(plan: WalkPlan, until: float, step: float = 0.01):
    t = 0.0
    while t < until:
        plan.update(t)
        t += step
    plan.update(until)


@given(st.floats(-2, 2), st.floats(-0.5, 0.5), st.floats(-math.pi, math.pi))
def test_a_walk_ends_with_the_feet_side_by_side_where_it_was_asked(dx, dy, dyaw):
    plan = WalkPlan(dict(FEET))
    steps = plan.plan(dx, dy, dyaw, 0.0)   # the reach check refuses none of its own strides
    limits = Timing().max_stride
    for step in plan.steps:
        assert all(abs(v) <= limit + 1e-9 for v, limit in zip(step.stride, limits))
    strides = steps - 1                 # the last step only brings the other foot beside
    expected = (0.0, 0.0, 0.0)
    for _ in range(strides):            # equal strides, each in the robot's new frame
        expected = compose(expected, (dx / strides, dy / strides, dyaw / strides))
    play(plan, plan.end_time() + 0.1)
    assert not plan.walking and not plan.halted
    assert np.allclose(plan.centre, expected, atol=1e-9)
    assert np.allclose(plan.travelled, expected, atol=1e-9)
    left, right = plan.feet["left"], plan.feet["right"]
    assert math.isclose(math.hypot(left[0] - right[0], left[1] - right[1]), 0.22, abs_tol=1e-9)


def test_the_zmp_stands_on_the_stance_foot_while_the_other_swings():
    plan = WalkPlan(dict(FEET))
    plan.plan(0.3, 0.0, 0.0, 0.0)
    first = plan.steps[0]
    assert first.side == "left"
    middle = (first.lift_at + first.land_at) / 2
    x, y = (float(v[0]) for v in plan.zmp(np.array([middle])))
    inward = Timing().inward
    assert (x, y) == pytest.approx((0.0, -0.11 + inward))   # on the right foot
    assert plan.swinging(middle) == "left" and plan.swinging(first.lift_at - 0.01) is None


def test_the_swing_foot_rises_travels_and_comes_straight_down():
    plan = WalkPlan(dict(FEET))
    plan.plan(0.15, 0.0, 0.0, 0.0)
    step = plan.steps[0]
    duration = step.land_at - step.lift_at
    (x0, _, _), h0 = plan.foot("left", step.lift_at)
    (_, _, _), top = plan.foot("left", step.lift_at + 0.5 * duration)
    (xd, _, _), hd = plan.foot("left", step.lift_at + 0.75 * duration)
    (x1, _, _), h1 = plan.foot("left", step.land_at)
    assert h0 == pytest.approx(0.0) and top == pytest.approx(Timing().lift)
    assert 0 < hd < Timing().lift and xd == pytest.approx(0.15)   # descending above its spot
    assert x0 == pytest.approx(0.0) and x1 == pytest.approx(0.15) and h1 == pytest.approx(0.0)


def test_halt_in_the_air_lands_closes_the_feet_and_resume_walks_the_rest():
    plan = WalkPlan(dict(FEET))
    plan.plan(0.6, 0.0, 0.0, 0.0)
    first = plan.steps[0]
    t = (first.lift_at + first.land_at) / 2
    play(plan, t)
    plan.halt(t)
    assert plan.halted
    play(plan, plan.end_time() + 0.1)
    left, right = plan.feet["left"], plan.feet["right"]
    assert left[0] == pytest.approx(0.15) and right[0] == pytest.approx(0.15)  # side by side
    assert plan.travelled[0] == pytest.approx(0.15)
    end = plan.end_time() + 0.1
    assert plan.resume(end) > 0
    play(plan, plan.end_time() + 0.1)
    assert plan.travelled[0] == pytest.approx(0.6) and plan.centre[0] == pytest.approx(0.6)


def test_halt_keeps_the_zmp_plan_until_the_closing_step_lands():
    """Changing where the ZMP goes while the CoM swings towards the next stance foot would
    throw the robot sideways: the halted plan matches the walk's until its next landing."""
    plan = WalkPlan(dict(FEET))
    plan.plan(0.6, 0.0, 0.0, 0.0)
    first, second = plan.steps[0], plan.steps[1]
    t = (first.lift_at + first.land_at) / 2
    times = np.linspace(t, second.land_at, 50)
    before = np.array(plan.zmp(times))
    plan.halt(t)
    assert np.allclose(np.array(plan.zmp(times)), before)


def test_cancel_forgets_the_rest_and_a_new_walk_is_refused_while_walking():
    plan = WalkPlan(dict(FEET))
    plan.plan(1.0, 0.0, 0.0, 0.0)
    with pytest.raises(ValueError, match="already walking"):
        plan.plan(0.2, 0.0, 0.0, 0.0)
    plan.cancel(0.5)   # still in the first weight shift: one step in place, then stand
    play(plan, plan.end_time() + 0.1)
    assert not plan.halted and plan.resume(plan.end_time() + 1) == 0
    assert plan.centre[0] == pytest.approx(0.0)
    with pytest.raises(ValueError, match="finite"):
        plan.plan(math.nan, 0.0, 0.0, 10.0)


# -- uneven ground: steps up and down, footsteps a pilot placed, the legs' reach ----------------

def test_a_step_up_lands_both_feet_on_the_higher_ground_clearing_its_edge():
    plan = WalkPlan(dict(FEET))
    assert plan.step_to(0.33, 0.05, 0.0) == 2
    lead, follow = plan.steps
    assert (lead.side, follow.side) == ("left", "right")
    assert (lead.start_z, lead.land_z, follow.start_z, follow.land_z) == (0.0, 0.05, 0.0, 0.05)
    assert lead.climbs and follow.climbs
    assert lead.land_at - lead.lift_at == pytest.approx(Timing().swing + Timing().climb)
    lift = Timing().lift
    for t in np.linspace(lead.lift_at, lead.land_at, 200):
        (x, _, _), z = plan.foot("left", t)
        if 0.0 < x < 0.33:   # travelling: as high as the new ground and the lift above it
            assert z == pytest.approx(0.05 + lift, abs=1e-9), t
        assert 0.0 <= z <= 0.05 + lift + 1e-9
    assert plan.foot("left", lead.land_at)[1] == pytest.approx(0.05)
    # the pelvis's ground rises half the step with the lead foot, all of it with the other
    assert plan.ground_level(lead.lift_at) == pytest.approx(0.0)
    assert plan.ground_level(lead.land_at) == pytest.approx(0.025)
    play(plan, plan.end_time() + 0.1)
    assert plan.heights == {"left": 0.05, "right": 0.05}
    assert plan.feet["left"][0] == pytest.approx(0.33) and plan.feet["right"][0] == \
        pytest.approx(0.33)
    assert plan.travelled[0] == pytest.approx(0.33)


def test_a_step_down_goes_to_the_lower_ground_and_a_walk_after_it_stays_there():
    plan = WalkPlan(dict(FEET), ground={"left": Ground(0.05), "right": Ground(0.05)})
    plan.step_to(0.33, -0.05, 0.0)
    lead = plan.steps[0]
    (_, _, _), top = plan.foot("left", (lead.lift_at + lead.land_at) / 2)
    assert top == pytest.approx(0.05 + Timing().lift)   # the heel clears the edge it leaves
    play(plan, plan.end_time() + 0.1)
    assert plan.heights == {"left": 0.0, "right": 0.0}
    plan.plan(0.3, 0.0, 0.0, plan.end_time() + 1)
    assert all(step.land_z == 0.0 and not step.climbs for step in plan.steps)


@pytest.mark.parametrize("forward, height, problem", [
    (0.33, 0.12, "step 1 of 2 (left foot) cannot be made: 0.12 m above the other foot "
                 "(at most 0.08)"),
    (0.33, -0.12, "0.12 m below the other foot"),
    (0.45, 0.05, "0.45 m ahead of the other foot (at most 0.36)")])
def test_a_step_the_legs_cannot_make_is_refused_whole_before_a_foot_lifts(forward, height,
                                                                          problem):
    plan = WalkPlan(dict(FEET))
    with pytest.raises(ValueError, match=re.escape(problem)):
        plan.step_to(forward, height, 0.0)
    assert not plan.walking and plan.feet == FEET and plan.end_time() == 0.0


def test_a_long_level_step_over_a_board_reaches_further_and_swings_slowly():
    """Over a board lying on the floor (:mod:`walkman.control.ground_ahead` steps over it):
    onto ground level with the other foot's a foot lands up to ``Reach.level_ahead`` ahead of
    it, swung as slowly as a climb, the second foot beside the first as slowly; a walk's
    own strides swing at their pace.  Further, or onto higher ground that far, is refused."""
    timing = Timing()
    plan = WalkPlan(dict(FEET))
    assert plan.place([(0.38, -0.11, 0.0, 0.0, 0.0), (0.38, 0.11, 0.0, 0.0, 0.0)], 0.0) == 2
    assert [step.strides_over for step in plan.steps] == [True, True]
    assert [step.land_at - step.lift_at for step in plan.steps] == \
        pytest.approx([timing.swing + timing.climb] * 2)
    walk = WalkPlan(dict(FEET))
    walk.plan(1.0, 0.0, 0.0, 0.0)
    assert not any(step.strides_over for step in walk.steps)
    assert {round(step.land_at - step.lift_at, 6) for step in walk.steps} == {timing.swing}
    for footstep, problem in (
            ((Reach.level_ahead + 0.02, -0.11, 0.0, 0.0, 0.0),
             f"0.42 m ahead of the other foot (at most {Reach.level_ahead:.2f})"),
            ((0.38, -0.11, 0.0, 0.03, 0.0), "0.38 m ahead of the other foot (at most 0.36)")):
        with pytest.raises(ValueError, match=re.escape(problem)):
            WalkPlan(dict(FEET)).place([footstep], 0.0)


def test_placed_footsteps_are_played_in_turn_from_the_side_of_the_first():
    plan = WalkPlan(dict(FEET))
    assert plan.place([(0.15, -0.11, 0.0, 0.0, 0.0), (0.30, 0.11, 0.0, 0.05, 0.0),
                       (0.30, -0.11, 0.0, 0.05, 0.0)], 0.0) == 3
    assert [step.side for step in plan.steps] == ["right", "left", "right"]
    assert [step.land_z for step in plan.steps] == [0.0, 0.05, 0.05]
    play(plan, plan.end_time() + 0.1)
    assert plan.centre == pytest.approx((0.30, 0.0, 0.0))
    assert plan.travelled == pytest.approx((0.30, 0.0, 0.0))


@pytest.mark.parametrize("footsteps, problem", [
    ([(0.1, 0.11, 0.0, 0.0, 0.0), (0.1, 0.02, 0.0, 0.0, 0.0)],
     "step 2 of 2 (right foot) cannot be made: 0.09 m beside the other foot: the feet "
     "would touch"),
    ([(0.1, 0.5, 0.0, 0.0, 0.0)], "0.61 m beside the other foot (at most 0.34)"),
    ([(0.0, 0.11, 0.8, 0.0, 0.0)], "turned 0.80 rad from the other foot (at most 0.45)"),
    ([(-0.3, 0.11, 0.0, 0.0, 0.0)], "0.30 m behind the other foot (at most 0.20)"),
    ([(0.15, 0.11, 0.0, 0.03, -0.3)], "on ground pitched 0.30 rad (at most 0.20)"),
    ([], "no footsteps"), ([(0.1, 0.11, math.inf, 0.0, 0.0)], "finite")])
def test_placed_footsteps_out_of_reach_are_refused_saying_which_and_why(footsteps, problem):
    plan = WalkPlan(dict(FEET))
    with pytest.raises(ValueError, match=re.escape(problem)):
        plan.place(footsteps, 0.0)
    assert not plan.walking


def test_halted_half_way_up_the_other_foot_joins_the_one_on_the_step():
    plan = WalkPlan(dict(FEET))
    plan.step_to(0.33, 0.05, 0.0)
    lead = plan.steps[0]
    t = (lead.lift_at + lead.land_at) / 2
    play(plan, t)
    plan.halt(t)
    play(plan, plan.end_time() + 0.1)
    assert plan.heights == {"left": 0.05, "right": 0.05}
    assert plan.feet["right"][0] == pytest.approx(0.33)



def test_a_walk_on_a_ramp_goes_on_up_its_slope_and_turns_each_sole_to_it():
    """Standing on a 10-degree ramp (pitch -0.1745: rising ahead), go_straight lands each foot
    where the ramp continues, pitched like it; a foot turns to the new pitch on its way."""
    slope = -math.radians(10)
    plan = WalkPlan(dict(FEET), ground={"left": Ground(0.0, slope), "right": Ground(0.0, slope)})
    plan.plan(0.3, 0.0, 0.0, 0.0)
    for step in plan.steps:
        assert step.land_ground.z == pytest.approx(step.land[0] * math.tan(-slope))
        assert step.land_ground.pitch == slope
    play(plan, plan.end_time() + 0.1)
    assert plan.heights["left"] == pytest.approx(0.3 * math.tan(-slope))
    # onto a level landing at the ramp's top: the sole turns flat while it travels
    top = plan.heights["left"]
    plan.place([(0.45, 0.11, 0.0, top + 0.01, 0.0), (0.45, -0.11, 0.0, top + 0.01, 0.0)],
               plan.end_time() + 1)
    step = plan.steps[0]
    assert plan.foot_pitch("left", step.lift_at) == pytest.approx(slope)
    assert slope < plan.foot_pitch("left", (step.lift_at + step.land_at) / 2) < 0.0
    assert plan.foot_pitch("left", step.land_at) == 0.0
    # a footstep that would need a steeper change of pitch than the ankle takes is refused
    plan = WalkPlan(dict(FEET), ground={"left": Ground(0.0, slope), "right": Ground(0.0, slope)})
    with pytest.raises(ValueError, match="pitched 0.37 rad from the other foot"):
        plan.place([(0.15, 0.11, 0.0, 0.03, -slope * 1.1)], 0.0)


def test_soles_seated_as_they_rest_turn_to_it_and_step_from_it_the_slope_going_on_as_planned():
    """Soles that rest 2.3 degrees flatter than the 10-degree ramp they stand on (crept onto
    the bend at its foot) are seated: their planned pitch turns to the measured one over the
    time given, the next step sets out from it, and a walk still goes on down the slope."""
    slope, rest = math.radians(10), math.radians(7.7)
    plan = WalkPlan(dict(FEET), ground={"left": Ground(0.0, slope), "right": Ground(0.0, slope)})
    plan.seat({"left": rest, "right": rest}, 1.0, 3.0)
    assert plan.foot_pitch("left", 1.0) == pytest.approx(slope)
    assert rest < plan.foot_pitch("left", 2.0) < slope
    assert plan.foot_pitch("right", 3.0) == pytest.approx(rest)
    assert plan.ground["left"].pitch == slope and plan.ground["left"].sole_pitch == rest
    plan.plan(0.3, 0.0, 0.0, 3.0)
    first = plan.steps[0]
    assert plan.foot_pitch(first.side, first.lift_at) == pytest.approx(rest)
    assert first.land_ground == Ground(first.land_ground.z, slope)    # the slope, no seat
    assert first.land_ground.z == pytest.approx(-first.land[0] * math.tan(slope))
    with pytest.raises(ValueError, match="standing"):
        plan.seat({"left": slope}, 4.0, 5.0)


def test_the_weight_waits_on_the_standing_foot_after_a_landing_on_other_ground():
    """A step onto higher ground (a kerb, a ramp) is checked on landing
    (walkman/control/foothold.py): the ZMP stays on the standing foot for
    ``Timing.foothold_wait`` after it lands; a step up a ramp's slope lands where the ground
    goes on, and a step down lands lower: neither is."""
    plan = WalkPlan(dict(FEET))
    plan.step_to(0.33, 0.05, 0.0)
    lead, follow = plan.steps
    assert lead.checked_on_landing and not follow.checked_on_landing   # it lands beside it
    wait = Timing().foothold_wait
    assert wait > 0 and follow.shift_at == pytest.approx(lead.land_at + wait)
    zmp_at = lambda t: (float(plan.zmp(np.array([t]))[0][0]), float(plan.zmp(np.array([t]))[1][0]))
    assert zmp_at(lead.land_at + wait) == pytest.approx(zmp_at(lead.land_at))
    unchecked = WalkPlan(dict(FEET), Timing(foothold_wait=0.0))
    unchecked.step_to(0.33, 0.05, 0.0)
    assert unchecked.steps[1].shift_at == pytest.approx(unchecked.steps[0].land_at)
    slope = -math.radians(10)
    ramp = WalkPlan(dict(FEET), ground={"left": Ground(0.0, slope), "right": Ground(0.0, slope)})
    ramp.plan(0.3, 0.0, 0.0, 0.0)
    assert all(step.climbs and not step.checked_on_landing for step in ramp.steps)
    # off a ramp's slope onto the floor at its foot: above the slope continued, yet lower
    # than where the foot lifted -- a step down, not checked
    off = WalkPlan(dict(FEET), ground={"left": Ground(0.03, -slope), "right": Ground(0.03, -slope)})
    off.place([(0.30, 0.11, 0.0, 0.0, 0.0), (0.30, -0.11, 0.0, 0.0, 0.0)], 0.0)
    assert all(step.climbs and not step.checked_on_landing for step in off.steps)
    down = WalkPlan(dict(FEET), ground={"left": Ground(0.05), "right": Ground(0.05)})
    down.step_to(0.33, -0.05, 0.0)
    assert not any(step.checked_on_landing for step in down.steps)
    assert down.steps[1].shift_at == pytest.approx(down.steps[0].land_at)
    # footsteps placed one by one: each is checked, but one beside the standing sole on
    # the ground that sole stands on (it bears there), as step_up's second
    placed = WalkPlan(dict(FEET))
    placed.place([(0.33, 0.11, 0.0, 0.05, 0.0), (0.33, -0.11, 0.0, 0.05, 0.0)], 0.0)
    assert [step.checked_on_landing for step in placed.steps] == [True, False]
    ahead = WalkPlan(dict(FEET))
    ahead.place([(0.33, 0.11, 0.0, 0.05, 0.0), (0.40, -0.11, 0.0, 0.05, 0.0)], 0.0)
    assert [step.checked_on_landing for step in ahead.steps] == [True, True]
    other = WalkPlan(dict(FEET))    # beside, but on other ground than the standing sole's
    other.place([(0.33, 0.11, 0.0, 0.05, 0.0), (0.33, -0.11, 0.0, 0.07, 0.0)], 0.0)
    assert [step.checked_on_landing for step in other.steps] == [True, True]


def test_retreat_puts_the_foot_back_where_it_lifted_from_and_drops_the_rest():
    plan = WalkPlan(dict(FEET))
    plan.step_to(0.33, 0.05, 0.0)
    lead = plan.steps[0]
    t = lead.land_at + 0.2
    play(plan, t)
    assert plan.heights["left"] == 0.05 and plan.feet["left"][0] == pytest.approx(0.33)
    assert plan.retreat(lead, t) == 1
    back = plan.steps[0]
    assert (back.side, back.start_z, back.land_z) == ("left", 0.05, 0.0)
    assert back.returning            # not watched for a strike on its way down
    assert back.lift_at > t          # the weight shifts back onto the standing foot first
    assert not plan.set_aside
    play(plan, plan.end_time() + 0.1)
    assert plan.feet == FEET and plan.heights == {"left": 0.0, "right": 0.0}
    assert plan.travelled == pytest.approx((0.0, 0.0, 0.0), abs=1e-9)


def test_strike_holds_the_foot_on_the_ground_it_left_then_puts_it_back():
    plan = WalkPlan(dict(FEET), ground={"left": Ground(0.05), "right": Ground(0.05)})
    plan.step_to(0.33, -0.05, 0.0)
    lead = plan.steps[0]
    t = lead.land_at - 0.12                  # on its way down, 1.3 cm above the floor
    play(plan, t)
    where, height = plan.foot("left", t)
    assert 0.0 < height < 0.05
    assert plan.strike(lead, t) == 1
    # it stands where it is, on the ground it left (the sole lags the plan's lower height)
    assert plan.foot("left", t) == (where, 0.05)
    assert plan.heights == {"left": 0.05, "right": 0.05} and not plan.set_aside
    back = plan.steps[0]
    assert (back.start, back.land, back.start_z, back.land_z) == (where, lead.start, 0.05, 0.05)
    assert back.slow and not back.check and back.lift_at > t   # the weight stays on the right
    assert back.returning and not lead.returning
    assert back.land_at - back.lift_at == pytest.approx(Timing().swing + Timing().climb)
    stance = plan.zmp(np.array([back.lift_at]))
    assert float(stance[0][0]) == pytest.approx(plan.feet["right"][0], abs=1e-6)
    play(plan, plan.end_time() + 0.1)
    assert plan.feet == FEET and plan.heights == {"left": 0.05, "right": 0.05}
    assert plan.travelled == pytest.approx((0.0, 0.0, 0.0), abs=1e-9)
