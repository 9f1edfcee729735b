#!/usr/bin/env python3
"""The Pilot Interface's benchmark: click to command, CPU with camera and cloud, start time.

    .venv/bin/python bench/bench_pilot.py [--quick] [--loopback]

Everything real: the topology's programs (``system.topology``), a private Xvfb
display, the PI's librviz on Mesa's software OpenGL.

1. **Click to command on the robot**, one way, in ``lab`` (one PC) and ``drc``
   (two PCs and the bridge; over the emulated ``drc`` link when this machine
   can build it, else loopback): a PI (``tests/system/pi_driver.py latency``)
   clicks gaze_control's ``look_at`` button with a new target each time and
   prints the wall time of each click; gaze_control logs each command it takes
   (its 100 Hz loop reads them: up to 10 ms of the figure is that tick).  The
   programs log wall-clock times (``WALKMAN_LOG_TIME``); both PCs share this
   machine's clock.  Reference: the same path without the PI, a ``rostopic
   pub``-style rospy publisher (``Command`` on ``/gaze_control/command``).
2. **CPU of the PI** (``walkman-pilot``) with the camera and the cloud at 2 Hz
   on the drc topology: the ``main-pilot`` layout (librviz drawing the robot and
   the cloud at 15 fps) and a camera-only layout (what the PI itself costs,
   librviz's rendering aside), in % of one core over 30 s.
3. **Start to a usable window**: from ``walkman-pilot`` being started to its
   ROS node being up with every topic connected (it logs "usable"), median of
   three starts.
"""

from __future__ import annotations

import argparse
import re
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Dict, List, Optional, Tuple

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from nodekit.logs import LOG_TIME_ENV  # noqa: E402
from system.compare import open_link  # noqa: E402
from system.display import display_env, private_display  # noqa: E402
from system.processes import Proc  # noqa: E402
from system.topology import PYTHON, Topology  # noqa: E402
from host import cpu_seconds, say_machine  # noqa: E402  (bench/ is the script's folder)
from walkman import MODELS_DIR  # noqa: E402

DRIVER = ROOT / "tests" / "system" / "pi_driver.py"
#: A layout with the camera and no 3-D view: the PI's own cost, librviz's rendering aside.
BENCH_LAYOUTS = """
[layout camera-only]
description = the camera view and the log (bench_pilot)
tab Camera = camera
side = log
"""
COMMAND_LINE = re.compile(r"^(\d+\.\d+) \S+ gaze_control: command look_at (\S+) (\S+) (\S+)")


def say(text: str) -> None:
    print(text, flush=True)


def percentile(values: List[float], share: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(round(share * (len(ordered) - 1))))]


def commands_taken(topology: Topology) -> Dict[Tuple[float, float], float]:
    """When gaze_control took each ``look_at`` (by its target), from its log."""
    taken = {}
    for line in topology.process("gaze_control").lines:
        match = COMMAND_LINE.search(line)
        if match:
            x, y = round(float(match.group(2)), 3), round(float(match.group(3)), 3)
            taken.setdefault((x, y), float(match.group(1)))
    return taken


def one_way(sent: Dict[Tuple[float, float], float], topology: Topology) -> List[float]:
    """Milliseconds from each send to gaze_control taking it (every one must arrive)."""
    deadline = time.monotonic() + 30
    while True:
        taken = commands_taken(topology)
        if all(key in taken for key in sent) or time.monotonic() > deadline:
            break
        time.sleep(0.2)
    lost = [key for key in sent if key not in taken]
    if lost:
        said = [line for pc in topology.unique_pcs() for proc in pc.processes.values()
                for line in proc.lines if any(f"{x} {y}" in line or f"{x}, {y}" in line
                                              for x, y in lost)]
        raise RuntimeError(f"{len(lost)} of {len(sent)} commands never reached gaze_control "
                           f"({lost}); lines naming them:\n" + "\n".join(said))
    return [(taken[key] - at) * 1e3 for key, at in sent.items()]


