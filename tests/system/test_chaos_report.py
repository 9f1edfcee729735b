"""The chaos run's summary, verdicts and renderings (system/chaos_report.py), from hand-made
records: a clean one passes every command goal, and each wrong kind of command is a MISSED
goal and a row of the report."""

from __future__ import annotations

from system import chaos
from system.chaos_figures import CANCELLED, EXPIRED, INTERRUPTED, Fault
from system.chaos_record import Record, RoundResult
from system.chaos_report import markdown, summarize, table
from walkman.modules.witness import Execution

NO_LEAKS = {"processes": [], "ports": [], "namespaces": []}


def record_of(executions, accepted) -> Record:
    record = Record(statuses={"counter": [{"t": 0.0, "module": "counter", "seq": 1,
                                           "state": "counting"}]})
    for a in accepted:
        record.take_pilot_event({"ev": "sent", **a})
    for e in executions:
        record.take_execution(e)
    result = RoundResult(Fault(1, "robot:counter", 0.0, 1.0, "kill -9"), killed_at=99.0,
                         back_at=100.0, seen_s=1.0, usable_s=2.0, finished=True)
    record.rounds.append(result)
    return record


def summary_of(record, sent, ended, tmp_path) -> dict:
    options = chaos.parse_args(["--rounds", "1", "--out", str(tmp_path)])
    return summarize(record, sent, ended, options, False, NO_LEAKS, 10.0, False, "")


def test_expired_cancelled_and_interrupted_commands_count_apart_and_pass(tmp_path):
    accepted = [{"t": 100.0, "n": 1, "seq": 10, "validity": 0.0, "cancel": False},
                {"t": 101.0, "n": 2, "seq": 20, "validity": 3.0, "cancel": False},
                {"t": 102.0, "n": 3, "seq": 30, "validity": 0.0, "cancel": True},
                {"t": 103.0, "n": 4, "seq": 40, "validity": 3.0, "cancel": False},
                {"t": 103.5, "n": 5, "seq": 50, "validity": 0.0, "cancel": False}]
    record = record_of([Execution("count", 10, 100.1), Execution("count", 40, 104.0, 0.1, 3.0)],
                       accepted)
    summary = summary_of(record, [(1, 10), (2, 20), (3, 30), (4, 40), (5, 50)],
                         {20: EXPIRED, 30: CANCELLED, 50: INTERRUPTED}, tmp_path)
    f = summary["figures"]
    assert (f["expired"], f["cancelled"], f["interrupted_commands"], f["lost"], f["late"],
            f["cancelled_ran"]) == (1, 1, 1, 0, 0, 0)
    assert (f["short_lived"], f["cancel_asked"], f["deadline_checked"]) == (2, 1, 1)
    assert all(summary["goals"].values()), summary["goals"]
    assert "ended expired / cancelled / interrupted (not run)" in table(summary)


def test_a_late_and_a_cancelled_command_that_ran_miss_their_goals(tmp_path):
    accepted = [{"t": 100.0, "n": 5, "seq": 50, "validity": 3.0, "cancel": False},
                {"t": 100.5, "n": 7, "seq": 70, "validity": 0.0, "cancel": True}]
    record = record_of([Execution("count", 50, 110.0, 0.2, 3.0), Execution("count", 70, 101.0)],
                       accepted)
    summary = summary_of(record, [(5, 50), (7, 70)], {70: CANCELLED}, tmp_path)
    assert (summary["figures"]["late"], summary["figures"]["cancelled_ran"]) == (1, 1)
    assert not summary["goals"]["late"] and not summary["goals"]["cancelled_ran"]
    assert [(w["kind"], w["seq"], w["n"], w["rounds"]) for w in summary["where"]] == \
        [("late", 50, 5, [1]), ("cancelled_ran", 70, 7, [1])]
    report = markdown(summary)
    assert "| late | 50 | 5 |" in report and "| cancelled_ran | 70 | 7 |" in report
    assert "MISSED" in table(summary)
