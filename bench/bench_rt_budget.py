#!/usr/bin/env python3
"""The kernel's real-time budget: how long a FIFO loop stalls when it takes nearly a CPU.

Linux keeps normal tasks alive beside real-time ones: since 6.12 a "fair server" (a
deadline task) gives them 50 ms in every second on a CPU whose real-time threads would
otherwise starve them (before 6.12, RT throttling at ``sched_rt_runtime_us`` did the same).
It takes those 50 ms *at once*.  A robot's loops are real-time threads; when together they
keep a CPU busy above the budget, every one of them stops for up to 50 ms, once a second.

This bench runs one SCHED_FIFO 60 thread on one CPU that works ``duty`` of every 2-ms
period and sleeps to the next, beside a normal-priority busy loop on the same CPU, and
prints the share of the time it worked, its longest tick (from one period's start to the
next) and how many ticks took over 10 ms, per duty.

Measured on the 2-core CI machine (2026-11-29, Linux 6.18): working 0.50, 0.80 and 0.90 of
the time, the longest tick 3.0-5.2 ms, none over 10 ms; working 0.956-0.974, 54-56 ms, four
ticks over 10 ms in 4 s (a fresh-clone test run beside it; idle, the same: 56 ms).
``sched_rt_runtime_us = -1`` changed nothing (the fair server is not RT throttling).  A free-standing robot's real-time threads take about one core (physics
35-45 %, walking's loop 30-37 %, state ports 20 %); a second robot's beside it take a CPU
over the budget: fc74's walking robot stalled 52 ms (physics) and 59 ms (loop) and
tripped its balance guard.  Hence tests/robot_slots.py.

Usage (root, for SCHED_FIFO): ``.venv/bin/python bench/bench_rt_budget.py [--seconds 6]
[--duty 0.5 --duty 0.97]``.
"""

from __future__ import annotations

import argparse
import math
import multiprocessing
import os
import sys
import time
from pathlib import Path
from typing import List, Optional, Tuple

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from host import say_machine  # noqa: E402  (bench/ is the script's folder)

PRIORITY = 60               # the HAL's physics loop
PERIOD = 0.002              # the robot's 500-Hz loops
CPU = min(os.sched_getaffinity(0))      # the first CPU this process may use
DUTIES = (0.5, 0.8, 0.9, 0.95, 0.97, 0.99)


def _burn() -> None:
    os.sched_setaffinity(0, {CPU})
    while True:
        pass


def ticks(duty: float, seconds: float) -> Tuple[List[float], float]:
    """The periods (s) of a FIFO loop on ``CPU`` that works ``duty`` of each 2 ms and sleeps
    to the next period's start, for ``seconds``, and the share of the time it worked; run
    in a child so its class and affinity end with it."""
    os.sched_setaffinity(0, {CPU})
    os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(PRIORITY))
    periods: List[float] = []
    busy = 0.0
    start = last = time.monotonic()
    due = start
    while last < start + seconds:
        began = time.monotonic()
        while time.monotonic() - began < duty * PERIOD:
            pass
        busy += time.monotonic() - began
        due = max(due + PERIOD, began)      # late: the next period starts now
        time.sleep(max(0.0, due - time.monotonic()))
        now = time.monotonic()
        periods.append(now - last)
        last = now
    return periods, busy / (last - start)


def _child(duty: float, seconds: float, out) -> None:
    out.send(ticks(duty, seconds))


def measure(duty: float, seconds: float) -> Tuple[List[float], float]:
    """:func:`ticks` in a child process; a child that fails says why, not a hang."""
    parent, child = multiprocessing.Pipe(duplex=False)
    runner = multiprocessing.Process(target=_child, args=(duty, seconds, child))
    runner.start()
    child.close()           # ours: the child's end closes with it, and recv() sees it
    try:
        return parent.recv()
    except EOFError:
        runner.join()
        raise SystemExit(f"the measuring child failed (exit code {runner.exitcode})") from None
    finally:
        runner.join()


def _rt_runtime() -> str:
    try:
        return Path("/proc/sys/kernel/sched_rt_runtime_us").read_text().strip()
    except OSError:
        return "unknown"


def main(argv: Optional[List[str]] = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=6.0)
    parser.add_argument("--duty", type=float, action="append", default=None,
                        help="share of each 2-ms period the FIFO loop works (0 < duty < 1); "
                             "repeat to compare (default: 0.5 to 0.99)")
    options = parser.parse_args(argv)
    duties = options.duty or list(DUTIES)
    for duty in duties:
        if not 0.0 < duty < 1.0:
            parser.error(f"--duty takes a share between 0 and 1, not {duty}")
    if not 0 < options.seconds < math.inf:
        parser.error(f"--seconds must be positive, not {options.seconds}")
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(PRIORITY))
        os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
    except PermissionError:
        parser.error(f"needs SCHED_FIFO {PRIORITY} (root or CAP_SYS_NICE)")
    say_machine()
    print(f"sched_rt_runtime_us {_rt_runtime()}; a FIFO {PRIORITY} loop of 2 ms on CPU {CPU} "
          f"beside a normal busy loop there, {options.seconds:g} s per row")
    burner = multiprocessing.Process(target=_burn, daemon=True)
    burner.start()
    try:
        print(f"{'duty':>6} {'worked':>7} {'ticks':>6} {'median ms':>10} {'max ms':>8} "
              f"{'> 10 ms':>8}")
        for duty in duties:
            periods, worked = measure(duty, options.seconds)
            periods.sort()
            n = len(periods)
            print(f"{duty:>6.2f} {worked:>7.3f} {n:>6} {periods[n // 2] * 1e3:>10.3f} "
                  f"{periods[-1] * 1e3:>8.1f} {sum(p > 0.010 for p in periods):>8}",
                  flush=True)
    finally:
        burner.terminate()
    say_machine("after")
    return 0


if __name__ == "__main__":
    sys.exit(main())
