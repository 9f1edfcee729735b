"""tests/suite_time.py: a round's minutes per share of the machine and the least wall time."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.flake_hunt import Outcome, Round, Run
from tests.suite_time import bound, minutes_by_share, shares_by_test


def test_the_plugin_s_lines_give_each_test_its_share_and_nothing_else_counts():
    lines = ["SUITE-TIME-SHARE alone tests/system/test_pilot_gui.py::test_a[x y]",
             "SUITE-TIME-SHARE none tests/unit/test_bottle.py::test_b",
             "SUITE-TIME-SHARE most tests/unit/test_bottle.py::test_c",     # no such share
             "tests/unit/test_bottle.py::test_d", "1772 tests collected in 29.26s"]
    assert shares_by_test(lines) == {"tests/system/test_pilot_gui.py::test_a[x y]": "alone",
                                     "tests/unit/test_bottle.py::test_b": "none"}


def test_a_round_s_minutes_add_up_per_share():
    runs = [Run("a", 1, Outcome.PASSED, 120.0, ""), Run("b", 1, Outcome.FAILED, 60.0, "x"),
            Run("c", 1, Outcome.PASSED, 30.0, ""), Run("gone", 1, Outcome.PASSED, 6.0, "")]
    round_ = Round(Path("fc1.xml"), "burners=2", "", 200.0, runs)
    minutes = minutes_by_share(round_, {"a": "alone", "b": "shared", "c": "shared"})
    assert minutes == {"alone": 2.0, "shared": 1.5, "none": 0.0, "unknown": 0.1}


@pytest.mark.parametrize("minutes, workers, least", [
    ({"alone": 12.0, "shared": 20.0, "none": 10.0}, 2, 22.0),   # alone, then shared in pairs
    ({"alone": 0.0, "shared": 2.0, "none": 40.0}, 2, 21.0),     # all of it over two workers
    ({"alone": 5.0, "shared": 4.0, "none": 1.0}, 1, 10.0),
])
def test_the_least_wall_time_is_the_tests_alone_plus_the_shared_ones_spread(minutes, workers,
                                                                             least):
    assert bound(minutes, workers) == pytest.approx(least)
