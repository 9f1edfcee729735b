#!/usr/bin/env python3
"""Who holds the real-time CPU: a per-thread account of the machine's SCHED_FIFO/RR threads.

A free-standing robot trips its balance guard when its physics or its walking loop waits
for a CPU (tests/robot_slots.py, bench_rt_budget.py).  Whether a stall came from real-time
load near the kernel's budget, or from one thread at a higher priority running long, the
logs of the robot's programs cannot say: they see only their own late ticks.  This account
watches every thread of the machine from outside while a test or the main job runs.

Theory of operation.  Every ``--interval`` the sampler reads, for each thread,
``/proc/PID/task/TID/stat`` (its scheduling class, real-time priority and the CPU it last ran
on) and ``schedstat`` (nanoseconds on a CPU, nanoseconds runnable but waiting for one).  The
difference between two samples of a real-time thread is its CPU share and its *wait* over
the interval; the wait of a FIFO thread is exactly the stall its ticks see.  The parsing and
the arithmetic are pure functions over the files' text (:func:`parse_stat`,
:func:`parse_schedstat`, :func:`account`); only :func:`sample` reads ``/proc``.  At the end
(``--seconds`` over, or Ctrl-C) it prints, per process, its real-time threads' priorities,
CPU share and longest wait in one interval; the intervals where the real-time threads took
the most CPU; and the intervals where a thread waited longest, with what else ran then.

Usage (root, to read every process's threads)::

    .venv/bin/python bench/rt_account.py --seconds 120 [--interval 0.1] &
    .venv/bin/python -m pytest tests/system/test_pilot_gui.py -k terrain
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Dict, Iterable, List, NamedTuple, Optional, Tuple

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from host import say_machine  # noqa: E402  (bench/ is the script's folder)

SCHED_FIFO, SCHED_RR = 1, 2
POLICY_NAMES = {0: "OTHER", 1: "FIFO", 2: "RR", 3: "BATCH", 5: "IDLE", 6: "DEADLINE"}


class ProcError(ValueError):
    """A /proc file's text is not what the kernel writes (names the file and the field)."""


class ThreadStat(NamedTuple):
    policy: int
    priority: int
    cpu: int


def parse_stat(text: str, where: str = "stat") -> ThreadStat:
    """``/proc/PID/task/TID/stat``: its class (field 41), real-time priority (40) and last
    CPU (39).  The command (field 2) is in parentheses and may itself hold spaces and ')'."""
    close = text.rfind(")")
    if close < 0:
        raise ProcError(f"{where}: no ')' closing the command name")
    fields = text[close + 2:].split()      # fields[0] is field 3, the state
    if len(fields) < 39:
        raise ProcError(f"{where}: {len(fields) + 2} fields, 41 expected")
    try:
        return ThreadStat(policy=int(fields[38]), priority=int(fields[37]), cpu=int(fields[36]))
    except ValueError as exc:
        raise ProcError(f"{where}: fields 39-41 are not numbers ({exc})") from None


def parse_schedstat(text: str, where: str = "schedstat") -> Tuple[int, int]:
    """``/proc/PID/task/TID/schedstat``: (ns on a CPU, ns runnable waiting for one)."""
    words = text.split()
    if len(words) != 3:
        raise ProcError(f"{where}: {len(words)} numbers, 3 expected")
    try:
        return int(words[0]), int(words[1])
    except ValueError:
        raise ProcError(f"{where}: not numbers: {text.strip()!r}") from None


@dataclass(frozen=True)
class Reading:
    """One thread at one sample."""
    stat: ThreadStat
    run_ns: int
    wait_ns: int


@dataclass(frozen=True)
class Share:
    """One real-time thread over one interval."""
    tid: int
    pid: int
    priority: int
    cpu: int
    run: float          # its CPU share of the interval (1.0: a whole CPU)
    wait_ms: float      # how long it was runnable without a CPU


Sample = Dict[Tuple[int, int], Reading]        # (pid, tid) -> reading


