"""The drywall's judge: what a running drill's tip cuts, against the circle marked on it."""

import math

import numpy as np
import pytest
from hypothesis import given, strategies as st

from walkman.hal.drywall import SECTORS, Drywall

CENTRE, NORMAL, RADIUS = (0.85, 0.2, 1.2), (-1.0, 0.0, 0.0), 0.08


def panel(**options) -> Drywall:
    return Drywall(CENTRE, NORMAL, RADIUS, **options)


def on_circle(angle_deg: float, radius: float = RADIUS, depth: float = 0.02) -> np.ndarray:
    """A point ``depth`` into the panel, ``radius`` from the centre, ``angle_deg`` clockwise
    from the top as the robot (looking along +x) sees it: the robot's right is -y."""
    angle = math.radians(angle_deg)
    return np.array(CENTRE) + np.array([depth, -radius * math.sin(angle),
                                        radius * math.cos(angle)])


def test_a_running_drill_taken_once_round_cuts_the_circle_out():
    wall = panel()
    events = wall.feed(on_circle(0, depth=-0.03), True)           # in front of the panel
    assert events == [] and wall.cut_points == 0
    events = wall.feed(on_circle(0), True)
    assert events == ["drywall: the bit goes in 8.0 cm from the circle's centre at 0 degrees"]
    said = []
    for step in range(1, 721):
        said += wall.feed(on_circle(step / 2), True)
    assert said == ["drywall: the circle is cut out (360 degrees, largest miss 0.0 cm)"]
    assert wall.cut_out and wall.cut_degrees == SECTORS
    assert wall.feed(on_circle(0, depth=-0.01), True) == [
        "drywall: the bit comes out 8.0 cm from the circle's centre at 0 degrees "
        "(360 degrees of the circle cut)"]
    assert wall.summary() == "360 degrees cut, largest miss 0.0 cm, cut out"


def test_the_angle_is_clockwise_as_the_robot_sees_the_wall():
    """Points placed by hand, not by :func:`on_circle`: the top of the circle is 0 degrees,
    the robot's right of the centre (-y: the robot looks along +x) 90."""
    centre = np.array(CENTRE)
    for point, sector in ((centre + [0.02, 0.0, RADIUS], 0), (centre + [0.02, -RADIUS, 0.0], 90),
                          (centre + [0.02, RADIUS, 0.0], 270)):
        wall = panel()
        wall.feed(point, True)
        assert wall.cut_degrees == 1 and wall.sectors[sector], (point, sector)


def test_a_stopped_drill_cuts_nothing_and_says_so_once():
    wall = panel()
    assert wall.feed(on_circle(0), False) == [
        "drywall: the bit pushes on the panel with the drill off (it cuts nothing)"]
    assert all(wall.feed(on_circle(angle), False) == [] for angle in range(1, 360))
    wall.feed(on_circle(0, depth=-0.01), False)
    assert wall.feed(on_circle(0), False) == []          # told once
    assert wall.cut_degrees == 0 and wall.cut_points == 0


def test_a_path_off_the_circle_is_a_wrong_cut_not_the_circle():
    wall = panel()
    for step in range(721):                               # 2 cm outside the circle
        wall.feed(on_circle(step / 2, RADIUS + 0.02), True)
    assert not wall.cut_out and wall.cut_degrees == 0
    assert wall.largest_miss == pytest.approx(0.02)
    assert wall.summary() == "0 degrees cut, largest miss 2.0 cm"


def test_half_a_circle_is_half_cut():
    wall = panel()
    for step in range(361):
        wall.feed(on_circle(step / 2), True)
    assert wall.cut_degrees == 181 and not wall.cut_out


@given(st.floats(-0.012, 0.012), st.floats(0.001, 0.05))
def test_a_circle_cut_within_the_tolerance_is_cut_out(radial_error, depth):
    wall = panel()
    for step in range(721):
        wall.feed(on_circle(step / 2, RADIUS + radial_error, depth), True)
    assert wall.cut_out
    assert wall.largest_miss == pytest.approx(abs(radial_error), abs=1e-9)


def test_the_bit_cuts_along_its_path_between_two_samples():
    """A tip sampled every 5 degrees (a module catching up after a stall moves it that fast)
    still cut every degree it passed: the simulator samples it, the drill cuts continuously."""
    wall = panel()
    said = []
    for angle in range(0, 365, 5):
        said += wall.feed(on_circle(angle), True)
    assert wall.cut_out and said[-1].startswith("drywall: the circle is cut out")
    assert wall.largest_miss == pytest.approx(0.0, abs=1e-9)   # the samples', not the chords'


def test_a_jump_across_the_panel_cuts_only_where_it_crosses_the_circle():
    wall = panel()
    wall.feed(on_circle(0), True)
    wall.feed(on_circle(180), True)                     # straight through the centre
    assert [k for k, cut in enumerate(wall.sectors) if cut] == [0, 180]


def test_nothing_is_cut_between_samples_with_the_drill_off_or_the_bit_out():
    wall = panel()
    wall.feed(on_circle(0.5), True)                     # mid-sector: no rounding to judge
    wall.feed(on_circle(10.5), False)                   # the drill stopped on the way
    wall.feed(on_circle(20.5), True)
    wall.feed(on_circle(30.5, depth=-0.01), True)       # out of the panel
    wall.feed(on_circle(40.5), True)
    assert [k for k, cut in enumerate(wall.sectors) if cut] == [0, 20, 40]
