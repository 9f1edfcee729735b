"""The foothold probe: a sole landing on new ground comes down on one end, turned about it, and
the first touch says whether it bears there (walkman/control/foothold.py); the walking module's
use of it on the simulated robot is in tests/modules/test_walking.py."""

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from walkman.control.balance import Sole
from walkman.control.foothold import (LATEST, REACH, TILT, TOUCH, TURN, FootholdProbe)

LANDING = 10.0
HEEL = -Sole().half_length


def touch(probe: FootholdProbe, cop_x: float, start: float = LANDING + 0.05,
          force: float = 300.0, ticks: int = 10) -> None:
    for tick in range(ticks):
        probe.sample(start + 0.01 * tick, (cop_x, 0.0, force))


def test_going_up_the_heel_lands_first_going_down_the_toes():
    assert FootholdProbe.for_step("left", LANDING, 0.05).end == "heel"
    assert FootholdProbe.for_step("left", LANDING, -0.05).end == "toes"
    with pytest.raises(ValueError, match="heel or its toes, not 'ball'"):
        FootholdProbe("left", LANDING, "ball")


def test_the_sole_turns_before_the_landing_and_stays_turned_until_the_verdict():
    probe = FootholdProbe("left", LANDING, "heel")
    assert probe.tilt(LANDING - TURN - 0.01) == 0.0
    assert probe.tilt(LANDING) == pytest.approx(-TILT)           # toes up: the heel first
    assert probe.tilt(LANDING + LATEST - 0.01) == pytest.approx(-TILT)   # nothing decided yet
    touch(probe, HEEL)
    decided = LANDING + 0.05 + TOUCH
    assert probe.decide(decided) == ""
    assert probe.tilt(decided + TURN / 2) == pytest.approx(-TILT / 2)
    assert probe.tilt(decided + TURN) == pytest.approx(0.0) and probe.done(decided + TURN)
    toes = FootholdProbe("left", LANDING, "toes")
    assert toes.tilt(LANDING) == pytest.approx(TILT)


@given(st.floats(-0.2, 0.2), st.sampled_from(["heel", "toes"]), st.floats(0.0, 1.0))
def test_the_end_landed_on_stays_where_the_plan_puts_the_sole(ground_pitch, end, into):
    """Turned about its end, the sole's centre moves so that the end does not."""
    probe = FootholdProbe("left", LANDING, end)
    t = LANDING - TURN + into * (TURN + LATEST)
    forward, up = probe.shift(t, ground_pitch)
    pitch = ground_pitch + probe.tilt(t)
    along = (-1.0 if end == "heel" else 1.0) * Sole().half_length

    def end_point(centre_x, centre_z, p):    # rpy pitch p turns +x towards -z
        return centre_x + along * math.cos(p), centre_z - along * math.sin(p)

    assert end_point(forward, up, pitch) == pytest.approx(end_point(0.0, 0.0, ground_pitch),
                                                          abs=1e-9)


def test_a_heel_that_bears_passes_one_over_an_edge_is_named_with_where_it_bore():
    firm = FootholdProbe("left", LANDING, "heel")
    touch(firm, HEEL + REACH - 0.005)
    assert firm.decide(LANDING + 1.0) == "" and firm.bears is True
    edge = FootholdProbe("left", LANDING, "heel")
    touch(edge, -0.033)
    problem = edge.decide(LANDING + 1.0)
    assert problem == ("the left sole landed on its heel but bore 3 cm behind its centre, "
                       "10 cm from its heel (at most 3): its heel is over an edge")
    assert edge.bears is False


def test_toes_over_an_edge_are_named_too():
    probe = FootholdProbe("right", LANDING, "toes")
    touch(probe, -0.12)          # the heel on the kerb it leaves
    assert "the right sole landed on its toes but bore 12 cm behind its centre, 25 cm from " \
           "its toes (at most 3): its toes are over an edge" == probe.decide(LANDING + 1.0)


def test_the_verdict_comes_from_the_first_touch_not_the_weight_that_follows():
    probe = FootholdProbe("left", LANDING, "heel")
    touch(probe, HEEL, start=LANDING + 0.1, ticks=3)
    assert probe.decide(LANDING + 0.1 + TOUCH / 2) is None       # touched, not long enough
    assert probe.decide(LANDING + 0.1 + TOUCH) == ""
    touch(probe, 0.05, start=LANDING + 0.2)                       # weight after the verdict
    assert probe.verdict() == "" and probe.decide(LANDING + 0.5) is None   # said once


def test_a_sole_that_never_touches_found_no_ground_and_readings_before_the_turn_do_not_count():
    probe = FootholdProbe("left", LANDING, "toes")
    probe.sample(LANDING - TURN - 0.05, (0.13, 0.0, 500.0))     # still swinging: not a touch
    probe.sample(LANDING + 0.1, None)                            # no weight on it
    assert probe.decide(LANDING + LATEST - 0.01) is None
    assert probe.decide(LANDING + LATEST) == ("the left sole found no ground: it carried no "
                                              f"weight {LATEST:.2f} s after it should have "
                                              "landed")


def test_a_sole_that_does_not_bear_stays_turned_until_its_foot_lifts():
    probe = FootholdProbe("left", LANDING, "heel")
    touch(probe, -0.03)
    decided = LANDING + 0.05 + TOUCH
    assert probe.decide(decided)
    assert probe.tilt(decided + 2 * TURN) == pytest.approx(-TILT)   # turned flat it would jam
    assert not probe.done(decided + 2 * TURN)
    probe.release(decided + 1.0)
    assert probe.tilt(decided + 1.0 + TURN) == pytest.approx(0.0)
    assert probe.done(decided + 1.0 + TURN)
