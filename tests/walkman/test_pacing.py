"""The control loop's schedule (walkman.gym.pacing), on a simulated clock and robot."""

from typing import List, Optional

import pytest

from walkman.gym.pacing import FAR_BEHIND, SLACK, TickSchedule, whole_multiple

MS = 1e-3


class Clock:
    def __init__(self) -> None:
        self.t = 1.0

    def __call__(self) -> float:
        return self.t

    def sleep_until(self, deadline: float) -> None:
        self.t = max(self.t, deadline)


class Rounds:
    """A robot whose state rounds arrive at the given times (and say their spacing)."""

    def __init__(self, clock: Clock, arrivals: List[float], period: float) -> None:
        self.clock, self.arrivals, self.period = clock, sorted(arrivals), period

    @property
    def round_period(self) -> float:
        return self.period

    @property
    def newest_round(self) -> float:
        return max([a for a in self.arrivals if a <= self.clock.t], default=0.0)

    def wait_round(self, after: float, timeout: float) -> Optional[float]:
        if self.newest_round > after:
            return self.newest_round
        coming = [a for a in self.arrivals if a > max(after, self.clock.t)]
        if coming and coming[0] - self.clock.t <= timeout:
            self.clock.t = coming[0]
            return coming[0]
        self.clock.t += max(timeout, 0.0)
        return None


def ticks(schedule: TickSchedule, clock: Clock, count: int, work: float = 0.0) -> List[float]:
    """When each of ``count`` ticks ran (each taking ``work`` seconds)."""
    times = []
    for _ in range(count):
        schedule.wait()
        times.append(clock.t)
        clock.t += work
    return times


def spaced(times: List[float]) -> List[float]:
    return [round((b - a) / MS, 6) for a, b in zip(times, times[1:])]


@pytest.mark.parametrize("period, round_period, expected", [
    (2 * MS, 2 * MS, True), (2 * MS, 1 * MS, True), (4 * MS, 2 * MS, True),
    (2.04 * MS, 2 * MS, True), (2.1 * MS, 2 * MS, False), (5 * MS, 2 * MS, False), (1 * MS, 2 * MS, False),
    (2 * MS, 0.0, False)])
def test_a_period_locks_only_to_a_whole_number_of_rounds(period, round_period, expected):
    assert whole_multiple(period, round_period) is expected


def test_without_a_robot_the_loop_keeps_the_wall_clock():
    clock = Clock()
    schedule = TickSchedule(2 * MS, clock=clock, sleep_until=clock.sleep_until)
    times = ticks(schedule, clock, 50, work=0.3 * MS)
    assert spaced(times) == [2.0] * 49
    assert schedule.locked_ticks == 0


@pytest.mark.parametrize("round_period", [2 * MS, 1 * MS])
def test_the_loop_locks_to_the_robots_rounds(round_period):
    clock = Clock()
    # Rounds at a phase the wall schedule would miss by 0.7 ms, for a second.
    robot = Rounds(clock, [clock.t + 0.7 * MS + k * round_period for k in range(1000)],
                   round_period)
    schedule = TickSchedule(2 * MS, lambda: robot, clock=clock, sleep_until=clock.sleep_until)
    times = ticks(schedule, clock, 100, work=0.3 * MS)
    # Within two ticks every tick runs the moment a round arrives: sense->move waits for none.
    assert all(t in robot.arrivals for t in times[2:])
    assert spaced(times[2:]) == [2.0] * 97
    assert schedule.locked_ticks >= 98


def test_the_loop_follows_the_robots_phase_not_each_rounds_jitter():
    clock = Clock()
    # Rounds 0.45 ms late, then 0.1 ms early: followed exactly, the early round after a late
    # one would arrive 0.55 ms before a deadline moved by the late one: out of the window.
    jitter = [(0.0, 0.45 * MS, -0.1 * MS)[k % 3] for k in range(1000)]
    robot = Rounds(clock, [clock.t + k * 2 * MS + j for k, j in enumerate(jitter)], 2 * MS)
    schedule = TickSchedule(2 * MS, lambda: robot, clock=clock, sleep_until=clock.sleep_until)
    times = ticks(schedule, clock, 200, work=0.3 * MS)
    assert schedule.wall_ticks == 0 and all(t in robot.arrivals for t in times)
    assert max(schedule.interval_errors) == pytest.approx(0.55 * MS)


def test_a_robot_at_another_rate_leaves_the_loop_on_the_wall_clock():
    clock = Clock()
    robot = Rounds(clock, [clock.t + k * 2 * MS for k in range(1000)], 2 * MS)
    schedule = TickSchedule(5 * MS, lambda: robot, clock=clock, sleep_until=clock.sleep_until)
    times = ticks(schedule, clock, 40)
    assert spaced(times) == [5.0] * 39
    assert schedule.locked_ticks == 0


