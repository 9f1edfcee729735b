"""The chaos run's figures (system/chaos_figures.py): pure functions on hand-made records.

Each record holds one kind of failure (lost, duplicated, out of order, late,
cancelled yet run) or of rightful ending (expired, cancelled), so each figure
is shown to count what it names and nothing else.
"""

from __future__ import annotations

import pytest

from system import chaos_figures as figures
from walkman.modules.witness import Execution


def test_a_clean_record_counts_nothing():
    sent = [(1, 10), (2, 20), (3, 30)]
    counted = figures.commands(sent, [10, 20, 30], [10, 20, 30])
    assert (counted.sent, counted.accepted, counted.executed) == (3, 3, 3)
    assert counted.lost == counted.duplicated == counted.out_of_order == []
    assert counted.unacknowledged == counted.retried_twice == []


def test_lost_duplicated_out_of_order_and_unacknowledged_commands_are_told_apart():
    sent = [(1, 10), (2, 20), (3, 30), (4, 40)]
    counted = figures.commands(sent, [10, 20, 30, 40], [10, 30, 20, 30, 99])
    assert counted.lost == [40]
    assert counted.duplicated == [30]
    assert counted.out_of_order == [20]      # ran after 30, which was sent later
    assert counted.unacknowledged == [99]    # ran, but no gateway logged sending it


def test_a_number_the_pilot_sent_twice_is_not_a_duplicate_of_the_system():
    sent = [(1, 10), (2, 20), (2, 21)]       # the pilot tried N=2 again after a failed call
    counted = figures.commands(sent, [10, 21], [10, 20, 21])
    assert counted.duplicated == [] and counted.lost == []
    assert counted.retried_twice == [2]


def status(t: float, seq: int, state: str = "counting", module: str = "counter") -> dict:
    return {"t": t, "module": module, "seq": seq, "state": state}


def test_news_after_a_fault_is_a_status_other_than_the_last_one_before_it():
    statuses = [status(1, 5), status(2, 6), status(10, 6), status(11, 2, "initializing"),
                status(12, 3, "idle", "gaze_control")]
    # at 10 the gateway republished seq 6 (roscore restart): old news; seq 2 is new
    assert figures.first_fresh(statuses, "counter", back=9.0) == 11
    assert figures.first_fresh(statuses, "counter", back=11.5) is None
    assert figures.first_fresh(statuses, "gaze_control", back=0.0) == 12


def test_the_schedule_is_seeded_and_draws_from_the_victims_given():
    pool = ["robot:hal", "pilot:gateway", figures.LINK]
    first = figures.schedule(7, 50, pool)
    assert first == figures.schedule(7, 50, pool)
    assert first != figures.schedule(8, 50, pool)
    assert {f.victim for f in first} == set(pool)
    for fault in first:
        low, high = figures.LINK_DOWN if fault.victim == figures.LINK else figures.PROCESS_DOWN
        assert low <= fault.down <= high
        assert fault.how in (figures.LINK_CUTS if fault.victim == figures.LINK
                             else (figures.KILL,))
    with pytest.raises(ValueError):
        figures.schedule(1, 3, [])


def test_blackouts_fit_the_soak():
    cuts = figures.blackouts(3, 1800.0)
    assert cuts == figures.blackouts(3, 1800.0) and len(cuts) >= 5
    ends = 0.0
    for start, seconds in cuts:
        assert start >= ends and 1.0 <= seconds <= 30.0
        ends = start + seconds
    assert ends < 1800.0


def test_percentiles_are_measured_values():
    values = [float(v) for v in range(1, 101)]
    assert figures.percentile(values, 0.5) == 50.0
    assert figures.percentile(values, 0.99) == 99.0
    assert figures.percentile([3.0, 1.0], 0.99) == 3.0
    assert figures.percentile([], 0.5) is None


def test_growth_after_the_warm_up_and_bounded_sizes():
    flat = [(float(t), 100.0 + (50.0 if t < 10 else 0.0)) for t in range(100)]
    assert figures.growth(flat, warm_up=20.0).percent == 0.0   # the warm-up does not count
    leaking = [(float(t), 100.0 + t) for t in range(100)]
    assert figures.growth(leaking, warm_up=0.0).percent > 50.0
    files = [(float(t), 5.0 + (t % 2)) for t in range(100)]   # a query open now and then
    assert figures.growth(files, warm_up=0.0, statistic=min).percent == 0.0
    assert figures.bounded([(float(t), min(t, 20) * 1e6) for t in range(100)])
    assert not figures.bounded([(float(t), t * 1e6) for t in range(100)])




# -- commands that end without running ---------------------------------------------------------


def test_an_expired_cancelled_or_interrupted_command_is_accounted_for_not_lost():
    sent = [(1, 10), (2, 20), (3, 30), (4, 40), (5, 50)]
    ended = figures.endings(expired=[20], cancelled=[30], interrupted=[50])
    counted = figures.commands(sent, [10, 20, 30, 40, 50], [10], ended)
    assert counted.expired == [20] and counted.cancelled == [30]
    assert counted.interrupted == [50]          # its module killed holding it, and said so
    assert counted.lost == [40]                 # no word of how it ended: lost
    # Without the endings the same record loses four.
    assert figures.commands(sent, [10, 20, 30, 40, 50], [10]).lost == [20, 30, 40, 50]


def test_a_cancel_the_bridge_confirmed_wins_over_an_expiry():
    assert figures.endings(expired=[5, 6], cancelled=[6]) == {5: figures.EXPIRED,
                                                              6: figures.CANCELLED}


def ran(seq: int, at: float, age=None, validity=None) -> Execution:
    return Execution("count", seq, at, age, validity)


def test_a_short_lived_command_that_started_in_time_is_not_late():
    asked = {1: (100.0, 3.0), 2: (100.0, 0.0)}
    checked = figures.deadlines([ran(1, 102.9, 0.1, 3.0), ran(2, 500.0)], asked, {})
    assert checked.late == [] and checked.cancelled_ran == []
    assert checked.checked == 1 and checked.closest_s == pytest.approx(0.1)


def test_late_commands_are_found_by_the_wall_clock_by_their_age_and_by_their_state():
    asked = {1: (100.0, 3.0), 2: (100.0, 3.0), 3: (100.0, 3.0), 4: (100.0, 3.0)}
    executions = [ran(1, 103.0 + figures.DEADLINE_SLACK + 0.01, 0.2, 3.0),  # wall clock
                  ran(2, 101.0, 3.5, 3.0),    # arrived older than its validity
                  ran(3, 101.0, 0.1, 3.0),    # in time, but said expired: it cannot run
                  ran(4, 103.0 + figures.DEADLINE_SLACK - 0.01, 0.2, 3.0)]  # within slack
    checked = figures.deadlines(executions, asked, {3: figures.EXPIRED})
    assert checked.late == [1, 2, 3]
    assert checked.closest_s == pytest.approx(-figures.DEADLINE_SLACK - 0.01)


def test_a_cancelled_command_that_ran_is_counted():
    checked = figures.deadlines([ran(7, 10.0), ran(8, 11.0)], {}, {8: figures.CANCELLED})
    assert checked.cancelled_ran == [8] and checked.late == []
