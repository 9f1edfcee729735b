"""walkman.hal.clock: a module's time follows the robot's, never backwards, never leaping."""

from typing import List

import pytest
from hypothesis import given
from hypothesis import strategies as st

from walkman.hal.clock import RobotClock

MAX_AHEAD = 0.01
SILENCE = 0.5


class Wall:
    def __init__(self, start: float = 100.0) -> None:
        self.now = start

    def __call__(self) -> float:
        return self.now


def make(start: float = 100.0):
    wall = Wall(start)
    return RobotClock(MAX_AHEAD, SILENCE, wall=wall), wall


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


@pytest.mark.parametrize("polls", [0, 1, 3])
def test_a_robot_slower_than_the_wall_slows_the_clock_down(polls):
    """The physics at half real time for a second: the clock gives its half second, however
    often a module reads it between two states."""
    clock, wall = make()
    clock.observe(0.0)
    for step in range(1, 101):
        for poll in range(polls):
            wall.now = 100.0 + (step - 1) * 0.01 + (poll + 1) * 0.01 / (polls + 1)
            clock.now()
        wall.now = 100.0 + step * 0.01
        clock.observe(step * 0.005)
    assert 100.5 <= clock.now() <= 100.5 + MAX_AHEAD


def test_it_stands_still_while_the_robot_is_silent_and_goes_on_from_there():
    clock, wall = make()
    clock.observe(5.0)
    wall.now = 103.0                # 3 s without a state
    assert clock.now() == pytest.approx(100.01)  # ran on one max_ahead, then waited
    clock.observe(8.0)              # back, its time ran on meanwhile: no leap
    assert clock.now() == pytest.approx(100.01)
    wall.now = 103.004
    clock.observe(8.004)
    assert clock.now() == pytest.approx(100.014)


def test_a_robot_that_stamps_its_state_with_arrival_times_does_not_leap_either():
    clock, wall = make()
    clock.observe(wall.now)
    wall.now = 102.0                # silent for 2 s, then back
    clock.observe(wall.now)
    assert clock.now() == pytest.approx(100.01)


def test_time_that_ran_on_without_a_silence_does_not_leap():
    """A wall clock set forward, or a connection remade while the robot ran on."""
    clock, wall = make()
    clock.observe(10.0)
    wall.now = 100.1
    clock.observe(70.0)
    assert clock.now() == pytest.approx(100.01)


def test_a_restarted_robot_does_not_turn_the_clock_back_nor_stop_it():
    clock, wall = make()
    clock.observe(50.0)
    wall.now = 100.005
    before = clock.now()
    clock.observe(0.0)              # the HAL restarted: its time is 0 again
    assert clock.now() == before
    wall.now = 100.050
    clock.observe(0.045)
    assert clock.now() == pytest.approx(before + 0.045)


def test_a_chain_whose_state_is_a_little_older_is_ignored():
    clock, wall = make()
    clock.observe(7.020)            # the legs' state
    clock.observe(7.018)            # the arms', sent 2 ms earlier, read after
    wall.now = 100.002
    clock.observe(7.022)
    assert clock.now() == pytest.approx(100.002)


def test_a_chain_late_by_more_than_a_restart_step_does_not_move_the_clock_on():
    clock, wall = make()
    clock.observe(7.0)
    wall.now = 100.002
    clock.observe(6.2)              # a state 0.8 s late: taken for a restart
    wall.now = 100.004
    clock.observe(7.004)            # the newest again: no leap of 0.8 s
    assert clock.now() == pytest.approx(100.004, abs=MAX_AHEAD)


#: How the robot's time moves at a state: as fast as the wall or slower (a fraction of the
#: wall time since its previous state), a restart (back by more than RESTART_STEP_BACK), or a
#: leap forward (further than the wall ran since its previous state, and then some).
robot_steps = st.one_of(st.tuples(st.just("runs"), st.floats(0, 1)),
                        st.tuples(st.just("restarts"), st.floats(0.6, 60)),
                        st.tuples(st.just("leaps"), st.floats(0.02, 60)))


@given(st.lists(st.tuples(st.floats(0, 0.6), st.booleans(), robot_steps), max_size=60))
def test_it_never_goes_backwards_nor_ahead_of_a_robot_that_never_outruns_the_wall(events: List):
    clock, wall = make()
    robot, observed_at, last = 0.0, wall.now, clock.now()
    for wall_step, observe, (kind, amount) in events:
        wall.now += wall_step
        if observe:
            waited = wall.now - observed_at
            robot = {"runs": robot + amount * waited, "restarts": max(0.0, robot - amount),
                     "leaps": robot + waited + MAX_AHEAD + amount}[kind]
            clock.observe(robot)
            observed_at = wall.now
        value = clock.now()
        assert last <= value <= wall.now + 1e-9
        last = value
