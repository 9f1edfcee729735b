"""The foothold checks: a sole landing on higher ground comes down heel first, turned about its
heel, and the first touch says whether the heel bears; a sole stepping down must not carry
weight before it is near its landing (walkman/control/foothold.py); the walking module's use of
them on the simulated robot is in tests/modules/test_walking.py."""

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from walkman.control.balance import Sole
from walkman.control.foothold import (LATEST, REACH, SEEK_AFTER, SEEK_DEPTH, SEEK_SPEED,
                                      STRIKE_ABOVE, STRIKE_SAMPLES, TILT, TOUCH, TURN,
                                      DescentCheck, FootholdCheck)

LANDING = 10.0
HEEL = -Sole().half_length


def touch(check: FootholdCheck, cop_x: float, start: float = LANDING + 0.05,
          force: float = 300.0, ticks: int = 10) -> None:
    for tick in range(ticks):
        check.sample(start + 0.01 * tick, (cop_x, 0.0, force))


def test_the_sole_turns_before_the_landing_and_stays_turned_until_the_verdict():
    check = FootholdCheck("left", LANDING)
    assert check.tilt(LANDING - TURN - 0.01) == 0.0
    assert check.tilt(LANDING) == pytest.approx(-TILT)           # toes up: the heel first
    assert check.tilt(LANDING + LATEST - 0.01) == pytest.approx(-TILT)   # nothing decided yet
    touch(check, HEEL)
    decided = LANDING + 0.05 + TOUCH
    assert check.decide(decided) == ""
    assert check.tilt(decided + TURN / 2) == pytest.approx(-TILT / 2)
    assert check.tilt(decided + TURN) == pytest.approx(0.0) and check.done(decided + TURN)


@given(st.floats(-0.2, 0.2), st.floats(0.0, 1.0))
def test_the_heel_stays_where_the_plan_puts_the_sole(ground_pitch, into):
    """Turned about its heel, the sole's centre moves so that the heel does not (but for
    the depth it reaches down for the ground, straight down)."""
    check = FootholdCheck("left", LANDING)
    t = LANDING - TURN + into * (TURN + LATEST)
    forward, up = check.shift(t, ground_pitch)
    pitch = ground_pitch + check.tilt(t)
    along = -Sole().half_length

    def end_point(centre_x, centre_z, p):    # rpy pitch p turns +x towards -z
        return centre_x + along * math.cos(p), centre_z - along * math.sin(p)

    assert end_point(forward, up, pitch) == pytest.approx(
        end_point(0.0, -check.reach(t), ground_pitch), abs=1e-9)


def test_a_sole_not_touching_reaches_down_for_the_ground_and_holds_where_it_touched():
    check = FootholdCheck("left", LANDING)
    assert check.reach(LANDING + SEEK_AFTER) == 0.0
    assert check.reach(LANDING + SEEK_AFTER + 0.1) == pytest.approx(0.1 * SEEK_SPEED)
    assert check.reach(LANDING + 10.0) == pytest.approx(SEEK_DEPTH)   # no deeper
    touch(check, HEEL, start=LANDING + SEEK_AFTER + 0.1)               # found it
    assert check.reach(LANDING + SEEK_AFTER + 0.3) == pytest.approx(0.1 * SEEK_SPEED)
    decided = LANDING + SEEK_AFTER + 0.1 + TOUCH
    assert check.decide(decided) == ""
    assert check.reach(decided + TURN / 2) == pytest.approx(0.05 * SEEK_SPEED)  # turning flat
    assert check.reach(decided + TURN) == 0.0


def test_a_sole_that_touches_in_time_never_reaches_down():
    check = FootholdCheck("left", LANDING)
    touch(check, HEEL, start=LANDING + SEEK_AFTER - 0.05)
    assert check.reach(LANDING + 1.0) == 0.0


def test_a_heel_that_bears_passes_one_over_an_edge_is_named_with_where_it_bore():
    firm = FootholdCheck("left", LANDING)
    touch(firm, HEEL + REACH - 0.005)
    assert firm.decide(LANDING + 1.0) == "" and firm.bears is True
    edge = FootholdCheck("left", LANDING)
    touch(edge, -0.033)
    problem = edge.decide(LANDING + 1.0)
    assert problem == ("the left sole landed on its heel but bore 3 cm behind its centre, "
                       "10 cm from its heel (at most 3): its heel is over an edge")
    assert edge.bears is False


