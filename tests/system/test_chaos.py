"""``walkman-chaos`` (system/chaos.py): its command line, and short runs of the tool itself.

The short runs are three rounds of kills on loopback (and, as root, over the
emulated ``drc`` link with a link cut) while the pilot sends every second
command short-lived (valid 1.5 s) and takes every third back at once: no command
may be lost, repeated, reordered, run after its deadline or run once cancelled,
and nothing may be left behind.  The faults are chosen so that some commands do
expire and some are cancelled: a zero that nothing put to the test proves nothing.
The figures, the records and the leak finder have their own tests
(``test_chaos_figures``, ``test_chaos_record``, ``test_chaos_report``,
``test_chaos_proc``).
"""

from __future__ import annotations

import os
import random
from pathlib import Path

import pytest

from system import chaos
from system import chaos_figures as figures
from system.chaos_run import victims
from system.topology import components


def test_command_line_refuses_unknown_victims_programs_and_plans():
    with pytest.raises(SystemExit):
        chaos.parse_args(["--victims", "robot:nonsense"])
    with pytest.raises(SystemExit):
        chaos.parse_args(["--skip", "counter"])   # the witness cannot be skipped
    for wrong in (["--short-validity", "0"], ["--short-every", "-1"], ["--cancel-every", "-2"]):
        with pytest.raises(SystemExit):
            chaos.parse_args(wrong)
    options = chaos.parse_args(["--rounds", "3", "--victims", "pilot:gateway,link"])
    assert options.victims == ["pilot:gateway", "link"] and options.rounds == 3
    assert (options.short_every, options.short_validity, options.cancel_every) == (5, 3.0, 7)
    assert "pilot:gateway" in victims(components("drc"), link=False)


# -- the tool ---------------------------------------------------------------------------------

#: Not on the command path: left out of the short run to spare two shared cores.
QUIET = "rosbag,perception,joint_state,joint_state_pilot"
ON_THE_PATH = "robot:bridge_robot,pilot:bridge_pilot,pilot:gateway,robot:counter,pilot:roscore"
#: Every second command short-lived, every third cancelled: any outage of a few seconds on the
#: command path holds short-lived ones past 1.5 s, and a pilot bridge without its peer holds
#: commands a cancel can still take back.
PLAN = ["--short-every", "2", "--short-validity", "1.5", "--cancel-every", "3"]


def short_run(tmp_path: Path, extra: list) -> dict:
    from nodekit.msgs import generate

    generate()
    lines: list = []

    def progress(text: str) -> None:
        lines.append(text)
        print(f"[chaos] {text}", flush=True)

    options = chaos.parse_args(["--rounds", "3", "--skip", QUIET, "--out",
                                str(tmp_path / "report"), *PLAN, *extra])
    summary = chaos.run(options, progress)
    report = (tmp_path / "report" / "report.md").read_text()
    assert summary["goals"]["run_completed"], report
    assert len([line for line in lines if line.startswith("round ")]) == 3, lines
    return summary


def assert_clean(summary: dict) -> None:
    f = summary["figures"]
    assert f["executed"] >= 10, f                 # the pilot did command through the faults
    assert (f["lost"], f["duplicated"], f["out_of_order"]) == (0, 0, 0), summary["where"]
    assert (f["late"], f["cancelled_ran"]) == (0, 0), summary["where"]
    assert f["deadline_checked"] >= 3, f          # short-lived commands did run, in time
    assert (f["leaked_processes"], f["leaked_ports"], f["leaked_namespaces"]) == (0, 0, 0), \
        summary["leaks"]
    assert f["unrecovered_rounds"] == 0, summary["rounds"]
    assert all(r["seen_s"] is not None for r in summary["rounds"])


def test_three_rounds_of_kills_on_loopback(tmp_path):
    # seed 24: the counter module (its commands wait for it: some expire), the pilot's bridge,
    # the robot's bridge for 3 s (the pilot bridge holds what is sent: some are cancelled)
    summary = short_run(tmp_path, ["--loopback", "--seed", "24", "--victims", ON_THE_PATH])
    assert [r["fault"]["victim"] for r in summary["rounds"]] == \
        ["robot:counter", "pilot:bridge_pilot", "robot:bridge_robot"]
    assert_clean(summary)
    f = summary["figures"]
    assert f["expired"] >= 1 and f["cancelled"] >= 1, f


@pytest.mark.requires("root")
def test_three_rounds_with_a_link_cut_on_emulated_hosts(tmp_path):
    # seed 5: the pilot's roscore, an 11 s link flap, the counter module
    prefix = f"wct{os.getpid() % 100000}"
    summary = short_run(tmp_path, ["--seed", "5", "--victims", ON_THE_PATH + ",link",
                                   "--netns-prefix", prefix,
                                   "--subnet", str(random.randint(20, 250))])
    assert summary["emulated"]
    assert [r["fault"]["victim"] for r in summary["rounds"]] == \
        ["pilot:roscore", figures.LINK, "robot:counter"]
    assert_clean(summary)
    f = summary["figures"]
    assert f["expired"] >= 1 and f["cancelled"] >= 1, f      # held through the 11 s flap
