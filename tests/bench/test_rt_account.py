"""bench/rt_account.py: /proc's thread files parsed, real-time shares counted, a report read."""

from __future__ import annotations

import os
import sys
import threading
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "bench"))

import rt_account  # noqa: E402
from rt_account import (Interval, ProcError, Reading, Share, ThreadStat, account,  # noqa: E402
                        parse_schedstat, parse_stat, report)

# A real line of /proc/PID/task/TID/stat (a FIFO 60 thread on CPU 1), its command holding
# a space and a ')' as a thread may name itself.
STAT = ("4242 (py thon) x) R 1 4242 4242 0 -1 4194560 351 0 0 0 19 8 0 0 -41 0 24 0 "
        "39962 40488960 2355 18446744073709551615 1 1 0 0 0 0 0 4096 1256 0 0 0 17 1 60 1 "
        "0 0 0 0 0 0 0 0 0 0 0")


def test_a_stat_line_gives_class_priority_and_cpu_whatever_the_command_holds():
    assert parse_stat(STAT) == ThreadStat(policy=1, priority=60, cpu=1)


def test_this_thread_s_own_files_parse():
    where = f"/proc/self/task/{threading.get_native_id()}"
    stat = parse_stat(Path(f"{where}/stat").read_text())
    assert stat.policy == os.sched_getscheduler(0) and stat.cpu in os.sched_getaffinity(0)
    run_ns, wait_ns = parse_schedstat(Path(f"{where}/schedstat").read_text())
    assert run_ns > 0 and wait_ns >= 0


@pytest.mark.parametrize("text, said", [
    ("4242 python R 1 2", "no .\\). closing"),
    ("4242 (python) R 1 2 3", "6 fields, 41 expected"),
    (STAT.replace(" 17 1 60 1 ", " 17 x 60 1 "), "fields 39-41 are not numbers"),
])
def test_a_stat_line_that_is_not_the_kernel_s_is_refused_by_name(text, said):
    with pytest.raises(ProcError, match=said) as refused:
        parse_stat(text, "/proc/4242/task/4242/stat")
    assert "/proc/4242/task/4242/stat" in str(refused.value)


@pytest.mark.parametrize("text", ["1 2", "1 2 3 4", "a b c"])
def test_a_schedstat_that_is_not_three_numbers_is_refused(text):
    with pytest.raises(ProcError, match="schedstat"):
        parse_schedstat(text)


def test_shares_are_counted_for_real_time_threads_seen_twice():
    fifo, other = ThreadStat(1, 60, 0), ThreadStat(0, 0, 1)
    before = {(1, 1): Reading(fifo, 0, 0), (1, 2): Reading(other, 0, 0),
              (1, 3): Reading(fifo, 0, 0)}
    after = {(1, 1): Reading(fifo, 50_000_000, 4_000_000), (1, 2): Reading(other, 10**8, 0),
             (1, 4): Reading(fifo, 10**6, 0)}      # 3 ended, 4 began: neither counted
    assert account(before, after, 0.1) == [Share(tid=1, pid=1, priority=60, cpu=0,
                                                 run=pytest.approx(0.5), wait_ms=4.0)]


def test_the_report_names_the_longest_wait_and_who_ran_then():
    quiet = Interval(0.1, [Share(1, 10, 60, 0, 0.4, 0.1), Share(2, 20, 5, 1, 0.1, 0.0)])
    stall = Interval(0.2, [Share(1, 10, 60, 0, 0.3, 12.5), Share(2, 20, 5, 0, 0.7, 0.0)])
    text = report([quiet, stall], {10: "walkman.hal.server", 20: "bridge.main"}, 0.2)
    lines = text.splitlines()
    hal = next(line for line in lines if line.startswith("walkman.hal.server"))
    assert hal.split()[1:] == ["60", "1", "0.350", "13ms", "12.5ms", "0.20s"]
    waits = lines[lines.index(next(l for l in lines if l.startswith("longest waits"))) + 1]
    assert "12.5 ms  walkman.hal.server" in waits and "bridge.main FIFO 5 0.70" in waits
    assert "t=   0.20s  1.00  (cpu0 1.00)" in text


def test_a_sample_of_this_machine_reads_its_real_time_threads():
    readings = rt_account.sample()
    assert all(reading.stat.policy in (1, 2) for reading in readings.values())
