#!/usr/bin/env python3
"""Run chosen tests many times under CPU burners and count each one's failures.

Why: fresh-clone runs of the suite failed about one in three, each time on a test that then
passed when run again (issue 31).  A test that fails once in twenty runs is invisible in one
run and costs everyone a re-run; this makes its rate a number.  Zero is the budget.

Each run is a fresh ``pytest`` process for one test (``-p no:randomly -q``, with the
environment ``launch_scripts/run_tests.sh`` exports, so a missing requirement fails rather
than skips), one after the other, while ``--burners`` busy-loop processes take CPU as a loaded
CI box does.  Tests take turns (run 1 of every test, then run 2 ...), so a load that changes
during the hunt is shared among them.  Ctrl-C or SIGTERM stops the run under way (pytest is
interrupted and tears down) and prints the figures so far; the burners are always killed.

    .venv/bin/python tests/flake_hunt.py --runs 20 --burners 2 TESTID...
    .venv/bin/python tests/flake_hunt.py --known            # every test a fresh clone failed
    .venv/bin/python tests/flake_hunt.py --process-level --list
    .venv/bin/python tests/flake_hunt.py --junit out/fresh-clones/*.xml   # rounds of the suite

A round of the whole suite runs every test once, the way CI does (both workers, the machine's
shares): ``--junit`` counts each test's runs and failures over the JUnit reports of such
rounds instead of running anything, which is how every process-level test reaches 20 runs in
hours, not days.  ``tests/fresh_clone_run.sh`` writes one report per fresh clone, its suite
name saying what ran beside it (``burners=2``); ``docs/fresh-clones/`` keeps them, gzipped.

Exit status: 0 every run passed, 1 a run failed (or was stopped), 2 misuse.
The report goes to ``out/flake-hunt-<time>/report.md`` with the output of every failing run.
It can also be loaded as a pytest plugin (``-p tests.flake_hunt``), which is how
``--process-level`` selects tests: see :func:`starts_processes`.
"""

from __future__ import annotations

import argparse
import enum
import gzip
import inspect
import os
import re
import shlex
import signal
import statistics
import subprocess
import sys
import time
import types
import xml.etree.ElementTree as ElementTree
from collections import Counter
from contextlib import contextmanager, suppress
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Dict, Iterator, List, NamedTuple, Optional, Sequence, Tuple

REPO = Path(__file__).resolve().parents[1]
PYTHON = str(REPO / ".venv" / "bin" / "python") if (REPO / ".venv").is_dir() else sys.executable
PYTEST = ["-m", "pytest", "-p", "no:randomly", "-p", "no:cacheprovider", "-q",
          "--rootdir", str(REPO)]  # test ids are relative to it, and runs start in it
RUN_TESTS = REPO / "launch_scripts" / "run_tests.sh"


class Known(NamedTuple):
    test: str
    failure: str


