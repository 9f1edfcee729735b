"""tests/flake_hunt.py's pure parts: pytest's outcome, the environment, the table, the choice."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest

import flake_hunt
from flake_hunt import Outcome, Run, ci_environment, parse_outcome, starts_processes, table, tally

FAILED = """\
F                                                                        [100%]
=================================== FAILURES ===================================
___________________ test_the_valve_turns_by_the_commanded_angle ________________
E   AssertionError: 1.614 -> 1.500
=========================== short test summary info ============================
FAILED tests/modules/test_drc_valve.py::test_the_valve - AssertionError: 1.614 -> 1.500
1 failed in 41.20s
"""


@pytest.mark.parametrize("output, returncode, outcome, summary", [
    (".                                    [100%]\n1 passed in 0.52s\n", 0, Outcome.PASSED, ""),
    ("1 passed, 2 warnings in 3.00s\n", 0, Outcome.PASSED, ""),
    (FAILED, 1, Outcome.FAILED,
     "FAILED tests/modules/test_drc_valve.py::test_the_valve - AssertionError: 1.614 -> 1.500"),
    ("E\nERROR tests/x.py::t - OSError: no run of 400 free TCP ports\n1 error in 2.10s\n", 1,
     Outcome.ERROR, "ERROR tests/x.py::t - OSError: no run of 400 free TCP ports"),
    # a failure in the test and one in its tear-down: the test's failure is the one told
    ("FAILED tests/x.py::t - assert 0\nERROR tests/x.py::t - teardown\n"
     "1 failed, 1 error in 9.0s\n", 1, Outcome.FAILED, "FAILED tests/x.py::t - assert 0"),
    ("s\nSKIPPED [1] tests/x.py:3: needs root\n1 skipped in 0.1s\n", 0, Outcome.SKIPPED,
     "SKIPPED [1] tests/x.py:3: needs root"),
    ("no tests ran in 0.01s\n", 5, Outcome.ERROR, "pytest exited 5: no tests ran in 0.01s"),
    (".\nFatal Python error: Segmentation fault\n", -11, Outcome.CRASHED,
     "pytest died of SIGSEGV: Fatal Python error: Segmentation fault"),
    ("free(): invalid next size\n", 134, Outcome.CRASHED,
     "pytest exited 134 without a summary: free(): invalid next size"),
    ("", 1, Outcome.CRASHED, "pytest exited 1 without a summary: (no output)"),
])
def test_the_outcome_and_the_line_that_says_why(output, returncode, outcome, summary):
    assert parse_outcome(output, returncode) == (outcome, summary)


def test_the_environment_is_what_run_tests_exports():
    script = "set -e\nexport A=1\n  export B='two words'\nexport C=\nFOO=1\n# export D=1\n"
    assert ci_environment(script) == {"A": "1", "B": "two words", "C": ""}
    real = ci_environment(flake_hunt.RUN_TESTS.read_text())
    assert real.pop("WALKMAN_HYPOTHESIS_PROFILE") == "ci"      # derandomised, as CI is
    assert real and all(name.startswith("WALKMAN_REQUIRE_") for name in real)


def runs_of(test: str, *outcomes: Outcome) -> list:
    return [Run(test, n, outcome, float(n), f"FAILED {test} - boom" if outcome.failing else "",
                Path(f"{n}.log") if outcome.failing else None)
            for n, outcome in enumerate(outcomes, 1)]


def test_the_table_counts_each_test_and_lists_each_distinct_failure_once():
    runs = (runs_of("tests/a.py::t", Outcome.PASSED, Outcome.FAILED, Outcome.FAILED)
            + runs_of("tests/b.py::u", Outcome.PASSED, Outcome.SKIPPED))
    a, b, never = tally(runs, ["tests/a.py::t", "tests/b.py::u", "tests/c.py::v"])
    assert (a.runs, a.failures, a.skipped) == (3, 2, 0)
    assert a.distinct == {"FAILED tests/a.py::t - boom": 2}
    assert a.logs == [Path("2.log"), Path("3.log")]
    assert (b.runs, b.failures, b.skipped) == (2, 0, 1) and never.runs == 0
    lines = table([a, b, never]).splitlines()
    assert lines[0].split() == ["runs", "failures", "skipped", "median", "s", "max", "s", "test"]
    assert lines[1].split() == ["3", "2", "0", "2.0", "3.0", "tests/a.py::t"]
    assert lines[2].split() == ["2x", "FAILED", "tests/a.py::t", "-", "boom"]
    assert lines[3].split() == ["2", "0", "1", "1.5", "2.0", "tests/b.py::u"]
    assert lines[4].split() == ["0", "0", "0", "nan", "nan", "tests/c.py::v"]


def _helper_that_spawns() -> None:
    subprocess.run(["true"])


def _pure() -> int:
    return 1


class _Spawner:
    def start(self) -> None:
        _helper_that_spawns()


def test_a_test_is_process_level_when_what_it_names_starts_a_process():
    def uses_helper():
        _helper_that_spawns()

    def uses_class():
        return _Spawner

    def pure():
        return _pure()

    def imports_inside():
        import subprocess as sp  # noqa: F401
    assert starts_processes(uses_helper) and starts_processes(uses_class)
    assert starts_processes(imports_inside) and not starts_processes(pure)


def test_misuse_is_told_and_exits_2(capsys):
    for argv in ([], ["--runs", "0", "tests/x.py"], ["--burners", "-1", "tests/x.py"]):
        with pytest.raises(SystemExit) as stopped:
            flake_hunt.parse_args(argv)
        assert stopped.value.code == 2
    assert "--known" in capsys.readouterr().err


def test_a_junit_testcase_is_named_by_its_node_id():
    files = {"tests/a/test_b.py"}.__contains__
    assert flake_hunt.test_id("tests.a.test_b", "t[x.y-1]", files) == "tests/a/test_b.py::t[x.y-1]"
    assert flake_hunt.test_id("tests.a.test_b.TestC", "t", files) == "tests/a/test_b.py::TestC::t"
    assert flake_hunt.test_id("tests.gone", "t", files) == "tests/gone.py::t"


ROUND_TESTS = """\
import pytest