def target(index: int, base: float) -> Tuple[float, float]:
    return round(base + 0.001 * (index % 400), 3), round(0.2 + 0.001 * (index // 400), 3)


def sent_at(proc: Proc) -> Dict[Tuple[float, float], float]:
    """When each ``look_at`` left, by its target: the lines ``... <time> look_at x y`` that the
    PI driver (``CLICKED i``) and the rospy publisher (``SENT``) print."""
    sent = {}
    for line in proc.lines:
        match = re.match(r"(?:CLICKED \d+|SENT) (\d+\.\d+) look_at (\S+) (\S+)", line)
        if match:
            sent[(float(match.group(2)), float(match.group(3)))] = float(match.group(1))
    return sent


def click_latency(topology: Topology, display: str, count: int, out: Path) -> List[float]:
    topology.pilot.extra_env.update(display_env(display))
    driver = topology.pilot.start("pi_latency", [PYTHON, str(DRIVER), "latency", str(out),
                                                 str(count)])
    driver.wait_for(r"DONE|FAIL", 120 + count)
    if "FAIL" in driver.output():
        raise RuntimeError(driver.output()[-3000:])
    driver.kill()
    return one_way(sent_at(driver), topology)


def rospy_latency(topology: Topology, count: int) -> List[float]:
    """The reference: a plain rospy publisher on the pilot roscore, no PI."""
    proc = topology.pilot.start("rospy_latency", [PYTHON, str(Path(__file__)), "--publisher",
                                                  str(count)])
    proc.wait_for(r"DONE", 60 + count)
    proc.kill()
    return one_way(sent_at(proc), topology)


def publisher(count: int, base: float = 1.5) -> int:
    """Run on the pilot PC: publish look_at commands as ``rostopic pub`` would (targets from
    ``base``: runs with different bases are told apart in gaze_control's log)."""
    import rospy
    from nodekit.msgs import ensure_importable

    ensure_importable()
    from walkman_msgs.msg import Command

    rospy.init_node("bench_pilot_publisher", anonymous=True, disable_signals=True)
    topic = rospy.Publisher("/gaze_control/command", Command, queue_size=10)
    deadline = time.monotonic() + 10
    while topic.get_num_connections() == 0 and time.monotonic() < deadline:
        time.sleep(0.05)
    time.sleep(0.5)
    for index in range(count):
        x, y = target(index, base)
        time.sleep(0.25)
        at = time.time()
        topic.publish(Command(command="look_at", numbers=[x, y, 0.1], sender="bench"))
        print(f"SENT {at:.6f} look_at {x:.3f} {y:.3f}", flush=True)
    print("DONE", flush=True)
    return 0


def start_pi(topology: Topology, display: str, layout: str, layouts: Path,
             name: str) -> Tuple[Proc, float]:
    """Start ``walkman-pilot``; returns it and the seconds until it logged "usable"."""
    topology.pilot.extra_env.update(display_env(display))
    began = time.time()
    proc = topology.pilot.start(name, [PYTHON, "-m", "pilot.app", "--layout", layout,
                                       "--layouts", str(layouts), "--name", name])
    match = proc.wait_for(r"(\d+\.\d+) \[pilot\] INFO pilot.app: pilot: \S+ usable", 90)
    return proc, float(match.group(1)) - began


def pi_cpu(topology: Topology, display: str, layout: str, layouts: Path,
           seconds: float) -> Tuple[float, float]:
    """(% of one core over ``seconds`` after a 5 s settle, seconds to usable)."""
    name = f"pi_cpu_{layout}".replace("-", "_")
    proc, usable = start_pi(topology, display, layout, layouts, name)
    time.sleep(5)
    before, at = cpu_seconds(proc.popen.pid), time.monotonic()
    time.sleep(seconds)
    share = (cpu_seconds(proc.popen.pid) - before) / (time.monotonic() - at) * 100
    proc.kill()
    return share, usable


def run_topology(kind: str, root: Path, link, display: str, options) -> Dict[str, object]:
    figures: Dict[str, object] = {}
    topology = Topology(kind, root / kind, link=link if kind == "drc" else None,
                        profile="drc" if link is not None else "lab", perception_rate=2.0,
                        extra_env={LOG_TIME_ENV: "1"})
    topology.start_name_servers()
    try:
        topology.start_all([name for name in topology.table if name != "rosbag"])
        topology.table.pop("rosbag", None)
        topology.wait_ready(180)
        say(f"  {kind}: topology up; {options.count} clicks at 4 Hz")
        figures["click"] = click_latency(topology, display, options.count, root / kind)
        figures["rospy"] = rospy_latency(topology, options.count)
        if kind == "drc":
            layouts = root / "bench_layouts.ini"
            layouts.write_text((MODELS_DIR / "pilot_layouts.ini").read_text()
                               + BENCH_LAYOUTS)
            for layout in ("main-pilot", "camera-only"):
                figures[layout], _ = pi_cpu(topology, display, layout, layouts, options.seconds)
                say(f"  {layout}: {figures[layout]:.1f} % of one core")
            starts = []
            for index in range(3):
                proc, usable = start_pi(topology, display, "main-pilot", layouts,
                                        f"pi_start_{index}")
                proc.kill()
                starts.append(usable)
            figures["starts"] = starts
    finally:
        topology.close()
    return figures


def main(argv: Optional[List[str]] = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="fewer clicks, shorter CPU runs")
    parser.add_argument("--loopback", action="store_true",
                        help="drc on loopback even when an emulated link could be built")
    parser.add_argument("--only", default="lab,drc", help="topologies (default %(default)s)")
    parser.add_argument("--publisher", type=int, help=argparse.SUPPRESS)
    parser.add_argument("--base", type=float, default=1.5, help=argparse.SUPPRESS)
    options = parser.parse_args(argv)
    if options.publisher is not None:
        return publisher(options.publisher, options.base)
    say_machine()
    options.count = 60 if options.quick else 200
    options.seconds = 15.0 if options.quick else 30.0
    from nodekit.msgs import generate

    generate()
    link = open_link(options.loopback, say, prefix="wp", subnet=62)
    where = "emulated drc link (1 Mbit/s, 5 % loss)" if link else "loopback"
    results = {}
    try:
        with private_display() as display, tempfile.TemporaryDirectory(prefix="bench-pilot-") \
                as tmp:
            for kind in options.only.split(","):
                results[kind] = run_topology(kind, Path(tmp), link, display, options)
    finally:
        if link is not None:
            link.down()
    say(f"\n1. Click to command taken by gaze_control, one way, ms ({options.count} each; "
        f"drc over {where})")
    say(f"   {'topology':<10} {'PI median':>10} {'PI p99':>8} {'rospy median':>13} "
        f"{'rospy p99':>10}")
    for kind, figures in results.items():
        click, plain = figures["click"], figures["rospy"]
        say(f"   {kind:<10} {statistics.median(click):>10.1f} {percentile(click, 0.99):>8.1f} "
            f"{statistics.median(plain):>13.1f} {percentile(plain, 0.99):>10.1f}")
    drc = results.get("drc")
    if drc is None:
        return 0
    say(f"\n2. PI CPU with camera and cloud at 2 Hz (drc), % of one core over "
        f"{options.seconds:.0f} s (goal <= 15 besides librviz's rendering)")
    say(f"   main-pilot (librviz drawing robot and cloud): {drc['main-pilot']:.1f}")
    say(f"   camera-only (no librviz):                    {drc['camera-only']:.1f}")
    starts = drc["starts"]
    say(f"\n3. Start to a usable window (goal <= 3 s): median {statistics.median(starts):.2f} s "
        f"({', '.join(f'{s:.2f}' for s in starts)})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
