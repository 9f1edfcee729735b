#!/usr/bin/env python3
"""Where the suite's time goes, by the share of the machine each test holds.

    .venv/bin/python tests/suite_time.py [--workers 2] REPORT...

Issue 31 asks for the README's test command in at most 10 minutes on 2 cores.  What bounds
it is not pytest's overhead but the machine-sharing rules of ``tests/robot_slots.py``: a
test that holds the machine ``alone`` runs beside no other real-time test, a ``shared`` one
beside other shared ones, and one that holds ``none`` beside anything.  However well the
workers are packed, a run takes at least the time of the tests alone plus the shared tests'
time spread over the workers (the tests that hold nothing fill the gaps), and at least all
of it spread over the workers.  This reads the JUnit reports of suite rounds
(``tests/fresh_clone_run.sh`` writes them; ``docs/fresh-clones/*.xml.gz`` keeps them), asks
pytest for each test's share as the suite's conftest computes it, and prints per report the
minutes per share, that bound and the round's own time.  Reads only: it runs no test.
"""

from __future__ import annotations

import argparse
import gzip
import subprocess
import sys
from pathlib import Path
from typing import Dict, Iterable, List, Optional, Sequence

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from tests.flake_hunt import Round, junit_round  # noqa: E402

SHARES = ("alone", "shared", "none")
_MARKER = "SUITE-TIME-SHARE"


def shares_by_test(lines: Iterable[str]) -> Dict[str, str]:
    """The ``SUITE-TIME-SHARE share nodeid`` lines this module's plugin prints."""
    found = {}
    for line in lines:
        words = line.split(" ", 2)
        if len(words) == 3 and words[0] == _MARKER and words[1] in SHARES:
            found[words[2]] = words[1]
    return found


def minutes_by_share(round_: Round, shares: Dict[str, str]) -> Dict[str, float]:
    """Minutes of a round's tests per share (``unknown``: a test pytest no longer
    collects)."""
    minutes = {share: 0.0 for share in SHARES}
    for run in round_.runs:
        share = shares.get(run.test, "unknown")
        minutes[share] = minutes.get(share, 0.0) + run.seconds / 60
    return minutes


def bound(minutes: Dict[str, float], workers: int) -> float:
    """The least wall time (min) any packing of these tests on ``workers`` can take."""
    total = sum(minutes.values())
    return max(total / workers, minutes["alone"] + minutes["shared"] / workers)


def line(round_: Round, minutes: Dict[str, float], workers: int) -> str:
    parts = "  ".join(f"{share} {value:5.1f}" for share, value in minutes.items())
    return (f"{round_.path.name:<16} {round_.conditions:<10} tests' minutes: {parts}  "
            f"-> at least {bound(minutes, workers):5.1f} min on {workers} workers; "
            f"the round took {round_.seconds / 60:5.1f}")


def collect_shares() -> Dict[str, str]:
    """Every test's share, from pytest's own collection with the suite's conftest."""
    result = subprocess.run([sys.executable, "-m", "pytest", "--collect-only", "-q",
                             "-p", "tests.suite_time", "--suite-time-shares", "tests"],
                            cwd=REPO, text=True, capture_output=True)
    shares = shares_by_test(result.stdout.splitlines())
    if result.returncode != 0 or not shares:
        raise SystemExit(f"suite_time: pytest did not collect the suite:\n"
                         f"{(result.stdout + result.stderr)[-2000:]}")
    return shares


def read_round(path: Path) -> Round:
    opener = gzip.open if path.suffix == ".gz" else open
    with opener(path, "rt", encoding="utf-8") as file:
        return junit_round(path, file.read(), lambda name: (REPO / name).is_file())


def main(argv: Optional[Sequence[str]] = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("reports", nargs="+", type=Path, metavar="REPORT",
                        help="JUnit reports of suite rounds (.xml or .xml.gz)")
    parser.add_argument("--workers", type=int, default=2, help="pytest workers (2)")
    options = parser.parse_args(argv)
    if options.workers < 1:
        parser.error("--workers must be at least 1")
    rounds: List[Round] = []
    for path in options.reports:
        try:
            rounds.append(read_round(path))
        except (OSError, ValueError, EOFError) as exc:
            print(f"suite_time: {path}: {exc}", file=sys.stderr)
            return 2
    shares = collect_shares()
    for round_ in rounds:
        print(line(round_, minutes_by_share(round_, shares), options.workers))
    return 0


# -- the pytest plugin (-p tests.suite_time --suite-time-shares) ----------------------------

def pytest_addoption(parser) -> None:  # type: ignore[no-untyped-def]
    parser.addoption("--suite-time-shares", action="store_true",
                     help="print each collected test's share of the machine (suite_time.py)")


def pytest_collection_modifyitems(config, items) -> None:  # type: ignore[no-untyped-def]
    if config.getoption("--suite-time-shares"):
        from tests.conftest import share_of_item

        for item in items:
            print(f"{_MARKER} {share_of_item(item).value} {item.nodeid}")


if __name__ == "__main__":
    sys.exit(main())
