"""tests/schedule.py: the suite's tests start longest first, free-standing robots spread."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from hypothesis import given, strategies as st

import schedule
from schedule import (durations_from_junit, estimates, junit_case_id, load_durations,
                      longest_first)

REPORT = """<?xml version="1.0" encoding="utf-8"?>
<testsuites><testsuite name="pytest">
<testcase classname="tests.unit.test_schedule" name="test_a[x]" time="{a}"/>
<testcase classname="tests.unit.test_schedule" name="test_b" time="2.0"><skipped/></testcase>
<testcase classname="tests.unit.test_schedule" name="test_c@packaging" time="{a}"/>
</testsuite></testsuites>
"""


def test_a_junit_case_is_named_as_pytest_names_it():
    assert junit_case_id("tests.unit.test_schedule", "test_a[x]") == \
        "tests/unit/test_schedule.py::test_a[x]"
    assert junit_case_id("tests.unit.test_schedule.TestSome", "test_c") == \
        "tests/unit/test_schedule.py::TestSome::test_c"


def test_durations_are_the_median_of_the_runs_that_ran_a_test(tmp_path):
    reports = []
    for index, seconds in enumerate((1.0, 9.0, 3.0)):
        reports.append(tmp_path / f"run{index}.xml")
        reports[-1].write_text(REPORT.format(a=seconds))
    assert durations_from_junit(reports) == {"tests/unit/test_schedule.py::test_a[x]": 3.0,
                                             "tests/unit/test_schedule.py::test_c": 3.0}


def test_a_missing_or_broken_durations_file_means_file_order(tmp_path):
    assert load_durations(tmp_path / "none.json") == {}
    (tmp_path / "bad.json").write_text("{not json")
    assert load_durations(tmp_path / "bad.json") == {}
    (tmp_path / "good.json").write_text(json.dumps({"tests/a.py::t": 2, "tests/a.py::u": "x"}))
    assert load_durations(tmp_path / "good.json") == {"tests/a.py::t": 2.0}


def test_an_unknown_test_is_given_its_folders_median():
    known = {"tests/system/a.py::t1": 10.0, "tests/system/b.py::t2": 30.0,
             "tests/system/c.py::t3": 50.0, "tests/unit/a.py::u": 0.1}
    guessed = estimates(["tests/system/new.py::t", "tests/unit/new.py::u", "tests/new/x.py::t"],
                        known)
    assert guessed == {"tests/system/new.py::t": 30.0, "tests/unit/new.py::u": 0.1,
                       "tests/new/x.py::t": schedule.UNKNOWN_S}


def test_the_longest_start_first_and_ties_keep_their_order():
    known = {"t/a.py::1": 1.0, "t/a.py::2": 5.0, "t/a.py::3": 5.0, "t/a.py::4": 9.0}
    assert longest_first(list(known), known) == ["t/a.py::4", "t/a.py::2", "t/a.py::3",
                                                 "t/a.py::1"]


def test_tests_that_take_turns_are_spread_not_queued_at_the_start():
    known = {"t/a.py::robot1": 60.0, "t/a.py::robot2": 50.0, "t/a.py::other1": 40.0,
             "t/a.py::other2": 40.0, "t/a.py::other3": 40.0, "t/a.py::other4": 40.0,
             "t/a.py::short": 1.0}
    order = longest_first(list(known), known, apart={"t/a.py::robot1", "t/a.py::robot2"},
                          workers=2)
    assert order[0] == "t/a.py::robot1" and order.index("t/a.py::robot2") > 2
    assert sorted(order) == sorted(known)


@given(st.dictionaries(st.sampled_from([f"t/a.py::{i}" for i in range(30)]),
                       st.floats(0.01, 100.0), min_size=1),
       st.integers(1, 4), st.data())
def test_every_test_runs_once_and_those_apart_never_overlap_in_the_model(known, workers,
                                                                         data):
    tests = list(known)
    apart = set(data.draw(st.lists(st.sampled_from(tests), unique=True)))
    order = longest_first(tests, known, apart, workers)
    assert sorted(order) == sorted(tests)
    clock, free_at = 0.0, 0.0
    for test in order:                     # the schedule's own model of time
        if test in apart:
            assert clock >= free_at - 1e-9 or all(t in apart for t in order[order.index(test):])
            free_at = max(clock, free_at) + known[test]
        clock += known[test] / workers


def test_the_script_rewrites_the_file_and_refuses_reports_without_tests(tmp_path, capsys):
    report = tmp_path / "run.xml"
    report.write_text(REPORT.format(a=4.0))
    out = tmp_path / "durations.json"
    assert schedule.main([str(report), "--out", str(out)]) == 0
    assert json.loads(out.read_text()) == {"tests/unit/test_schedule.py::test_a[x]": 4.0,
                                           "tests/unit/test_schedule.py::test_c": 4.0}
    empty = tmp_path / "empty.xml"
    empty.write_text("<testsuites/>")
    with pytest.raises(SystemExit):
        schedule.main([str(empty), "--out", str(out)])
    assert "hold no test that ran" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        schedule.main([str(tmp_path / "missing.xml"), "--out", str(out)])
    assert "cannot read a report" in capsys.readouterr().err


def test_the_recorded_durations_name_tests_that_exist():
    recorded = load_durations()
    assert len(recorded) > 1000
    root = Path(schedule.__file__).resolve().parents[1]
    missing = sorted({test.split("::")[0] for test in recorded
                      if not (root / test.split("::")[0]).is_file()})
    assert not missing, f"tests/durations.json names files that are gone: {missing}"