def test_the_verdict_comes_from_the_first_touch_not_the_weight_that_follows():
    check = FootholdCheck("left", LANDING)
    touch(check, HEEL, start=LANDING + 0.1, ticks=3)
    assert check.decide(LANDING + 0.1 + TOUCH / 2) is None       # touched, not long enough
    assert check.decide(LANDING + 0.1 + TOUCH) == ""
    touch(check, 0.05, start=LANDING + 0.2)                       # weight after the verdict
    assert check.verdict() == "" and check.decide(LANDING + 0.5) is None   # said once


def test_a_sole_that_never_touches_found_no_ground_and_readings_before_the_turn_do_not_count():
    check = FootholdCheck("left", LANDING)
    check.sample(LANDING - TURN - 0.05, (HEEL, 0.0, 500.0))     # still swinging: not a touch
    check.sample(LANDING + 0.1, None)                            # no weight on it
    assert check.decide(LANDING + LATEST - 0.01) is None
    assert check.decide(LANDING + LATEST) == ("the left sole found no ground: it carried no "
                                              f"weight {LATEST:.2f} s after it should have "
                                              "landed")


def test_a_sole_that_does_not_bear_stays_turned_until_its_foot_lifts():
    check = FootholdCheck("left", LANDING)
    touch(check, -0.03)
    decided = LANDING + 0.05 + TOUCH
    assert check.decide(decided)
    assert check.tilt(decided + 2 * TURN) == pytest.approx(-TILT)   # turned flat it would jam
    assert not check.done(decided + 2 * TURN)
    check.release(decided + 1.0)
    assert check.tilt(decided + 1.0 + TURN) == pytest.approx(0.0)
    assert check.done(decided + 1.0 + TURN)


# -- a sole stepping down ------------------------------------------------------------------

LOADED = (0.0, 0.0, 540.0)


def test_a_sole_stepping_down_that_carries_weight_early_struck_and_is_said_once():
    check = DescentCheck("left", 0.05, LANDING)
    assert check.sample(LANDING - 0.8, 0.05, LOADED) is None    # the weight still leaving it
    assert check.sample(LANDING - 0.7, 0.06, None) is None      # lifted
    assert check.sample(LANDING - 0.122, 0.013, LOADED) is None  # a tick: not yet
    problem = check.sample(LANDING - 0.12, 0.013, LOADED)
    assert problem == ("the left sole met ground on its way 5 cm down, 0.12 s before it "
                       "should have landed (540 N on it): the ground it leaves goes on under it")
    assert check.sample(LANDING - 0.11, 0.010, LOADED) is None  # once


def test_a_swinging_sole_s_reading_for_a_tick_or_a_light_one_is_no_strike():
    """fc21 and fc23 of 2026-11-28: 51-52 N for a tick, 0.19 s before landing, the way clear
    of the edge: the foot was put back for nothing."""
    check = DescentCheck("left", 0.05, LANDING)
    check.sample(LANDING - 0.6, 0.08, None)
    for k in range(20):     # light, for as long as it likes
        assert check.sample(LANDING - 0.5 + 0.002 * k, 0.05, (0.0, 0.0, 52.0)) is None
    assert check.sample(LANDING - 0.3, 0.04, LOADED) is None    # one tick of weight
    assert check.sample(LANDING - 0.298, 0.04, None) is None
    assert check.sample(LANDING - 0.296, 0.04, LOADED) is None  # and another, not in a row


def test_a_sole_that_touches_near_or_after_its_landing_did_not_strike():
    check = DescentCheck("right", 0.05, LANDING)
    check.sample(LANDING - 0.5, 0.09, None)
    assert check.sample(LANDING - 0.02, STRIKE_ABOVE, LOADED) is None
    assert check.sample(LANDING + 0.1, 0.0, LOADED) is None


@given(st.lists(st.tuples(st.floats(0.0, 0.2), st.booleans()), max_size=60))
def test_a_strike_is_said_only_after_a_lift_off_and_only_once_per_lift_off(samples):
    check = DescentCheck("left", 0.05, LANDING)
    lifted = False     # a sample without weight since the start or the last strike said
    pressed = 0        # loaded samples in a row, early, since the lift-off
    for index, (above, loaded) in enumerate(samples):
        problem = check.sample(LANDING - 1 + 0.01 * index, above, LOADED if loaded else None)
        if not loaded:
            lifted, pressed = True, 0
        elif lifted and above > STRIKE_ABOVE:
            pressed += 1
        else:
            pressed = 0
        if problem:
            assert lifted and above > STRIKE_ABOVE and pressed == STRIKE_SAMPLES
            lifted, pressed = False, 0
        else:
            assert pressed < STRIKE_SAMPLES