#: Every test that failed in a fresh-clone run of the README's test command or in the
#: project's CI, from the closing notes (``issues stops``) and the commits that fixed them.
KNOWN: Tuple[Known, ...] = (
    Known("tests/system/test_view3d_restart.py::"
          "test_a_killed_3d_view_comes_back_and_the_pi_lives_on",
          "the valve's x did not follow the dragged marker (fc9 of the fourth 2026-11-27 "
          "session): the render process connected twice at once to the PI's feedback "
          "publisher, rospy dropped the duplicate while the other's handshake read it (EBADF "
          "in nodekit.ros_node's bounded_read) and kept neither; open; the ghost not on "
          "the screen 30 s after the render process had switched the preview on (fc27 of "
          "the second 2026-11-28 session, beside two burners): the 'without' share came from "
          "one grab, which can catch a frame half drawn; a share is now taken once three "
          "grabs agree (the ghost is drawn 0.05-0.16 s after the ask beside four burners, "
          "9 runs); the cause is likely, not proven"),
    Known("tests/modules/test_drc_valve.py::test_the_valve_turns_by_the_commanded_angle",
          "valve slipped back after release (ci46, project CI; 15e599d, 7ba9f83)"),
    Known("tests/system/test_pilot_gui.py::"
          "test_two_pilot_pcs_see_each_others_commands_and_a_pi_survives_restarts",
          "stations race (a83e26d); a PI's log missed the other pilot's command (ci48, bac1334)"),
    Known("tests/system/test_pilot_gui.py::"
          "test_the_valve_task_by_clicks_with_a_pi_crash_and_a_cancelled_timed_turn",
          "the PI aborted at start, librviz heap corruption (ci45; 01ba698, d852343)"),
    Known("tests/bridge/test_emulated_network.py::test_profiles_shape_the_link",
          "ARP under 20 % loss: 0 of 2000 datagrams arrived (ci30; a8f3a95)"),
    Known("tests/bridge/test_emulated_network.py::test_gym_module_and_perception_over_a_drc_link",
          "perception over drc: mean cloud completeness 0.749995 < 0.75 (ba5ef03)"),
    Known("tests/bridge/test_emulated_network.py::test_a_30_second_cut_and_kills_lose_no_command",
          "commands lost after a bridge restart (4e697ad; d2ff6ca)"),
    Known("tests/unit/test_freeport.py::test_runs_are_found_while_single_ports_are_scattered",
          "no run of 400 free ports late in a run: 4 errors (ba5ef03, c90e059); the regression "
          "test, since the original failure needs a whole suite before it"),
    Known("tests/unit/test_stream.py::test_a_thread_told_not_to_spin_sleeps_in_recv_at_once",
          "no-spin: the first read outlasted the spin window under load (ci46; dc98d72)"),
    Known("tests/bridge/test_tcp_channel.py::test_a_recorded_connection_replayed_is_refused",
          "the recording relay's 3 s deadline ended first under load (ba5ef03)"),
    Known("tests/bridge/test_tcp_channel.py::test_a_keyless_peer_is_named_as_such",
          "the side that noticed first closed before the other could say why (d2ff6ca)"),
    Known("tests/interop/test_interop.py::"
          "test_persistent_connection_made_when_ports_appear_and_after_restart",
          "all-real-YARP persistence: stale connection 'already present' (ci15; 77e6ab9, a474bd1)"),
    Known("tests/system/test_chaos.py::test_three_rounds_with_a_link_cut_on_emulated_hosts",
          "8 commands expired: the gateway stamped 10 s validity (23c97c0); one command lost "
          "(fc17 of 2026-11-28, beside the PI start loop): the witness module receipted "
          "'accepted' for count 34 and was killed -9 by round 3 before its control thread ran "
          "it -- 'accepted' is terminal and no one says the command died with the process; "
          "the module's next process now says 'interrupted' of what it held (f2d5331)"),
    Known("tests/system/test_pc_launcher.py::"
          "test_launchers_bring_up_both_pcs_and_a_plain_shell_pilots_the_robot",
          "the first command beat the connection keeper (44637d4)"),
    Known("tests/system/test_hostile_peers.py::"
          "test_every_program_keeps_serving_under_hostile_peers",
          "a flood locked a real rosservice call out (01ba698); the robot name server under a "
          "1000-connection flood did not answer `yarp-lite wait` within 20 s (fc13 of "
          "2026-11-28, beside the PI start loop: load 11 on 2 cores); again beside only two "
          "burners (fc27 of the second 2026-11-28 session): a port took 512 silent connections, "
          "each waiting out its handshake, and a real client queued behind the rest in the "
          "listen backlog; a port now keeps at most 64 connections that have not introduced "
          "themselves, closing the oldest for the newest (yarp_lite.port_inputs.MAX_INTRODUCING); 3 "
          "of 3 beside four burners since"),
    Known("tests/integration/test_text_and_cli.py::test_cli_conf_namespace_where_clean",
          "`yarp-lite clean` got 'connection refused' from the test's name server right after "
          "it had served `name register /ghost`; its log ended there, no error (fc13 of "
          "2026-11-28, beside the PI start loop); 60 runs since passed; a failed test's "
          "dump now says how each program ended (6d09c3c); open"),
    Known("tests/bridge/test_rogue_host.py::test_a_rogue_on_the_radio_gets_nothing_executed",
          "the pilot's 250 commands (25 s) ended before the attacks did (fc15 of 2026-11-28, "
          "beside the PI start loop and a flake hunt: load up to 29); the pilot commands until "
          "told since.  Then the injected frame counted malformed, not forged, beside two "
          "burners (fc98 of 2026-12-02): the rogue injected late, over the pilot's own next "
          "segment; the test takes either refusal since (both drop the connection, execute "
          "nothing)"),
    Known("tests/modules/test_drc_drive.py::test_steer_and_accelerate",
          "the status's measured wheel angle 0.13 rad short of the world's: the status before "
          "the wheel settled (fc14 of 2026-11-28, beside the PI start loop; waits for the "
          "next since: afa4c6b); fc43 of 2026-11-28 (beside two burners): still apart after "
          "10 s, by how much not said (the failure says both angles since); 10 of 10 beside "
          "two burners after it.  Likely cause: measured from the grip pointed at, not from "
          "where the hand took the rim (0.04 rad off offline); measured from the hold since; "
          "fc58 of the fifth 2026-11-28 session (load 52): the throttle pressed 0.78 s of 2 "
          "-- timed by the test's clock from when it saw 'accelerating', late; timed on the "
          "simulator's clock from before the command since (1.85-1.91 s quiet)"),
    Known("tests/system/test_pilot_gui.py::"
          "test_an_arm_task_by_clicks_standing_unsupported[wall]",
          "as test_the_wall_task_by_clicks_cuts_the_circle_in_the_world, merged into this "
          "one since (the same clicks standing unsupported, the preview checked there): a "
          "whole cut judged 340 of 360 degrees: the bit sampled, not swept (fc15; 0bc5197)"),
    Known("tests/modules/test_walking.py::test_the_door_sequence_unsupported_as_processes",
          "the walk short, the guard tripped beside another robot (fc15, fc16): threads at normal "
          "priority held the interpreter lock (44348b6); real-time throttling with two "
          "multi-module robots: free-standing robots take turns since d98a2bb"),
    Known("tests/modules/test_walking.py::test_turns_side_steps_and_a_push_standing_as_processes",
          "tilt 0.122 rad after the push beside another robot (fc16; 44348b6)"),
    Known("tests/modules/test_walking.py::"
          "test_a_step_up_sent_too_far_from_the_kerb_is_put_back_as_processes",
          "no heel warning in 30 s: the sole touched after 0.35 s, 'no ground' (fc15; 44348b6)"),
    Known("tests/system/test_pilot_gui.py::"
          "test_the_terrain_course_by_clicks_with_footsteps_placed_in_the_3d_view",
          "the bridges silent 2-4 s beside two burners, walking paused (fc19; d9a24ba); the "
          "guard tripped standing on the kerb after step_up, ZMP -0.5 cm, the loop on time "
          "(fc4 of the third, fc6 of the fourth 2026-11-27 session, both beside burners: "
          "open, issue 32's step robustness); the step down from 4 cm short of the far edge: "
          "the heel caught it, the foot put back, and walk() blind to that warning (fc21 of "
          "2026-11-28, quiet; from 1 cm, and the driver sees it: f2d5331); again from 1 cm "
          "(fc23): 51-52 N read for a tick by a swinging sole, its way clear by 6 cm -- a "
          "strike is now 150 N for two ticks in a row; with PI_CAMERA_FOOTSTEPS=1 (not "
          "the suite's run) the walk on the kerb's top tripped the balance guard in 2 of 7 "
          "runs beside two burners, ZMP 0.4-0.6 cm from the feet's edge; with perception "
          "paused while walking 1 of 5 beside a loaded machine, standing, after gaze_control's "
          "start stalled the HAL's physics 8.5 ms; 12 of 13 with perception's loop at "
          "normal priority, the thirteenth the same, a 13-ms physics step (2026-12-02); "
          "offline the standing and the look down keep 11 cm: the stalls, open; the PI "
          "exited 0 without a word right after 'CLICK walking start' (fc29 of the second "
          "2026-11-28 session, quiet): it had walked the course and printed DONE, but the "
          "test's reader had died on a byte that is not UTF-8 and never read a later line; "
          "undecodable bytes are shown escaped since; in fc54-fc56 of the fifth 2026-11-28 "
          "session (a machine 2.5 times slower, three workers on two cores, load 66-82) "
          "walking's loop stalled 120 ms and its heartbeat 5 s, and it was killed: one "
          "worker per core since (8cbde49); the guard tripped standing on the kerb after "
          "step_up again, ZMP -0.0 cm, the loop's longest tick 17 ms 2 s before (fc71 of the "
          "eighth 2026-11-28 session, beside two burners; passed beside them right after): "
          "open"),
    Known("tests/walkman/test_gym_hal.py::"
          "test_the_robot_says_when_each_state_round_arrives",
          "no rounds from the chain-by-chain reader within 10 s (fc54 and fc57 of the fifth "
          "2026-11-28 session, a machine 2.5 times slower): a starved reader sees rounds of "
          "two steps or more and says 'not known' until it keeps up; it waits 60 s since"),
    Known("tests/walkman/test_supervisor.py::"
          "test_a_module_that_stops_beating_is_killed_after_the_heartbeat_timeout",
          "killed 1.299 s after the watch began against a lower bound of 1.3 s that assumed "
          "the five beats on time (fc37 of the third 2026-11-28 session, beside two "
          "burners); the bound is now the beating thread's last write + 0.5 s: 20 of 20 "
          "beside two burners"),
    Known("tests/walkman/test_gym_hal.py::"
          "test_a_module_asked_with_sigusr1_prints_every_thread_s_stack",
          "the module process died of SIGSEGV in faulthandler's all-threads dump while its "
          "connector thread imported (2026-11-28, beside nothing); SIGUSR1 is a Python "
          "handler since (nodekit/stacks.py), faulthandler's dump moved to SIGUSR2; 'no "
          "stacks to show' (CI of 2026-12-03): the supervisor waited for a first beat, which "
          "came after 'ready for the pilot'; the runner now says SIGNALS_ARMED once its "
          "handlers are in, before its imports"),
    Known("tests/system/test_tasks_via_gateway.py::test_walking_through_rosservice",
          "the guard tripped at a 0.3-cm ZMP margin, the HAL on time (fc22; the trip now logs "
          "the loop's longest tick: e497490); again at 0.1 cm after a 33-ms tick (2026-11-27 "
          "fc2): free-standing robots take turns (d98a2bb); at -0.2 cm after a 59-ms tick "
          "0.6 s before, walked 0.25 of 0.4 m (fc74 of the eighth 2026-11-28 session, quiet); "
          "its physics had stalled 52 ms too: a second robot's real-time threads beside it "
          "pushed a CPU over the kernel's real-time budget (bench/bench_rt_budget.py), and "
          "free-standing robots have the machine to themselves since"),
    Known("tests/nodekit/test_connections.py::"
          "test_a_round_with_many_missing_asks_the_name_server_once",
          "['list', 'query', 'query'] for ['list', 'query'] (fc74 of the eighth 2026-11-28 "
          "session, quiet): the second was the ports' registration keeper asking about "
          "/keeper/out8 through the same client (the server's log); held off during the "
          "count since"),
    Known("tests/system/test_tasks_via_gateway.py::test_the_drive_task_through_rosservice",
          "'throttle pressed' not seen in 10 s of probes (fc22; watched throughout: 41555e4)"),
    Known("tests/interop/test_controlboard_oracle.py::"
          "test_a_cpp_remote_controlboard_moves_the_simulated_robot[sim-left_arm-3--40.0-udp]",
          "a real remote_controlboard over udp (fc22; the output was not kept, 30 runs since "
          "passed)"),
    Known("tests/integration/test_auth.py::test_other_keys_are_refused_with_a_message_within_seconds",
          "refused after 10-26 s, over its 8-s bound (fc2 of 2026-11-27, with two extra GUI "
          "runs; judged by the refusal's reason since: df94822)"),
    Known("tests/walkman/test_gym_hal.py::test_the_robot_says_when_each_state_round_arrives",
          "0.71 ms for a 1-ms robot, 2.06 for 2 ms: rounds timed by arrival (fc2, fc3 of the "
          "third 2026-11-27 session; by the robot's clock since: 5ad64ff, a4d92dd)"),
    Known("tests/walkman/test_gym_hal.py::test_pilot_moves_the_head_through_yarp_write",
          "gaze_control's log silent after its robot ports, no 'tracking' (fc4) or no exit "
          "after quit (fc6), beside two burners; fc11 before: the write tool failed; again "
          "[yarp-hal-first-sim] (fc6 of the fourth session): the runner's walkman.gym lines "
          "stop while its yarp_lite lines go on, the module still works; not found; again "
          "[yarp_lite-module-first-sim] (fc6 of the fifth, 2 burners, the test 163 s): the "
          "module's lines end mid-test with its status and warning outputs removed, the test's "
          "inputs re-made (no 'Sending output' from the module); the next one keeps every line "
          "(out/failed/) and the module's stacks (SIGUSR1).  Found (d9f9ecf): the 40-line "
          "tail was a *second* module process ('state stopped'): the watchdog beat nothing "
          "while it waited for the quit's hooks (2 s each), the supervisor killed the "
          "quitting module after 5 s of silence and restarted it, stopped, for ever; again "
          "(fc14 of 2026-11-28, beside the PI start loop): the quit's hooks were done, then "
          "closing its ports took over 5 s -- the runner now says QUITTING and the supervisor "
          "gives it 30 s, never a restart (4c2bf2a)"),
    Known("tests/walkman/test_gym_hal.py::"
          "test_stop_and_quit_win_over_a_hanging_or_throwing_module",
          "no exit within 90 s of quit (CI of 2026-12-02, 2 xdist workers): the module's "
          "run() hung, so the quit was 'stuck' and the runner did not say QUITTING; its ports' "
          "closing beat nothing for over 5 s and the supervisor started a fresh module nobody "
          "would quit, and the SIGUSR1 for its stacks went to that one while it still "
          "imported (no handler: it died).  Now every quit says QUITTING, and the supervisor "
          "passes signals only to a module whose handlers are in (SIGNALS_ARMED)"),
    Known("tests/system/test_pilot_gui.py::"
          "test_an_arm_task_by_clicks_standing_unsupported[wall]",
          "as test_the_wall_task_by_clicks_cuts_the_circle_in_the_world, merged into this "
          "one since (the same clicks standing unsupported, the preview checked there): "
          "'approach is disabled' right after 'reach -> reached' (fc2; not found, the driver "
          "now says the widget's state); 'reach is disabled', the PI's drc_wall 'not running "
          "(last: ready)', heard 10.8 s ago, the link not down (fc68 of the seventh "
          "2026-11-28 session, load 20-31 beside the 30 %-loss stop_all test's two PCs: the "
          "pilot bridge dropped 100 stale /battery messages, the robot PC's loops starving "
          "its bridge and the radio stage; open)"),
    Known("tests/bridge/test_udp_channel.py::"
          "test_adaptive_repairs_follow_the_loss_the_receiver_reports",
          "the mean completeness of frames 10-40 at 30 % loss 0.919, not >= 0.98 (fc68 of the "
          "seventh 2026-11-28 session, under load: the loss reports and the repair level "
          "follow the machine's timing; open)"),
    Known("tests/system/test_pilot_gui.py::"
          "test_drive_door_and_plug_by_clicks_in_one_session_as_the_readme_walks_through",
          "the wheel at 12.5 degrees after the task for the slider's 25, the widget showing "
          "25.5 measured (its first flake hunt, 1 of 3 beside two burners); the wheel is now "
          "read at the moment it is steered and again after the task; where it drifted, open; "
          "again in fc76 of the ninth session (2026-11-29, beside two burners): 10 degrees "
          "after the task for 25, the HAL's physics stalled 52-54 ms meanwhile (the kernel's "
          "real-time budget: two-PC tests have the machine to themselves since)"),
    Known("tests/bridge/test_tcp_channel.py::"
          "test_an_unacknowledged_event_is_followed_by_empty_frames_and_a_periodic_one_is_not",
          "its 3-s wait for the nudges beside two burners (fc6; 15 s since: 7c633c2); no "
          "nudge in 15 s (2026-11-27 fc3): an event riding with the periodic frame was not "
          "awaited, a product defect (2559128)"),
)


