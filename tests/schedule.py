"""The order the suite's tests start in: the longest first.

Theory of operation.  The suite runs on a few workers (pytest-xdist), each taking the
next test as it finishes one (``--dist loadgroup``: a test at a time, or a whole group
whose tests share an expensive fixture).  Started longest first, the minute-long
topologies overlap from the start and the short tests fill the gaps at the end; started
in file order, a 70-s test could begin in the last minute and the others wait for it.
How long each test takes comes from ``tests/durations.json`` (seconds by test id, the
median of earlier runs' JUnit reports, written by this script); a test not in it is
given the median of its folder's.  A stale file only orders less well: nothing is
skipped or weakened by it.

    .venv/bin/python tests/schedule.py run1.xml run2.xml ...   # rewrite tests/durations.json
"""

from __future__ import annotations

import argparse
import json
import re
import statistics
import sys
import xml.etree.ElementTree as ElementTree
from collections import defaultdict
from pathlib import Path
from typing import AbstractSet, Dict, Iterable, List, Sequence

TESTS = Path(__file__).resolve().parent
DURATIONS = TESTS / "durations.json"
#: A test of a folder with no recorded duration at all (s).
UNKNOWN_S = 1.0


def without_group(test_id: str) -> str:
    """pytest-xdist's ``--dist loadgroup`` names a grouped test ``<id>@<group>``."""
    return re.sub(r"@[\w.-]+$", "", test_id)


def folder_of(test_id: str) -> str:
    """``tests/system/test_x.py::test_y`` -> ``tests/system``."""
    return test_id.split("::", 1)[0].rsplit("/", 1)[0]


def junit_case_id(classname: str, name: str, root: Path = TESTS.parent) -> str:
    """A JUnit test case's pytest id: ``tests.system.test_x`` + ``test_y[a]`` ->
    ``tests/system/test_x.py::test_y[a]`` (a class's cases: ``...py::Class::test_y``)."""
    parts = classname.split(".")
    for split in range(len(parts), 0, -1):
        path = "/".join(parts[:split]) + ".py"
        if (root / path).is_file():
            return "::".join([path, *parts[split:], name])
    return "::".join(["/".join(parts) + ".py", name])


def durations_from_junit(reports: Iterable[Path]) -> Dict[str, float]:
    """Each test's median time (s) over the reports that ran it (skipped ones not counted)."""
    seen: Dict[str, List[float]] = defaultdict(list)
    for report in reports:
        for case in ElementTree.parse(report).getroot().iter("testcase"):
            if case.find("skipped") is not None:
                continue
            name = without_group(case.get("name", ""))
            seen[junit_case_id(case.get("classname", ""), name)].append(
                float(case.get("time", 0.0)))
    return {test: round(statistics.median(times), 2) for test, times in sorted(seen.items())}


def load_durations(path: Path = DURATIONS) -> Dict[str, float]:
    """The recorded durations; none when the file is missing or unreadable (file order)."""
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError):
        return {}
    return {str(k): float(v) for k, v in data.items() if isinstance(v, (int, float))}


def estimates(test_ids: Sequence[str], durations: Dict[str, float]) -> Dict[str, float]:
    """How long each test should take: its recorded time, else its folder's median."""
    by_folder: Dict[str, List[float]] = defaultdict(list)
    for test, seconds in durations.items():
        by_folder[folder_of(test)].append(seconds)
    medians = {folder: statistics.median(times) for folder, times in by_folder.items()}
    return {test: durations.get(test, medians.get(folder_of(test), UNKNOWN_S))
            for test in test_ids}


def longest_first(test_ids: Sequence[str], durations: Dict[str, float],
                  apart: AbstractSet[str] = frozenset(), workers: int = 1) -> List[str]:
    """The tests, longest expected first (ties keep their order); those in ``apart``
    (tests that take turns: tests/robot_slots.py) each put off until the one before is
    expected to be over, on ``workers`` workers -- not all at the start, waiting."""
    expected = estimates(test_ids, durations)
    ordered = sorted(test_ids, key=lambda test: -expected[test])
    out: List[str] = []
    put_off: List[str] = []
    clock = 0.0                  # when the next test is expected to start
    free_at = 0.0                # when the last of ``apart`` is expected to be over
    for test in ordered + [None]:
        while put_off and (clock >= free_at or test is None):
            turn = put_off.pop(0)
            out.append(turn)
            free_at = max(clock, free_at) + expected[turn]
            clock += expected[turn] / workers
        if test is None:
            break
        if test in apart and (clock < free_at or put_off):
            put_off.append(test)
            continue
        out.append(test)
        if test in apart:
            free_at = clock + expected[test]
        clock += expected[test] / workers
    return out


def main(argv: Sequence[str] = ()) -> int:
    parser = argparse.ArgumentParser(description="rewrite tests/durations.json from JUnit "
                                                 "reports of whole runs")
    parser.add_argument("reports", nargs="+", type=Path, help="JUnit XML files (--junitxml)")
    parser.add_argument("--out", type=Path, default=DURATIONS)
    options = parser.parse_args(list(argv) or None)
    try:
        durations = durations_from_junit(options.reports)
    except (OSError, ElementTree.ParseError) as exc:
        parser.error(f"cannot read a report: {exc}")
    if not durations:
        parser.error("the reports hold no test that ran")
    options.out.write_text(json.dumps(durations, indent=0, sort_keys=True) + "\n")
    print(f"{len(durations)} tests, {sum(durations.values()):.0f} s in all -> {options.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
