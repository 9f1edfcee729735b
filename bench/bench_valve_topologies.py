#!/usr/bin/env python3
"""A DRC task clicked through the Pilot Interface, end to end, on lab, drc and degraded.

    sudo .venv/bin/python bench/bench_valve_topologies.py [--task drc_valve] [--rounds 3]
                                                          [--runs 1] [--only lab,drc,degraded]

``--task`` is any task module with its station (drc_valve, drc_drive, drc_door, drc_wall,
drc_plug; the HAL starts at its station, the PI clicks its pose and its ``TASK_STEPS``);
per run it also counts the bytes each bridge sent per id meanwhile: the task's own
(commands down, statuses up), the robot state's, all.  The valve is the default and the
description below.

Each topology starts as a user starts it (:mod:`system.topology`, the component table
``walkman-pc`` and the main job use; the HAL at the valve station, gaze_control,
temperature, perception, joint state, the session's rosbag, plus ``drc_valve`` under
its supervisor):

``lab``       one PC, no bridge (the paper's lab), on this machine's loopback;
``drc``       robot and pilot PCs on emulated hosts (:mod:`netem.emulation`), both
              bridges over the user-space radio (:mod:`netem.radio_stage`): 1 Mbit/s,
              50 ms one way, 5 % loss;
``degraded``  the same hosts at 9600 bit/s, 50 ms one way, no loss.

The pilot is the real PI (``walkman-pilot``'s window, ``tests/system/pi_driver.py
valve``) on a private Xvfb display, clicking the task widget's buttons with QTest:
start the module, then RUNS times the whole task -- ``valvedatasent`` (the pose
fields' defaults) -> ready, reach, approach, grasp, ``turn`` (its 3 s countdown, then
``turning``) -> grasped, ungrasp, move_away, home -> idle.  A step lasts from its click
to the task widget showing the state it ends in; a run from the first click to
``idle`` shown.  By default each run has a freshly started topology (``--rounds``,
interleaved lab, drc, degraded, lab...: a load from other work weighs on each alike);
``--runs`` repeats the task on one start, but the second task from the same pose turns
the valve about 0.47 rad instead of 1.61 (the angle is printed per run).  The PI's layout has the valve's task widget, status, link and log but
no 3-D view (``--layout main-pilot`` for the DRC's, librviz drawing on Mesa: on a
2-core box its rendering competes with the robot's programs for the CPU).

Blackouts are off: a profile's blackouts run only under ``walkman-netem blackouts``,
which this bench never starts, and :meth:`EmulatedLink.apply` ends any; the radio
stage's settings are read before and after each topology and printed (blackout
false) with what the radio delivered and dropped.  Loss stays: drc's 5 % is the
profile, not a blackout.

Where the time goes: every program logs wall-clock times (``WALKMAN_LOG_TIME``; the
emulated PCs share this machine's clock), so each step splits into click -> gateway
sent it, gateway -> module took it (the bridge, on drc/degraded), module took it ->
gateway received the end state (the motion, and the status's way back), and gateway
-> PI showed it.  Needs root (network namespaces) and Xvfb; without them it says so
and skips.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import statistics
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Dict, List, Optional, Tuple

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(ROOT))

from netem import emulation  # noqa: E402
from host import say_machine  # noqa: E402  (bench/ is the script's folder)
from nodekit.logs import LOG_TIME_ENV  # noqa: E402
from system.display import display_env, private_display  # noqa: E402
from system.processes import Proc  # noqa: E402
from system.topology import PYTHON, Component, Topology, task_component  # noqa: E402
from walkman import MODELS_DIR  # noqa: E402
from walkman.model.mjcf import task_harness  # noqa: E402

DRIVER = ROOT / "tests" / "system" / "pi_driver.py"
TOPOLOGIES = ("lab", "drc", "degraded")
#: The issue's goals: a topology's median run within this factor of lab's.
GOALS = {"drc": 1.1, "degraded": 1.5}
#: Each task: the station the HAL starts at (walkman.model.mjcf.STATIONS) and the bridge id
#: its commands and statuses cross on (walkman/models/bridge_drc.xml).
TASKS = {"drc_valve": ("valve", 2), "drc_drive": ("car", 4), "drc_wall": ("wall", 5),
         "drc_door": ("door", 6), "drc_plug": ("plug", 11)}
ROBOT_STATE_ID = 20


def hal_at(station: str) -> Component:
    return Component("hal", "robot", (PYTHON, "-m", "walkman.hal.server", "--backend", "sim",
                                      "--station", station, "--harness",
                                      task_harness(station)), r"HAL for walkman")


def bench_layouts(task: str) -> str:
    """The task's widget without the 3-D view."""
    return f"""
[layout valve-bench]
description = the task's widget, status, link and log, no 3-D view (bench_valve_topologies)
tab Tasks = task:{task}
tab Status = status link
side = log
"""