class Outcome(enum.Enum):
    PASSED = "passed"
    SKIPPED = "skipped"
    FAILED = "failed"
    ERROR = "error"      # an error in set-up or tear-down, or pytest could not run the test
    TIMEOUT = "timeout"  # still running after --timeout seconds
    CRASHED = "crashed"  # pytest died without its summary (a signal, an abort)

    @property
    def failing(self) -> bool:
        return self not in (Outcome.PASSED, Outcome.SKIPPED)


@dataclass(frozen=True)
class Run:
    test: str
    number: int           # 1-based, per test
    outcome: Outcome
    seconds: float        # the pytest process, start to exit
    summary: str          # pytest's short summary line of a failure or skip, "" when it passed
    log: Optional[Path] = None


# -- pure parts: pytest's output, the environment, the tables ------------------------------

_TALLY = re.compile(r"(\d+) (passed|failed|errors?|skipped|xfailed|xpassed|deselected)\b")
_FINAL = re.compile(r"\bin [\d.]+s\b")


def parse_outcome(output: str, returncode: int) -> Tuple[Outcome, str]:
    """One test's outcome and its summary line from ``pytest -q -rfEs`` output."""
    lines = [line.rstrip() for line in output.splitlines() if line.strip()]
    summary = {kind: next((line for line in lines if line.startswith(kind + " ")), "")
               for kind in ("FAILED", "ERROR", "SKIPPED")}
    final = next((line for line in reversed(lines) if _FINAL.search(line)), "")
    counts = Counter({word.rstrip("s") if word.startswith("error") else word: int(n)
                      for n, word in _TALLY.findall(final)})
    last = lines[-1] if lines else "(no output)"
    if returncode < 0:
        return Outcome.CRASHED, f"pytest died of {signal.Signals(-returncode).name}: {last}"
    if counts["failed"] or summary["FAILED"]:
        return Outcome.FAILED, summary["FAILED"] or final
    if counts["error"] or summary["ERROR"]:
        return Outcome.ERROR, summary["ERROR"] or final
    if returncode == 0 and counts["passed"]:
        return Outcome.PASSED, ""
    if returncode == 0 and counts["skipped"]:
        return Outcome.SKIPPED, summary["SKIPPED"] or final
    if not final:
        return Outcome.CRASHED, f"pytest exited {returncode} without a summary: {last}"
    return Outcome.ERROR, f"pytest exited {returncode}: {final}"


