"""The step planner as pure logic: strides within limits, feet back side by side, odometry,
pauses only with both feet down."""

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from walkman.control.gait import Gait, compose, inverse


def play(gait: Gait, until: float, dt: float = 0.01):
    t = 0.0
    while t < until:
        gait.update(t)
        yield t
        t += dt


def test_compose_and_inverse_are_se2():
    a, b = (0.3, -0.1, 0.7), (0.2, 0.05, -0.4)
    back = compose(inverse(a), compose(a, b))
    assert back == pytest.approx(b)


@given(st.floats(-3, 3), st.floats(-1, 1), st.floats(-3, 3))
def test_a_walk_travels_what_was_asked_and_ends_feet_together(dx, dy, dyaw):
    gait = Gait()
    count = gait.plan(dx, dy, dyaw, 0.0)
    assert count >= 2
    for step in gait.steps:
        for value, limit in zip(step.stride, gait.max_stride):
            assert abs(value) <= limit + 1e-9
    for _ in play(gait, count * (gait.step_time + gait.double_support) + 0.1):
        pass
    assert not gait.walking
    assert gait.travelled[2] == pytest.approx(dyaw, abs=1e-9)
    if dyaw == 0:  # with a turn the strides compose on SE(2): x, y are not the plain sums
        assert gait.travelled[:2] == pytest.approx((dx, dy), abs=1e-9)
    for side in ("left", "right"):
        assert gait.feet[side] == pytest.approx(gait.nominal(side), abs=1e-9)


def test_the_stance_foot_slides_back_and_the_swing_foot_lifts_and_lands_ahead():
    gait = Gait(lift=0.05)
    gait.plan(0.4, 0.0, 0.0, 0.0)  # strides of 0.2: half, full, half
    first = gait.steps[0]
    assert first.swing == "left"
    mid = gait.double_support + gait.step_time / 2
    (x, _, _), z = gait.foot("left", mid)
    assert z == pytest.approx(gait.ground + 0.05)
    (sx, _, _), sz = gait.foot("right", mid)
    assert sz == gait.ground and sx < 0.0
    end = gait.double_support + gait.step_time
    assert gait.foot("left", end)[0][0] == pytest.approx(0.1)   # half a stride ahead
    assert gait.foot("right", end)[0][0] == pytest.approx(-0.1)  # the pelvis moved 0.1


def test_pause_only_with_both_feet_down_and_resume_shifts_the_rest():
    gait = Gait()
    gait.plan(0.4, 0.0, 0.0, 0.0)
    assert gait.can_pause(0.1)                               # double support
    assert not gait.can_pause(gait.double_support + 0.5)     # a foot in the air
    step_end = gait.double_support + gait.step_time
    gait.update(step_end)
    assert gait.can_pause(step_end + 0.01)
    gait.hold(step_end + 0.01)
    feet = dict(gait.feet)
    assert gait.update(step_end + 5.0) is None and gait.feet == feet
    assert gait.foot("left", step_end + 5.0) == (feet["left"], gait.ground)
    gait.resume(step_end + 5.01)
    assert gait.steps[0].t0 == pytest.approx(step_end + 5.0)


def test_bad_walks_are_refused():
    gait = Gait()
    with pytest.raises(ValueError, match="finite"):
        gait.plan(math.nan, 0, 0, 0)
    gait.plan(0.2, 0, 0, 0)
    with pytest.raises(ValueError, match="already walking"):
        gait.plan(0.2, 0, 0, 0)