#: What each bridge has sent per id so far (run on the bridge's PC): ``{"tcp": {id: bytes},
#: "udp": {id: bytes}}`` from the bridge's rpc ``status``.
BYTES_PROBE = """
import json, sys
from bridge.status import from_bottle
from yarp_lite.bottle import Bottle
from yarp_lite.rpc import RpcClient
client = RpcClient("/bench/bytes")
assert client.connect(sys.argv[1])
status = from_bottle(client.call(Bottle(["status"]), timeout=20))
print(json.dumps({"tcp": status["tcp"].get("bytes_by_id", {}),
                  "udp": status.get("udp", {}).get("bytes_by_id", {})}))
"""
TIMED = re.compile(r"^TIMED (\d+) (\S+) (\S+) (\d+\.\d+) (\d+\.\d+)")
SHOWN = re.compile(r"^SHOWN (\d+\.\d+) (\S+) (\d+\.\d+)")
GATEWAY_SENT = r"^(\d+\.\d+) .*gateway: sent to /{task}/command:i: \(?(\w+)"
MODULE_TOOK = r"^(\d+\.\d+) .*{task}: command (\S+)"


def say(text: str) -> None:
    print(text, flush=True)


@dataclass
class Step:
    """One click and what followed, wall-clock seconds."""
    run: int
    command: str
    state: str
    clicked: float
    shown: float
    sent: Optional[float] = None       # the gateway wrote it to /<task>/command:i
    took: Optional[float] = None       # the module took it from its inbox
    received: Optional[float] = None   # the gateway received the end state

    @property
    def seconds(self) -> float:
        return self.shown - self.clicked


@dataclass
class Result:
    kind: str
    steps: List[Step] = field(default_factory=list)
    turned: List[float] = field(default_factory=list)   # rad the valve turned, per run
    #: per run: its seconds, and what each bridge sent meanwhile, per channel and id
    crossed: List[Tuple[float, Dict]] = field(default_factory=list)
    radio: Dict = field(default_factory=dict)

    def runs(self) -> List[float]:
        """Each run's seconds, first click to idle shown."""
        by_run: Dict[int, List[Step]] = {}
        for step in self.steps:
            by_run.setdefault(step.run, []).append(step)
        return [steps[-1].shown - steps[0].clicked for _, steps in sorted(by_run.items())]


def first_after(times: List[Tuple[float, str]], after: float, word: str,
                before: float) -> Optional[float]:
    return next((at for at, said in times if after <= at < before and said == word), None)


def attribute(steps: List[Step], driver: Proc, topology: Topology, task: str) -> None:
    """Fill each step's gateway and module times from the programs' logs."""
    gateway_sent = re.compile(GATEWAY_SENT.format(task=task))
    module_took = re.compile(MODULE_TOOK.format(task=task))
    sent = [(float(m.group(1)), m.group(2)) for m in map(gateway_sent.search,
                                                         topology.process("gateway").lines) if m]
    took = [(float(m.group(1)), m.group(2)) for m in map(module_took.search,
                                                         topology.process(task).lines) if m]
    shown = [(float(m.group(1)), m.group(2), float(m.group(3)))
             for m in map(SHOWN.search, driver.lines) if m]
    for index, step in enumerate(steps):
        before = steps[index + 1].clicked if index + 1 < len(steps) else float("inf")
        step.sent = first_after(sent, step.clicked, step.command, before)
        step.took = first_after(took, step.clicked, step.command, before)
        step.received = next((stamp for at, state, stamp in shown
                              if at == step.shown and state == step.state), None)