def ci_environment(script: str) -> Dict[str, str]:
    """The variables a shell script exports (``export NAME=value`` lines)."""
    found = re.findall(r"^\s*export\s+([A-Za-z_]\w*)=(.*?)\s*$", script, re.MULTILINE)
    return {name: (shlex.split(value) or [""])[0] for name, value in found}


class Round(NamedTuple):
    """One JUnit report of a suite run: where it came from and what it came to."""
    path: Path
    conditions: str       # the report's suite name: what ran beside it, e.g. "burners=2"
    started: str
    seconds: float
    runs: List[Run]


_WORST = [Outcome.PASSED, Outcome.SKIPPED, Outcome.ERROR, Outcome.FAILED]


def test_id(classname: str, name: str, is_file: Callable[[str], bool]) -> str:
    """A JUnit testcase's pytest node id: ``tests.a.test_b`` and ``t[x]`` make
    ``tests/a/test_b.py::t[x]`` (a class inside the file stays after ``::``, found by which
    prefix is a file)."""
    parts = classname.split(".")
    for cut in range(len(parts), 0, -1):
        path = "/".join(parts[:cut]) + ".py"
        if is_file(path):
            return "::".join([path, *parts[cut:], name])
    return "::".join(["/".join(parts) + ".py", name])


def junit_round(path: Path, text: str, is_file: Callable[[str], bool]) -> Round:
    """The runs one JUnit report records, a test's entries merged (a tear-down's error can
    come as an entry of its own) into its worst outcome; ValueError if it is not a report."""
    try:
        root = ElementTree.fromstring(text)
    except ElementTree.ParseError as error:
        raise ValueError(f"{path}: not XML ({error})") from None
    suites = [root] if root.tag == "testsuite" else root.findall("testsuite")
    if root.tag not in ("testsuite", "testsuites") or not suites:
        raise ValueError(f"{path}: not a JUnit report (root <{root.tag}>, no <testsuite>)")
    merged: Dict[str, Run] = {}
    for suite in suites:
        for case in suite.iter("testcase"):
            test = test_id(case.get("classname", ""), case.get("name", ""), is_file)
            outcome, summary = Outcome.PASSED, ""
            for kind, found in (("failure", Outcome.FAILED), ("error", Outcome.ERROR),
                                ("skipped", Outcome.SKIPPED)):
                element = case.find(kind)
                if element is not None and _WORST.index(found) > _WORST.index(outcome):
                    message = (element.get("message") or element.text or kind).strip()
                    outcome, summary = found, message.splitlines()[0][:300] if message else kind
            seconds = float(case.get("time") or 0)
            before = merged.get(test)
            if before is not None:
                seconds += before.seconds
                if _WORST.index(before.outcome) >= _WORST.index(outcome):
                    outcome, summary = before.outcome, before.summary
            merged[test] = Run(test, 1, outcome, seconds, summary, path if outcome.failing
                               else None)
    first = suites[0]
    return Round(path, first.get("name", ""), first.get("timestamp", ""),
                 sum(float(suite.get("time") or 0) for suite in suites), list(merged.values()))