def test_a_silent_robot_costs_a_slack_per_tick_and_the_loop_finds_it_again():
    clock = Clock()
    start = clock.t
    before = [start + k * 2 * MS for k in range(50)]                 # 100 ms of rounds
    after = [start + 300.9 * MS + k * 2 * MS for k in range(100)]     # silent 200 ms, new phase
    robot = Rounds(clock, before + after, 2 * MS)
    schedule = TickSchedule(2 * MS, lambda: robot, clock=clock, sleep_until=clock.sleep_until)
    times = ticks(schedule, clock, 200)
    silent = [t for t in times if start + 101 * MS < t < start + 300 * MS]
    # The loop keeps its rate while the robot is silent (each tick a slack late) ...
    assert set(spaced(silent)) == {2.0}
    behind_the_wall = [t - start - round((t - start) / (2 * MS)) * 2 * MS for t in silent]
    assert all(abs(late - SLACK * 2 * MS) < 1e-9 for late in behind_the_wall)
    # ... and runs on the robot's rounds again from its second tick after it is back.
    back = [t for t in times if t > after[0]]
    assert all(t in robot.arrivals for t in back[1:])


@pytest.mark.parametrize("with_robot", [True, False])
def test_a_tick_that_overran_by_far_starts_the_schedule_again_without_a_burst(with_robot):
    clock = Clock()
    robot = Rounds(clock, [clock.t + k * 2 * MS for k in range(1000)], 2 * MS)
    schedule = TickSchedule(2 * MS, lambda: robot if with_robot else None, clock=clock,
                            sleep_until=clock.sleep_until)
    ticks(schedule, clock, 10)
    clock.t += FAR_BEHIND + 0.05                 # run() blocked for 150 ms
    times = ticks(schedule, clock, 10)
    assert min(spaced(times)) >= 1.5             # not 75 ticks at once to catch up


def test_a_robot_a_little_slower_is_followed_and_one_slower_still_is_not():
    for robot_period, locks in ((2.04 * MS, True), (2.14 * MS, False)):
        clock = Clock()
        robot = Rounds(clock, [clock.t + k * robot_period for k in range(2000)], robot_period)
        schedule = TickSchedule(2 * MS, lambda: robot, clock=clock,
                                sleep_until=clock.sleep_until)
        times = ticks(schedule, clock, 400, work=0.3 * MS)
        intervals = spaced(times[2:])
        if locks:   # at the robot's rate, every tick on a round
            assert schedule.wall_ticks <= 2 and min(intervals) == max(intervals) == 2.04
        else:       # the wall clock's, never faster
            assert schedule.locked_ticks == 0 and set(intervals) == {2.0}


@pytest.mark.parametrize("case", ["phase jump", "1 kHz, a round lost"])
def test_finding_the_robots_phase_again_never_ticks_too_soon(case):
    clock = Clock()
    start = clock.t
    if case == "phase jump":    # the HAL slipped 0.6 ms (an overrun) 100 ms in
        arrivals = [start + k * 2 * MS + (0.6 * MS if k >= 50 else 0.0) for k in range(500)]
        robot = Rounds(clock, arrivals, 2 * MS)
    else:                       # a 1 kHz robot whose round 101 never reached us
        arrivals = [start + k * MS for k in range(1000) if k != 101]
        robot = Rounds(clock, arrivals, MS)
    schedule = TickSchedule(2 * MS, lambda: robot, clock=clock, sleep_until=clock.sleep_until)
    times = ticks(schedule, clock, 300, work=0.3 * MS)
    assert min(spaced(times)) >= 2 * 0.75       # ms
    assert schedule.wall_ticks <= 4 and all(t in robot.arrivals for t in times[-100:])


def test_a_stall_of_robot_and_loop_together_is_no_burst():
    clock = Clock()
    start = clock.t
    # Rounds for 100 ms, nothing while the whole box stalls 150 ms, rounds again after.
    arrivals = [start + k * 2 * MS for k in range(50)] + \
        [start + 260 * MS + k * 2 * MS for k in range(200)]
    robot = Rounds(clock, arrivals, 2 * MS)
    schedule = TickSchedule(2 * MS, lambda: robot, clock=clock, sleep_until=clock.sleep_until)
    ticks(schedule, clock, 50)
    clock.t = start + 250 * MS                   # the loop wakes first, robot still silent
    times = ticks(schedule, clock, 60)
    assert min(spaced(times)) >= 2 * 0.75


def test_sleep_until_never_returns_before_its_deadline_and_spins_only_its_lead(monkeypatch):
    import time as real_time

    from walkman.gym import pacing

    slept: List[float] = []
    real_sleep = real_time.sleep
    monkeypatch.setattr(pacing.time, "sleep", lambda s: (slept.append(s), real_sleep(s)))
    for wait in (0.0, 0.00005, 0.0004, 0.002):
        deadline = real_time.monotonic() + wait
        pacing.sleep_until(deadline)
        assert real_time.monotonic() >= deadline
    # the waits longer than the lead slept all but the lead, the shorter ones only spun
    lead = pacing.spin_lead()
    assert len(slept) == 2 and all(s < 0.002 - lead + 1e-4 for s in slept)


@pytest.mark.requires("root")
def test_a_realtime_thread_spins_less_than_a_normal_one():
    import os
    import threading

    from walkman.gym import pacing
    from walkman.realtime import make_realtime

    leads: List[float] = []

    def realtime() -> None:
        assert make_realtime(10), "SCHED_FIFO refused to root"
        leads.append(pacing.spin_lead())

    thread = threading.Thread(target=realtime)
    thread.start()
    thread.join()
    assert os.sched_getscheduler(0) != os.SCHED_FIFO
    assert leads == [pacing.SPIN_REALTIME] and pacing.spin_lead() == pacing.SPIN_NORMAL