def valve_angle(topology: Topology, task: str) -> float:
    """The valve's angle (the valve task's outcome); nan for the other tasks."""
    if task != "drc_valve":
        return float("nan")
    out = topology.robot.run([PYTHON, "-m", "tests.modules.scene", "valve"], timeout=90).output()
    words = out.split()
    return float(words[words.index("valve") + 1])


def bytes_sent(topology: Topology) -> Dict[str, Dict[str, Dict[str, int]]]:
    """Each bridge's bytes sent so far per channel and id (empty in the lab: no bridge)."""
    if topology.kind == "lab":
        return {}
    out = {}
    for side in ("robot", "pilot"):
        proc = topology.pcs[side].run([PYTHON, "-c", BYTES_PROBE, f"/bridge/{side}/rpc:i"],
                                      timeout=60)
        lines = [line for line in proc.lines if line.startswith("{")]
        out[side] = json.loads(lines[-1]) if lines else {}
    return out


def bytes_between(before: Dict, after: Dict) -> Dict[str, Dict[str, Dict[str, int]]]:
    return {side: {channel: {key: value - before.get(side, {}).get(channel, {}).get(key, 0)
                             for key, value in ids.items()}
                   for channel, ids in channels.items()}
            for side, channels in after.items()}


def radio_status(link) -> Dict:
    return link.status() if link is not None else {}


def counted(before: Dict, after: Dict) -> Dict[str, Dict[str, int]]:
    """What the radio counted between two of its statuses, per direction."""
    return {direction: {name: value - before["counters"][direction].get(name, 0)
                        for name, value in counters.items()}
            for direction, counters in after.get("counters", {}).items()}


class BenchTopology(Topology):
    """A topology whose bridges may pace UDP to another budget (``--udp-rate``, a diagnosis)."""

    udp_rate: Optional[str] = None

    def _argv(self, component: Component) -> List[str]:
        argv = super()._argv(component)
        if self.udp_rate and component.name.startswith("bridge_"):
            argv[argv.index("--udp-rate") + 1] = self.udp_rate
        return argv


def run_topology(kind: str, root: Path, link, display: str, options, result: Result,
                 first_run: int) -> None:
    """``options.runs`` valve tasks on a freshly started ``kind``, added to ``result``."""
    profile = "lab" if kind == "lab" else kind
    root = root / f"{kind}-{first_run}"
    topology = BenchTopology("lab" if kind == "lab" else "drc", root,
                             link=None if kind == "lab" else link, profile=profile,
                             extra=[hal_at(TASKS[options.task][0]),
                                    task_component(options.task)],
                             extra_env={LOG_TIME_ENV: "1"})
    topology.udp_rate = options.udp_rate
    for name in options.without:
        topology.table.pop(name, None)
    for pc in topology.unique_pcs():
        pc.log_dir = root / f"{pc.name}-logs"
        pc.log_dir.mkdir(parents=True, exist_ok=True)
    try:
        topology.start_name_servers()
        before = radio_status(topology.link)
        if before and before["settings"].get("blackout"):
            raise RuntimeError(f"the radio is blacked out at the start: {before}")
        topology.start_all()
        topology.wait_ready(300)
        angle = valve_angle(topology, options.task)
        say(f"  {kind}: topology up; the PI clicks {options.task} {options.runs} times "
            f"(load {os.getloadavg()[0]:.1f})")
        layouts = root / "bench_layouts.ini"
        layouts.write_text((MODELS_DIR / "pilot_layouts.ini").read_text() +
                           bench_layouts(options.task))
        topology.pilot.extra_env.update(display_env(display), PI_LAYOUT=options.layout,
                                        PI_LAYOUTS=str(layouts), PI_NAME=f"bench_{kind}")
        out = root / "screens"
        out.mkdir(parents=True, exist_ok=True)
        counted_from = bytes_sent(topology)
        driver = topology.pilot.start("pi_task", [PYTHON, str(DRIVER), "task", str(out),
                                                  options.task, str(options.runs)], stdin=True)
        for run in range(options.runs):
            driver.wait_for(rf"RUN {run} done|FAIL", 900)
            if "FAIL" in driver.output():
                raise RuntimeError(f"the PI driver failed on {kind}:\n{driver.output()[-3000:]}")
            done = [s for s in parse_steps(driver) if s.run == run]
            sent_now = bytes_sent(topology)   # one probe: each byte counts in one run
            crossed, counted_from = bytes_between(counted_from, sent_now), sent_now
            result.crossed.append((done[-1].shown - done[0].clicked, crossed))
            now = valve_angle(topology, options.task)
            turned, angle = now - angle, now
            result.turned.append(turned)
            say(f"    run {first_run + run + 1}: {done[-1].shown - done[0].clicked:.2f} s"
                + ("" if math.isnan(turned) else f", valve turned {turned:.3f} rad")
                + "  (" + ", ".join(f"{s.command} {s.seconds:.2f}" for s in done) + ")")
            if run + 1 < options.runs:
                driver.send("next\n")
        driver.wait_for(r"DONE", 30)
        steps = parse_steps(driver)
        attribute(steps, driver, topology, options.task)
        for step in steps:
            step.run += first_run
        result.steps += steps
        after = radio_status(topology.link)
        if after:
            if after["settings"].get("blackout") or any(
                    c.get("blackout") for c in counted(before, after).values()):
                raise RuntimeError(f"the radio blacked out during the runs: {after}")
            result.radio = {"settings": after["settings"], "counters": {
                direction: {name: result.radio.get("counters", {}).get(direction, {})
                            .get(name, 0) + value for name, value in counters.items()}
                for direction, counters in counted(before, after).items()}}
    finally:
        topology.close()