def rounds_table(rounds: Sequence[Round]) -> str:
    rows = [["report", "beside", "started", "minutes", "tests", "failing"]]
    for one in rounds:
        beside = "?" if one.conditions in ("", "pytest") else one.conditions
        rows.append([str(one.path), beside, one.started[:19], f"{one.seconds / 60:.1f}",
                     str(len(one.runs)),
                     str(sum(run.outcome.failing for run in one.runs))])
    widths = [max(len(row[i]) for row in rows) for i in range(len(rows[0]))]
    return "\n".join("  ".join(cell.ljust(w) for cell, w in zip(row, widths)).rstrip()
                     for row in rows)


def counts_line(tallies: Sequence[Tally]) -> str:
    """The failing runs, and how many tests ran how often, fewest runs first:
    ``1754 tests, 0 failing runs; runs each: 2 x 14, 3 x 1740``."""
    often = Counter(entry.runs for entry in tallies)
    return (f"{len(tallies)} tests, {sum(e.failures for e in tallies)} failing runs; runs each: "
            + ", ".join(f"{runs} x {count}" for runs, count in sorted(often.items())))


@dataclass
class Tally:
    test: str
    runs: int = 0
    failures: int = 0
    skipped: int = 0
    seconds: List[float] = field(default_factory=list)
    distinct: Counter = field(default_factory=Counter)  # failure summary line -> runs
    logs: List[Path] = field(default_factory=list)


def tally(runs: Sequence[Run], tests: Sequence[str] = ()) -> List[Tally]:
    """Per test, in the order given (then first seen): what its runs came to."""
    by_test: Dict[str, Tally] = {test: Tally(test) for test in tests}
    for run in runs:
        entry = by_test.setdefault(run.test, Tally(run.test))
        entry.runs += 1
        entry.seconds.append(run.seconds)
        if run.outcome is Outcome.SKIPPED:
            entry.skipped += 1
        elif run.outcome.failing:
            entry.failures += 1
            entry.distinct[run.summary] += 1
            if run.log is not None:
                entry.logs.append(run.log)
    return list(by_test.values())


