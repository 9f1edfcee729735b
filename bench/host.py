"""The machine a benchmark ran on, printed before and after its figures.

Figures from a loaded 2-core box and an idle workstation are not comparable;
every script in ``bench/`` says which it was, so a reader can tell.
"""

from __future__ import annotations

import os
import platform


def _cpu_model() -> str:
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as info:
            for line in info:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass     # no /proc (not Linux): the platform's own name below
    return platform.processor() or "unknown CPU"


def describe() -> str:
    """``N cores (model), load 1/5/15 min, Python, kernel``."""
    load = os.getloadavg()
    usable = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    return (f"{usable} cores ({_cpu_model()}), load {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}, "
            f"Python {platform.python_version()}, Linux {platform.release()}")


def say_machine(when: str = "") -> None:
    print(f"machine{' ' + when if when else ''}: {describe()}", flush=True)


def cpu_seconds(pid: int) -> float:
    """CPU time (user + system, s) of ``pid`` and its descendants, from /proc: a process
    measured from outside, through whatever wrapper (a network namespace, a shell) runs it."""
    from system.processes import descendants

    total = 0
    for each in [pid, *descendants(pid)]:
        try:
            with open(f"/proc/{each}/stat") as stat:
                fields = stat.read().rsplit(")", 1)[1].split()
            total += int(fields[11]) + int(fields[12])
        except (OSError, IndexError, ValueError):
            continue
    return total / os.sysconf("SC_CLK_TCK")