def parse_steps(driver: Proc) -> List[Step]:
    return [Step(int(m.group(1)), m.group(2), m.group(3), float(m.group(4)),
                 float(m.group(5))) for m in map(TIMED.search, driver.lines) if m]


def median_of(values: List[Optional[float]]) -> float:
    known = [v for v in values if v is not None]
    return statistics.median(known) if known else float("nan")


def report(results: Dict[str, Result], runs: int, task: str) -> None:
    lab = results.get("lab")
    lab_median = statistics.median(lab.runs()) if lab else None
    say(f"\n{task} by the PI, first click to the last step's state shown, s ({runs} runs "
        f"each)")
    say(f"{'topology':<10} {'median':>7} {'min':>7} {'max':>7} {'x lab':>6}  {'goal':<9} "
        f"{'':<5} {'valve turned, each run' if task == 'drc_valve' else ''}")
    for kind, result in results.items():
        times = result.runs()
        median = statistics.median(times)
        ratio = median / lab_median if lab_median else float("nan")
        goal = GOALS.get(kind)
        verdict = "" if goal is None or lab_median is None else \
            ("pass" if ratio <= goal else "FAIL")
        goal_text = f"<= {goal:.1f}x" if goal else "-"
        say(f"{kind:<10} {median:>7.2f} {min(times):>7.2f} {max(times):>7.2f} {ratio:>6.2f}  "
            f"{goal_text:<9} {verdict:<5} "
            + (" ".join(f"{angle:.2f}" for angle in result.turned) + " rad (1.57 asked)"
               if task == "drc_valve" else ""))
    say("\nPer step, medians in s: click -> gateway sent | gateway -> module took | "
        "module took -> gateway got the end state | gateway -> PI showed | whole step")
    commands = [s.command for s in next(iter(results.values())).steps if s.run == 0]
    say(f"{'step':<14}" + "".join(f"{kind:>38}" for kind in results))
    for command in commands:
        cells = []
        for result in results.values():
            steps = [s for s in result.steps if s.command == command]
            parts = [median_of([(s.sent - s.clicked) if s.sent else None for s in steps]),
                     median_of([(s.took - s.sent) if s.took and s.sent else None
                                for s in steps]),
                     median_of([(s.received - s.took) if s.received and s.took else None
                                for s in steps]),
                     median_of([(s.shown - s.received) if s.received else None for s in steps]),
                     statistics.median(s.seconds for s in steps)]
            cells.append(" ".join(f"{p:6.2f}" for p in parts))
        say(f"{command:<14}" + "".join(f"{cell:>38}" for cell in cells))
    module_id = str(TASKS[task][1])
    say(f"\nBytes through the bridge per run (the task's id {module_id}: commands pilot -> "
        f"robot, statuses robot -> pilot; the robot state, id {ROBOT_STATE_ID}, at 10 Hz "
        f"meanwhile; everything)")
    for kind, result in results.items():
        for seconds, crossed in result.crossed:
            if not crossed:
                say(f"{kind:<10} {seconds:7.1f} s  (no bridge)")
                continue
            down = crossed.get("pilot", {}).get("tcp", {}).get(module_id, 0)
            up = crossed.get("robot", {}).get("tcp", {}).get(module_id, 0)
            state = crossed.get("robot", {}).get("tcp", {}).get(str(ROBOT_STATE_ID), 0)
            total = sum(value for side in crossed.values() for ids in side.values()
                        for value in ids.values())
            say(f"{kind:<10} {seconds:7.1f} s  task {down:>7} B down {up:>8} B up "
                f"({8 * (down + up) / 1000:.1f} kbit)  robot state {state / 1e3:8.1f} kB  "
                f"all {total / 1e6:7.2f} MB ({8 * total / seconds / 1e3:.0f} kbit/s)")
    for kind, result in results.items():
        if result.radio:
            say(f"radio on {kind}: settings {result.radio['settings']}")
            for direction, counters in result.radio.get("counters", {}).items():
                say(f"    {direction}: {counters}")