def _figures(entry: Tally) -> List[str]:
    seconds = entry.seconds or [float("nan")]
    return [str(entry.runs), str(entry.failures), str(entry.skipped),
            f"{statistics.median(seconds):.1f}", f"{max(seconds):.1f}"]


HEADER = ["runs", "failures", "skipped", "median s", "max s", "test"]


def table(tallies: Sequence[Tally], width: int = 200) -> str:
    """A plain-text table, one row per test, each distinct failure under its test's row."""
    rows = [HEADER] + [_figures(entry) + [entry.test] for entry in tallies]
    widths = [max(len(row[i]) for row in rows) for i in range(len(HEADER) - 1)]
    out = []
    for row, entry in zip(rows, [None, *tallies]):
        out.append("  ".join([cell.rjust(w) for cell, w in zip(row, widths)] + [row[-1]]))
        for line, count in (entry.distinct.most_common() if entry else ()):
            out.append(f"{'':>{widths[0]}}  {count}x {line}"[:width])
    return "\n".join(out)


def markdown_table(tallies: Sequence[Tally]) -> str:
    lines = ["| " + " | ".join(HEADER) + " |", "|" + "---:|" * (len(HEADER) - 1) + "---|"]
    for entry in tallies:
        lines.append("| " + " | ".join(_figures(entry) + [f"`{entry.test}`"]) + " |")
    return "\n".join(lines)


# -- processes: burners, one pytest run -----------------------------------------------------

#: A burner spins until its parent is gone, so even a hunt killed with SIGKILL leaves none.
BURNER = "import os, sys\nparent = int(sys.argv[1])\nwhile os.getppid() == parent:\n" \
         "    for _ in range(100000): pass\n"


@contextmanager
def burners(count: int) -> Iterator[List[subprocess.Popen]]:
    procs: List[subprocess.Popen] = []
    try:
        for _ in range(count):
            procs.append(subprocess.Popen([sys.executable, "-c", BURNER, str(os.getpid())],
                                          stdin=subprocess.DEVNULL, start_new_session=True))
        yield procs
    finally:
        for proc in procs:
            proc.kill()
        for proc in procs:
            proc.wait()


class Stopped(Exception):
    """SIGTERM, raised in the main thread as Ctrl-C raises KeyboardInterrupt."""


def _started(pid: int) -> Optional[str]:
    """A process's start time (/proc), so a number reused by a newer process is left alone."""
    try:
        with open(f"/proc/{pid}/stat") as stat:
            return stat.read().rsplit(")", 1)[1].split()[19]
    except (OSError, IndexError):
        return None


def _stop_tree(proc: subprocess.Popen, grace: float) -> str:
    """SIGINT to pytest (its fixtures tear down), SIGKILL to it and all below it after
    ``grace`` seconds; what it printed.  The processes below are noted first: a test's own
    sessions are not in pytest's group, and once pytest is gone they are no longer below it."""
    from system.processes import descendants
    below = {pid: _started(pid) for pid in descendants(proc.pid)}
    with suppress(ProcessLookupError):
        os.killpg(proc.pid, signal.SIGINT)
    try:
        output: Optional[str] = proc.communicate(timeout=grace)[0]
    except subprocess.TimeoutExpired:
        below.update({pid: _started(pid) for pid in descendants(proc.pid)})
        proc.kill()
        output = None
    for pid, started in below.items():
        if started is not None and _started(pid) == started:
            with suppress(ProcessLookupError):
                os.kill(pid, signal.SIGKILL)
    if output is None:
        try:
            output = proc.communicate(timeout=10)[0]
        except subprocess.TimeoutExpired:  # a process we could not see holds the pipe
            proc.wait()
            output = "(output lost: a process left behind holds pytest's output)"
    return output


def run_once(test: str, env: Dict[str, str], timeout: float) -> Tuple[Outcome, str, float, str]:
    """``(outcome, summary line, seconds, output)`` of one fresh pytest process for ``test``."""
    started = time.monotonic()
    proc = subprocess.Popen([PYTHON, *PYTEST, "-rfEs", test], cwd=REPO, encoding="utf-8",
                            errors="backslashreplace",
                            env={**env, "COLUMNS": "250"},  # the summary line not cut at 80
                            stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, start_new_session=True)
    try:
        output, _ = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        output = _stop_tree(proc, grace=30)
        return (Outcome.TIMEOUT, f"still running after {timeout:g} s",
                time.monotonic() - started, output)
    except BaseException:
        _stop_tree(proc, grace=30)
        raise
    outcome, summary = parse_outcome(output, proc.returncode)
    return outcome, summary, time.monotonic() - started, output


# -- the hunt ------------------------------------------------------------------------------

def _slug(test: str) -> str:
    return re.sub(r"[^\w.-]+", "_", test.replace("tests/", "", 1))[:150]


