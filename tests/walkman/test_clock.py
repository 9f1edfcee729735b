"""walkman.hal.clock: a module's time follows the robot's, never backwards, still while silent."""

from typing import List

import pytest
from hypothesis import given
from hypothesis import strategies as st

from walkman.hal.clock import RobotClock


class Wall:
    def __init__(self, start: float = 100.0) -> None:
        self.now = start

    def __call__(self) -> float:
        return self.now


def make(max_ahead: float = 0.01, start: float = 100.0):
    wall = Wall(start)
    return RobotClock(max_ahead, wall=wall), wall


def test_before_the_first_state_it_is_the_wall_clock_and_then_goes_on_from_there():
    clock, wall = make()
    assert clock.now() == 100.0
    wall.now = 100.5
    clock.observe(0.0)              # the robot's time starts at 0: the clock does not jump
    assert clock.now() == 100.5
    wall.now = 100.504
    assert clock.now() == 100.504   # between two states it runs with the wall
    clock.observe(0.002)            # the robot is behind the wall: the clock waits for it
    assert clock.now() == 100.504
    wall.now = 100.508
    assert clock.now() == pytest.approx(100.506)


def test_a_robot_slower_than_the_wall_slows_the_clock_down():
    clock, wall = make(max_ahead=0.01)
    clock.observe(0.0)
    for step in range(1, 101):     # the physics runs at half real time for a second
        wall.now = 100.0 + step * 0.01
        clock.observe(step * 0.005)
    assert clock.now() == pytest.approx(100.5)  # the robot's half second, not the wall's one


def test_it_stands_still_while_the_robot_is_silent_and_goes_on_from_there():
    clock, wall = make(max_ahead=0.01)
    clock.observe(5.0)
    wall.now = 103.0               # 3 s without a state
    held = clock.now()
    assert held == pytest.approx(100.01)  # ran on one max_ahead, then waited
    clock.observe(5.002)           # back: the trajectory goes on from where it stood
    assert clock.now() == held
    wall.now = 103.008
    clock.observe(5.010)
    wall.now = 103.012
    assert clock.now() == pytest.approx(100.014)


def test_a_restarted_robot_does_not_turn_the_clock_back():
    clock, wall = make()
    clock.observe(50.0)
    wall.now = 100.005
    before = clock.now()
    clock.observe(0.0)             # the HAL restarted: its time is 0 again
    assert clock.now() >= before
    wall.now = 100.007
    clock.observe(0.002)
    assert clock.now() == pytest.approx(before + 0.002)


@given(st.lists(st.tuples(st.floats(0, 0.05), st.floats(-1, 1), st.booleans()), max_size=60))
def test_it_never_goes_backwards(events: List):
    clock, wall = make()
    robot, last = 0.0, clock.now()
    for wall_step, robot_step, observe in events:
        wall.now += wall_step
        if observe:
            robot = max(0.0, robot + robot_step)
            clock.observe(robot)
        value = clock.now()
        assert value >= last
        last = value


def test_a_chain_whose_state_is_a_little_older_does_not_count_as_a_restart():
    clock, wall = make()
    clock.observe(7.020)           # the legs' state
    clock.observe(7.018)           # the arms', sent 2 ms earlier, read after
    wall.now = 100.002
    assert clock.now() == pytest.approx(100.002)