@pytest.fixture
def breaks_on_the_way_out():
    yield
    raise RuntimeError("tear-down broke")

def test_passes(): pass
def test_fails(): assert 1 == 2, "one is not two"
def test_skips(): pytest.skip("needs root")
def test_passes_then_its_tear_down_fails(breaks_on_the_way_out): pass
@pytest.mark.parametrize("x", ["a.b", "c"])
def test_each(x): assert x != "c"
"""


def test_a_round_is_what_pytest_s_own_junit_report_records(tmp_path):
    (tmp_path / "tests").mkdir()
    (tmp_path / "tests" / "test_round.py").write_text(ROUND_TESTS)
    report = tmp_path / "round.xml"
    subprocess.run([flake_hunt.sys.executable, "-m", "pytest", "-q", "-p", "no:randomly",
                    "-p", "no:cacheprovider", "-o", "junit_suite_name=burners=2",
                    f"--junitxml={report}", "tests"], cwd=tmp_path, capture_output=True)
    found = flake_hunt.junit_round(report, report.read_text(),
                                   lambda name: (tmp_path / name).is_file())
    assert found.conditions == "burners=2" and found.seconds > 0
    outcomes = {run.test.split("::")[1]: run.outcome for run in found.runs}
    assert outcomes == {"test_passes": Outcome.PASSED, "test_fails": Outcome.FAILED,
                        "test_skips": Outcome.SKIPPED,
                        "test_passes_then_its_tear_down_fails": Outcome.ERROR,
                        "test_each[a.b]": Outcome.PASSED, "test_each[c]": Outcome.FAILED}
    why = {run.test.split("::")[1]: run.summary for run in found.runs}
    assert "one is not two" in why["test_fails"] and "tear-down broke" in why[
        "test_passes_then_its_tear_down_fails"]
    assert all(run.test.startswith("tests/test_round.py::") for run in found.runs)


def test_a_file_that_is_not_a_junit_report_is_refused_by_name(tmp_path):
    for text, says in (("not xml", "not XML"), ("<html/>", "not a JUnit report")):
        with pytest.raises(ValueError, match=says) as refused:
            flake_hunt.junit_round(tmp_path / "r.xml", text, lambda name: False)
        assert "r.xml" in str(refused.value)


def test_rounds_add_up_per_test_and_the_counts_say_who_ran_less(tmp_path):
    def report(*cases: str) -> str:
        return ('<testsuites><testsuite name="burners=0" time="60">' + "".join(cases)
                + "</testsuite></testsuites>")
    ok = '<testcase classname="tests.test_x" name="{}" time="1"/>'
    bad = '<testcase classname="tests.test_x" name="{}" time="1"><failure message="m"/></testcase>'
    rounds = [flake_hunt.junit_round(tmp_path / f"{n}.xml", text, lambda name: True)
              for n, text in enumerate([report(ok.format("t1"), ok.format("t2")),
                                        report(ok.format("t1"), bad.format("t2")),
                                        report(ok.format("t1"))])]
    tallies = tally([run for one in rounds for run in one.runs])
    assert [(entry.test, entry.runs, entry.failures) for entry in tallies] == [
        ("tests/test_x.py::t1", 3, 0), ("tests/test_x.py::t2", 2, 1)]
    assert flake_hunt.counts_line(tallies) == "2 tests, 1 failing runs; runs each: 2 x 1, 3 x 1"
    assert "1.0" in flake_hunt.rounds_table(rounds).splitlines()[1]