def hunt(tests: Sequence[str], runs: int, env: Dict[str, str], timeout: float, out_dir: Path,
         say: Callable[[str], None]) -> Tuple[List[Run], str]:
    """Every test ``runs`` times, taking turns; ``(runs done, why it stopped early or "")``."""
    done: List[Run] = []
    total = len(tests) * runs
    try:
        for number in range(1, runs + 1):
            for test in tests:
                outcome, summary, seconds, output = run_once(test, env, timeout)
                log = None
                if outcome.failing:
                    log = out_dir / "logs" / f"{_slug(test)}.run{number}.log"
                    log.parent.mkdir(parents=True, exist_ok=True)
                    log.write_text(output)
                done.append(Run(test, number, outcome, seconds, summary, log))
                say(f"[{len(done):>{len(str(total))}}/{total}] {outcome.value.upper():<7} "
                    f"{seconds:6.1f} s  load {os.getloadavg()[0]:4.1f}  {test}"
                    + (f"\n    {summary}" if outcome is not Outcome.PASSED else ""))
    except KeyboardInterrupt:
        return done, "stopped by SIGINT"
    except Stopped:
        return done, "stopped by SIGTERM"
    return done, ""


def collect(args: Sequence[str], env: Dict[str, str], process_level: bool = False) -> List[str]:
    """The test ids pytest collects for ``args``; raises ValueError with pytest's complaint."""
    extra = ["-p", "tests.flake_hunt", "--flake-hunt-process-level"] if process_level else []
    result = subprocess.run([PYTHON, *PYTEST, "--collect-only", *extra, *args], cwd=REPO,
                            env=env, text=True, capture_output=True)
    ids = [line for line in result.stdout.splitlines() if re.match(r"\S+\.py::", line)]
    if result.returncode != 0 or not ids:
        complaint = [line for line in (result.stdout + result.stderr).splitlines()
                     if line.startswith("ERROR") or "rror" in line[:40]]
        raise ValueError("\n".join(complaint[:10]) or f"pytest collected no test from "
                         f"{' '.join(args)} (only tests inside {REPO} can be hunted)")
    return ids


def report(path: Path, command: str, tallies: Sequence[Tally], burner_count: int,
           stopped: str, started: str, load: Tuple[float, float]) -> None:
    head = subprocess.run(["git", "describe", "--always", "--dirty"], cwd=REPO, text=True,
                          capture_output=True).stdout.strip()
    lines = [f"# Flake hunt {started}", "",
             f"`{command}`", "",
             f"Head {head}; {os.cpu_count()} CPUs, {burner_count} burners; load average "
             f"{load[0]:.1f} at the start, {load[1]:.1f} at the end."
             + (f"  **{stopped} before the last run.**" if stopped else ""), "",
             markdown_table(tallies), ""]
    for entry in tallies:
        if entry.failures:
            lines += [f"## `{entry.test}`: {entry.failures} of {entry.runs} failed", ""]
            lines += [f"- {count}x `{line}`" for line, count in entry.distinct.most_common()]
            lines += [f"- log: [{log.name}](logs/{log.name})" for log in entry.logs] + [""]
    path.write_text("\n".join(lines))


def parse_args(argv: Optional[Sequence[str]]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog="tests/flake_hunt.py", description=__doc__.split("\n\n")[0],
        epilog="Exit status: 0 every run passed, 1 a run failed or the hunt was stopped, "
               "2 misuse.")
    parser.add_argument("tests", nargs="*", metavar="TESTID",
                        help="pytest node ids, files or folders (each test found is hunted)")
    parser.add_argument("--runs", type=int, default=20, help="runs of each test (20)")
    parser.add_argument("--burners", type=int, default=2, help="busy-loop processes (2)")
    parser.add_argument("--known", action="store_true",
                        help="add every test that ever failed in a fresh-clone run")
    parser.add_argument("--process-level", action="store_true",
                        help="add every test that starts processes (within TESTIDs if given)")
    parser.add_argument("--timeout", type=float, default=900,
                        help="seconds before a run counts as a failure (900)")
    parser.add_argument("--list", action="store_true", help="print the tests and stop")
    parser.add_argument("--junit", nargs="+", action="extend", type=Path, metavar="REPORT",
                        help="run nothing: count the runs JUnit reports of suite rounds "
                             "record (of the TESTIDs, given before it, or of every test)")
    parser.add_argument("--out", type=Path, default=REPO / "out",
                        help="where out/flake-hunt-<time>/ goes (out/)")
    args = parser.parse_args(argv)
    if not (args.tests or args.known or args.process_level or args.junit):
        parser.error("name tests to hunt, or --known, or --process-level, or --junit")
    if args.runs < 1 or args.burners < 0 or args.timeout <= 0:
        parser.error("--runs must be at least 1, --burners at least 0, --timeout positive")
    args.error = parser.error
    return args


def main(argv: Optional[Sequence[str]] = None) -> int:
    args = parse_args(argv)
    if sys.path and Path(sys.path[0]).resolve() == REPO / "tests":
        sys.path[0] = str(REPO)  # run as a script: tests/system would hide the project's system
    env = {**os.environ, **ci_environment(RUN_TESTS.read_text())}
    try:
        tests = collect([known.test for known in KNOWN], env) if args.known else []
        if args.process_level:
            tests += collect(args.tests or ["tests"], env, process_level=True)
        elif args.tests:
            tests += collect(args.tests, env)
    except ValueError as error:
        args.error(f"pytest cannot collect these tests:\n{error}")
    tests = list(dict.fromkeys(tests))
    if args.junit:
        return tally_rounds(args.junit, tests, args.error)
    if args.list:
        print("\n".join(tests))
        return 0
    started = time.strftime("%Y%m%d-%H%M%S")
    out_dir = args.out / f"flake-hunt-{started}"
    out_dir.mkdir(parents=True)
    command = " ".join(shlex.quote(word) for word in ["tests/flake_hunt.py", *sys.argv[1:]])
    print(f"{len(tests)} test(s) x {args.runs} run(s), {args.burners} burner(s); "
          f"report in {out_dir.relative_to(REPO) if out_dir.is_relative_to(REPO) else out_dir}",
          flush=True)
    load_before = os.getloadavg()[0]

    def on_term(signum: int, frame: Optional[types.FrameType]) -> None:
        raise Stopped()

    signal.signal(signal.SIGTERM, on_term)
    with burners(args.burners):
        done, stopped = hunt(tests, args.runs, env, args.timeout, out_dir,
                             lambda line: print(line, flush=True))
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    tallies = tally(done, tests)
    print(("\n" + stopped + ": the figures so far" if stopped else "") + "\n" + table(tallies))
    report(out_dir / "report.md", command, tallies, args.burners, stopped,
           started, (load_before, os.getloadavg()[0]))
    print(f"\nreport: {out_dir / 'report.md'}")
    return 1 if stopped or any(entry.failures for entry in tallies) else 0