def main(argv: Optional[List[str]] = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--task", default="drc_valve", choices=sorted(TASKS),
                        help="the task the PI clicks through (default %(default)s)")
    parser.add_argument("--runs", type=int, default=1,
                        help="tasks per start of a topology (default %(default)s)")
    parser.add_argument("--rounds", type=int, default=3,
                        help="starts of each topology, interleaved lab, drc, degraded, lab... "
                             "(default %(default)s)")
    parser.add_argument("--without", default="",
                        help="leave these components out (comma-separated; a diagnosis, "
                             "e.g. perception: what its stream costs the task)")
    parser.add_argument("--udp-rate",
                        help="the bridges' UDP budget instead of the topology's (60 %% of the "
                             "link; a diagnosis: e.g. 1440 on degraded, 15 %%)")
    parser.add_argument("--only", default=",".join(TOPOLOGIES),
                        help="topologies, comma-separated (default %(default)s)")
    parser.add_argument("--layout", default="valve-bench",
                        help="the PI's layout (default %(default)s: no 3-D view; main-pilot "
                             "is the DRC's, with librviz)")
    parser.add_argument("--logs", type=Path,
                        help="keep every program's log here (default: a folder removed after)")
    options = parser.parse_args(argv)
    kinds = options.only.split(",")
    options.without = [name for name in options.without.split(",") if name]
    if any(kind not in TOPOLOGIES for kind in kinds):
        parser.error(f"--only takes {', '.join(TOPOLOGIES)}")
    reason = emulation.available()
    if reason is not None and kinds != ["lab"]:
        say(f"bench_valve_topologies: skipped: {reason} (run it with sudo)")
        return 0
    say_machine("before")
    from nodekit.msgs import generate

    generate()
    results: Dict[str, Result] = {}
    link = None
    began = time.monotonic()
    try:
        with private_display() as display, tempfile.TemporaryDirectory(
                prefix="bench-valve-") as tmp:
            if options.logs is not None:
                tmp = str(options.logs.resolve())
                say(f"logs in {tmp}/<topology>/")
            for round_ in range(options.rounds):     # interleaved: a load that comes and
                for kind in kinds:                    # goes weighs on every topology alike
                    if kind != "lab" and link is None:
                        link = emulation.EmulatedLink(f"wv{os.getpid() % 1000}", 63)
                        link.up()
                    run_topology(kind, Path(tmp), link, display, options,
                                 results.setdefault(kind, Result(kind)), round_ * options.runs)
    finally:
        if link is not None:
            link.down()
    report(results, options.runs * options.rounds, options.task)
    if options.without or options.udp_rate:
        say(f"(without {', '.join(options.without) or 'nothing'}, UDP budget "
            f"{options.udp_rate or 'as started'}: not the topology a user starts)")
    say(f"\n({time.monotonic() - began:.0f} s in all)")
    say_machine("after")
    return 0


if __name__ == "__main__":
    sys.exit(main())