def account(before: Sample, after: Sample, seconds: float) -> List[Share]:
    """The real-time threads' shares between two samples ``seconds`` apart; a thread that
    started or ended between them is left out, as is one that is not real-time now."""
    shares = []
    for key, now in after.items():
        then = before.get(key)
        if then is None or now.stat.policy not in (SCHED_FIFO, SCHED_RR):
            continue
        shares.append(Share(tid=key[1], pid=key[0], priority=now.stat.priority,
                            cpu=now.stat.cpu, run=(now.run_ns - then.run_ns) / 1e9 / seconds,
                            wait_ms=(now.wait_ns - then.wait_ns) / 1e6))
    return shares


def sample(proc: Path = Path("/proc")) -> Sample:
    """Every real-time thread's reading now (threads that end while it reads are skipped;
    only a real-time thread's ``schedstat`` is read: a sample of 400 threads takes 10 ms)."""
    readings: Sample = {}
    for pid in os.listdir(proc):
        if not pid.isdigit():
            continue
        try:
            tids = os.listdir(f"{proc}/{pid}/task")
        except OSError:
            continue
        for tid in tids:
            where = f"{proc}/{pid}/task/{tid}"
            try:
                with open(f"{where}/stat", encoding="utf-8", errors="replace") as file:
                    stat = parse_stat(file.read(), f"{where}/stat")
                if stat.policy not in (SCHED_FIFO, SCHED_RR):
                    continue
                with open(f"{where}/schedstat", encoding="ascii") as file:
                    run_ns, wait_ns = parse_schedstat(file.read(), f"{where}/schedstat")
            except (OSError, ProcError):
                continue
            readings[(int(pid), int(tid))] = Reading(stat, run_ns, wait_ns)
    return readings


def command_line(pid: int, proc: Path = Path("/proc")) -> str:
    """The program a process runs, shortened to what tells the robot's programs apart."""
    try:
        words = (proc / str(pid) / "cmdline").read_bytes().split(b"\0")
    except OSError:
        return f"pid {pid} (ended)"
    words = [w.decode(errors="replace") for w in words if w]
    if not words:         # a kernel thread (migration/0, a NIC's interrupt thread)
        try:
            return f"[{(proc / str(pid) / 'comm').read_text().strip()}]"
        except OSError:
            return f"pid {pid} (ended)"
    if words and words[0].endswith(("python", "python3")) and len(words) > 1:
        words = words[2:] if words[1] == "-m" and len(words) > 2 else words[1:]
    return " ".join(words)[:70] or f"pid {pid}"


@dataclass
class Interval:
    at: float                     # seconds since the account began
    shares: List[Share]

    @property
    def total(self) -> float:
        return sum(share.run for share in self.shares)

    def per_cpu(self) -> Dict[int, float]:
        cpus: Dict[int, float] = {}
        for share in self.shares:     # by the CPU each last ran on: an approximation
            cpus[share.cpu] = cpus.get(share.cpu, 0.0) + share.run
        return cpus

    def worst(self) -> Optional[Share]:
        return max(self.shares, key=lambda share: share.wait_ms, default=None)