def tally_rounds(paths: Sequence[Path], tests: Sequence[str],
                 error: Callable[[str], None]) -> int:
    """``--junit``: the rounds, then each failing test's row and how often each test ran."""
    rounds = []
    for path in paths:
        try:
            data = path.read_bytes()
            text = (gzip.decompress(data) if path.suffix == ".gz" else data).decode(
                "utf-8", "replace")
            rounds.append(junit_round(path, text, lambda name: (REPO / name).is_file()))
        except (OSError, ValueError, EOFError) as why:
            error(str(why))
    runs = [run for one in rounds for run in one.runs if not tests or run.test in tests]
    tallies = tally(runs, tests)
    print(rounds_table(rounds) + "\n")
    failing = [entry for entry in tallies if entry.failures]
    if failing:
        print(table(failing) + "\n")
    print(counts_line(tallies))
    conditions = sorted({one.conditions for one in rounds})
    for beside in conditions if len(conditions) > 1 else ():
        of = [run for one in rounds if one.conditions == beside for run in one.runs
              if not tests or run.test in tests]
        print(f"  beside {beside or '?'}: " + counts_line(tally(of, tests)))
    return 1 if failing else 0


# -- pytest plugin: --process-level ---------------------------------------------------------

SPAWNERS = ("subprocess", "multiprocessing")


def _ours(obj: object) -> bool:
    try:
        path = Path(inspect.getsourcefile(obj) or "").resolve()  # type: ignore[arg-type]
    except TypeError:
        return False
    return path.is_relative_to(REPO) and not path.is_relative_to(REPO / ".venv")


def _codes(code: types.CodeType) -> Iterator[types.CodeType]:
    yield code
    for const in code.co_consts:
        if isinstance(const, types.CodeType):
            yield from _codes(const)


def starts_processes(obj: object, seen: Optional[set] = None) -> bool:
    """Whether ``obj`` (a function or class of ours) names subprocess or multiprocessing, or
    names a function or class of ours that does, at any depth.

    A test is process-level when its function or one of its fixtures does.  It is a static
    over-estimate (a class counts if any of its methods starts a process) and it cannot see
    a process started through an object handed in from elsewhere; ``--list`` shows the choice.
    """
    top = seen is None
    seen = set() if seen is None else seen
    obj = inspect.unwrap(obj) if callable(obj) else obj
    if id(obj) in _VERDICTS:
        return _VERDICTS[id(obj)]
    if id(obj) in seen:
        return False  # a cycle: its other paths are being looked at already
    seen.add(id(obj))
    verdict = _starts_processes(obj, seen)
    if verdict or top:  # a False below the top may be a cycle cut short, not final
        _VERDICTS[id(obj)] = verdict
    return verdict


_VERDICTS: Dict[int, bool] = {}  # id of a function or class (alive: held by its module)


def _starts_processes(obj: object, seen: set) -> bool:
    if isinstance(obj, type):
        members = [getattr(m, "fget", None) if isinstance(m, property)
                   else getattr(m, "__func__", m) for m in vars(obj).values()]
        return any(isinstance(m, types.FunctionType) and starts_processes(m, seen)
                   for m in members)
    if not isinstance(obj, types.FunctionType):
        return False
    names = {name for code in _codes(obj.__code__) for name in code.co_names}
    if names & set(SPAWNERS):  # also a module imported inside the function
        return True
    for name in names:
        value = obj.__globals__.get(name)
        if isinstance(value, types.ModuleType):
            if value.__name__.split(".")[0] in SPAWNERS:
                return True
            if _ours(value) and any(starts_processes(getattr(value, attr), seen)
                                    for attr in names & set(vars(value))
                                    if _ours_callable(getattr(value, attr))):
                return True
        elif str(getattr(value, "__module__", "")).split(".")[0] in SPAWNERS:
            return True
        elif _ours_callable(value) and starts_processes(value, seen):
            return True
    return False


def _ours_callable(value: object) -> bool:
    return isinstance(value, (types.FunctionType, type)) and _ours(value)


def pytest_addoption(parser) -> None:  # type: ignore[no-untyped-def]
    parser.addoption("--flake-hunt-process-level", action="store_true",
                     help="keep only the tests that start processes (tests/flake_hunt.py)")


def pytest_collection_modifyitems(config, items) -> None:  # type: ignore[no-untyped-def]
    if not config.getoption("flake_hunt_process_level"):
        return
    keep, drop = [], []
    for item in items:
        fixtures = [d.func for defs in item._fixtureinfo.name2fixturedefs.values() for d in defs]
        spawns = any(_ours_callable(f) and starts_processes(f)
                     for f in [getattr(item, "function", None), *fixtures])
        (keep if spawns else drop).append(item)
    config.hook.pytest_deselected(items=drop)
    items[:] = keep


if __name__ == "__main__":
    sys.exit(main())
