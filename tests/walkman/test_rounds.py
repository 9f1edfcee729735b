"""The robot's step period from its state rounds (walkman.hal.rounds), on made-up arrivals."""

import pytest
from hypothesis import given, strategies as st

from walkman.hal.rounds import AT_LEAST, KEPT, STALE_AFTER, RoundPeriod

MS = 1e-3


def fed(arrivals, seqs, robot_times=None) -> RoundPeriod:
    rounds = RoundPeriod()
    for k, (now, seq) in enumerate(zip(arrivals, seqs)):
        rounds.round(now, seq, None if robot_times is None else robot_times[k])
    return rounds


def test_a_burst_after_our_reader_was_held_up_does_not_shorten_the_robots_step():
    """A 1-ms robot; our reader stalled 20 ms, was handed the 20 states at once, and went
    on.  Once the stall's spacing has left the last 32 and the burst's have not, the
    arrivals say well under a millisecond; the robot's clock says one."""
    arrivals = [1.0 + k * MS for k in range(40)]
    stall_end = arrivals[-1] + 20 * MS
    arrivals += [stall_end + k * 0.01 * MS for k in range(20)]
    arrivals += [arrivals[-1] + (k + 1) * MS for k in range(KEPT - 19)]
    seqs = list(range(len(arrivals)))
    robot_times = [5.0 + seq * MS for seq in seqs]
    by_arrival = fed(arrivals, seqs).period(arrivals[-1])
    assert by_arrival < 0.8 * MS                     # what fc2's reader saw: 0.71 ms
    assert fed(arrivals, seqs, robot_times).period(arrivals[-1]) == pytest.approx(MS)


def test_read_chain_by_chain_a_step_said_twice_adds_nothing():
    """Eight chains of a 2-ms robot, one state each per step: a round can end on a chain
    that already said this step -- a round of no step, a tenth of a millisecond later."""
    arrivals, seqs, robot_times = [], [], []
    for k in range(KEPT):
        arrivals.append(1.0 + k * 2 * MS)
        seqs.append(k)
        robot_times.append(k * 2 * MS)
        if k % 3 == 0:                          # the same step again, just after
            arrivals.append(arrivals[-1] + 0.1 * MS)
            seqs.append(k)
            robot_times.append(robot_times[-1])
    rounds = fed(arrivals, seqs, robot_times)
    assert rounds.period(arrivals[-1]) == pytest.approx(2 * MS)


def test_a_robot_whose_time_does_not_move_is_timed_by_arrival():
    """fakeMotionControl stamps time 0: the arrivals say the step."""
    arrivals = [1.0 + k * 2 * MS for k in range(KEPT)]
    rounds = fed(arrivals, range(KEPT), [0.0] * KEPT)
    assert rounds.period(arrivals[-1]) == pytest.approx(2 * MS)


def test_missed_steps_are_counted_and_a_throttled_reader_knows_no_period():
    arrivals = [1.0 + k * 2 * MS for k in range(KEPT)]
    seqs = [k + (k // 4) for k in range(KEPT)]     # one round in four skipped a step
    assert fed(arrivals, seqs).period(arrivals[-1]) == pytest.approx(
        2 * MS * (KEPT - 1) / (seqs[-1] - seqs[0]))
    every_tenth = fed(arrivals, [10 * k for k in range(KEPT)])
    assert every_tenth.period(arrivals[-1]) == 0.0  # its own rhythm, not the robot's


def test_too_few_rounds_or_a_silent_robot_is_not_known():
    arrivals = [1.0 + k * MS for k in range(AT_LEAST)]
    assert fed(arrivals, range(AT_LEAST)).period(arrivals[-1]) == 0.0   # AT_LEAST - 1 spacings
    more = fed(arrivals + [arrivals[-1] + MS], range(AT_LEAST + 1))
    assert more.period(arrivals[-1] + MS) == pytest.approx(MS)
    assert more.period(arrivals[-1] + MS + STALE_AFTER) == 0.0


@given(step=st.floats(0.5 * MS, 10 * MS), jitter=st.lists(st.floats(0, 0.9), min_size=KEPT,
                                                          max_size=KEPT))
def test_any_arrival_jitter_leaves_the_robots_step_exact(step, jitter):
    seqs = list(range(KEPT))
    arrivals = [1.0 + (k + jitter[k]) * step for k in seqs]   # late by up to 0.9 step
    robot_times = [k * step for k in seqs]
    assert fed(arrivals, seqs, robot_times).period(arrivals[-1]) == pytest.approx(step)