def report(intervals: List[Interval], names: Dict[int, str], seconds: float,
           top: int = 8) -> str:
    """The account as a reader wants it: per process, then the busiest and the worst
    intervals."""
    lines: List[str] = []
    if not intervals:
        return "no interval measured"
    groups: Dict[Tuple[int, int], Dict[str, object]] = {}   # (pid, priority) -> totals
    for interval in intervals:
        for share in interval.shares:
            entry = groups.setdefault((share.pid, share.priority),
                                      {"threads": set(), "cpu": 0.0, "wait_ms": 0.0,
                                       "worst_ms": 0.0, "worst_at": 0.0})
            entry["threads"].add(share.tid)
            entry["cpu"] += share.run / len(intervals)
            entry["wait_ms"] += share.wait_ms
            if share.wait_ms > entry["worst_ms"]:
                entry["worst_ms"], entry["worst_at"] = share.wait_ms, interval.at
    lines.append(f"real-time threads over {seconds:.1f} s in {len(intervals)} intervals "
                 f"of {seconds / len(intervals) * 1e3:.0f} ms (cpu: cores on average; "
                 f"waited: runnable without a CPU, in all and the most in one interval)")
    lines.append(f"{'process':<62} {'prio':>4} {'thr':>4} {'cpu':>6} {'waited':>8} "
                 f"{'worst':>7} {'at':>8}")
    for (pid, priority), entry in sorted(groups.items(), key=lambda item: -item[1]["cpu"]):
        if entry["cpu"] < 0.0005 and entry["wait_ms"] < 1:
            continue          # idle kernel threads
        lines.append(f"{names.get(pid, str(pid))[:62]:<62} {priority:>4} "
                     f"{len(entry['threads']):>4} {entry['cpu']:>6.3f} "
                     f"{entry['wait_ms']:>6.0f}ms {entry['worst_ms']:>5.1f}ms "
                     f"{entry['worst_at']:>7.2f}s")
    totals = sorted(intervals, key=lambda interval: -interval.total)
    lines.append(f"busiest intervals (cores of real-time CPU; by the CPU each thread last "
                 f"ran on):")
    for interval in totals[:top]:
        cpus = " ".join(f"cpu{cpu} {load:.2f}" for cpu, load in sorted(interval.per_cpu().items()))
        lines.append(f"  t={interval.at:7.2f}s  {interval.total:.2f}  ({cpus})")
    lines.append("longest waits of one thread in one interval, and who ran then:")
    waits = sorted((i for i in intervals if i.worst() is not None),
                   key=lambda interval: -interval.worst().wait_ms)
    for interval in waits[:top]:
        worst = interval.worst()
        busiest = sorted(interval.shares, key=lambda share: -share.run)[:3]
        ran = ", ".join(f"{names.get(s.pid, s.pid)[:28]} FIFO {s.priority} {s.run:.2f}"
                        for s in busiest)
        lines.append(f"  t={interval.at:7.2f}s  {worst.wait_ms:5.1f} ms  "
                     f"{names.get(worst.pid, worst.pid)[:40]} (tid {worst.tid}, FIFO "
                     f"{worst.priority}); total {interval.total:.2f}: {ran}")
    return "\n".join(lines)


def run(seconds: Optional[float], interval: float) -> Tuple[List[Interval], Dict[int, str],
                                                            float]:
    stopping = []
    signal.signal(signal.SIGINT, lambda *_: stopping.append(1))
    signal.signal(signal.SIGTERM, lambda *_: stopping.append(1))
    names: Dict[int, str] = {}
    intervals: List[Interval] = []
    start = last_at = time.monotonic()
    last = sample()
    while not stopping and (seconds is None or time.monotonic() - start < seconds):
        time.sleep(interval)
        now_at, now = time.monotonic(), sample()
        shares = account(last, now, now_at - last_at)
        for share in shares:
            if share.pid not in names:
                names[share.pid] = command_line(share.pid)
        intervals.append(Interval(now_at - start, shares))
        last, last_at = now, now_at
    return intervals, names, last_at - start


def main(argv: Optional[Iterable[str]] = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, help="how long to watch (default: until "
                                                      "Ctrl-C or SIGTERM)")
    parser.add_argument("--interval", type=float, default=0.1,
                        help="seconds between samples (default 0.1)")
    parser.add_argument("--top", type=int, default=8, help="intervals listed (default 8)")
    options = parser.parse_args(None if argv is None else list(argv))
    if options.interval <= 0 or (options.seconds is not None and options.seconds <= 0):
        parser.error("--interval and --seconds must be positive")
    if os.geteuid() != 0:
        print("rt_account: not root: other users' threads are not read", file=sys.stderr)
    say_machine("before")
    intervals, names, span = run(options.seconds, options.interval)
    print(report(intervals, names, span, options.top), flush=True)
    say_machine("after")
    return 0


if __name__ == "__main__":
    sys.exit(main())
