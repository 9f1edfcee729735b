"""The burst rule: 1st, 10th, 100th ... of a burst logged, a calm spell starts a new one."""

from __future__ import annotations

from yarp_lite.bursts import Burst


def test_burst_restarts_after_a_quiet_spell():
    now = [0.0]
    burst = Burst(quiet=10.0, clock=lambda: now[0])
    logged = []
    for i in range(1, 101):
        now[0] += 0.01
        if burst.record():
            logged.append(i)
    assert logged == [1, 10, 100]
    now[0] += 11.0
    assert burst.record() and burst.count == 1 and burst.total == 101  # told at once
    now[0] += 1.0
    assert not burst.record()


def test_several_occurrences_at_once_cross_a_mark():
    burst = Burst(clock=lambda: 0.0)
    assert burst.record(5)          # holds the 1st
    assert not burst.record(4)      # 6th..9th
    assert burst.record(50)         # 10th..59th
    assert burst.count == 59
