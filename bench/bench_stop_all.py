#!/usr/bin/env python3
"""The pilot's stop-all through the drc topology on the emulated radio (needs root).

The whole drc topology runs (HAL, gaze_control, temperature, perception streaming its
images and clouds over the same radio, both bridges, the gateway), the two modules
started.  Then, on each profile, ROUNDS stop-alls are sent as the PI's button sends them
(``stop_all`` on ``/bridge/pilot/rpc:i``, from the pilot's emulated PC), each followed by
a release.  For each:

* *held*: from the pilot bridge's sending to the robot held -- its first copy's arrival on
  the robot's bridge, plus the robot's own part (the HAL's halt and the modules' pause).
  Both bridges log each stop with the wall clock (``WALKMAN_LOG_TIME``), which the two
  emulated PCs share;
* *ack*: the click-to-acknowledgement time the pilot bridge measured (the stop went out by
  TCP and as repeated datagrams until the robot's answer came back);
* the robot's own part alone.

Goals: issue 33, ack p99 <= 2 round trips of the link, < 100 ms on drc; issue 66, held p99
<= 500 ms on ``degraded`` and <= 200 ms on drc at 30 % loss, none lost or unacknowledged.
There is no reference implementation to compare with: neither YARP nor ROS has a stop-all
across two name servers.

Usage: ``.venv/bin/python bench/bench_stop_all.py [--rounds N]``.
"""

from __future__ import annotations

import argparse
import os
import random
import re
import statistics
import sys
import tempfile
import textwrap
from pathlib import Path
from typing import Dict, List, Tuple

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(ROOT))

from netem.emulation import PROFILES, EmulatedLink  # noqa: E402
from nodekit.logs import LOG_TIME_ENV  # noqa: E402
from host import say_machine  # noqa: E402  (bench/ is the script's folder)
from system.topology import PYTHON, Topology  # noqa: E402

CASES: List[Tuple[str, float]] = [("drc", 5.0), ("drc", 30.0), ("degraded", 0.0)]
#: Issue 66's goals for click-to-held p99, ms, by case.
HELD_GOALS: Dict[Tuple[str, float], float] = {("drc", 30.0): 200.0, ("degraded", 0.0): 500.0}
#: What this bench measured before the link budget (2026-12-07, 20-100 clicks, load < 2),
#: printed beside today's figures.
BEFORE: Dict[Tuple[str, float], str] = {
    ("drc", 5.0): "held 54 / 56 ms, acknowledged 106 / 110 ms",
    ("drc", 30.0): "held 53 / 304 ms, acknowledged 106 / 356 ms",
    ("degraded", 0.0): "held 125 / 2566 ms, acknowledged 2622 / 4821 ms, 2 of 20 unanswered",
}
#: ``<time> [bridge...] INFO bridge.stop: stop_all ID: ...``, as each bridge logs a stop.
STOP_LOG = re.compile(r"^(?P<time>\d+\.\d+) .*bridge\.stop: stop_all (?P<id>\d+): "
                      r"(?P<what>sent|its first copy arrived|held, .* in (?P<ms>[\d.]+) ms)")

CLIENT = textwrap.dedent("""
    import sys, time
    from yarp_lite.bottle import Bottle
    from yarp_lite.rpc import RpcClient
    client = RpcClient(None)
    client.connect("/bridge/pilot/rpc:i")
    for _ in range(int(sys.argv[1])):
        for word in ("stop_all", "release"):
            reply = client.call(Bottle([word]), timeout=30.0)
            fields = {str(f[0]): list(f)[1:] for f in list(reply)[2:]} if reply[0] == "ok" \\
                else {}
            if word == "stop_all":
                print("STOP", reply[0], fields.get("round_trip_ms", ["nan"])[0],
                      fields.get("robot_ms", ["nan"])[0], flush=True)
        time.sleep(0.3)
""")


def held_times(pilot_lines: List[str], robot_lines: List[str]) -> Tuple[List[float], int]:
    """Click-to-held of each stop the pilot bridge sent (ms, in the order sent), and how
    many it sent that the robot never held."""
    sent: Dict[str, float] = {}
    arrived: Dict[str, float] = {}
    took: Dict[str, float] = {}
    for line in pilot_lines:
        match = STOP_LOG.match(line)
        if match and match["what"] == "sent":
            sent[match["id"]] = float(match["time"])
    for line in robot_lines:
        match = STOP_LOG.match(line)
        if match and match["what"].startswith("its first"):
            arrived[match["id"]] = float(match["time"])
        elif match and match["ms"]:
            took[match["id"]] = float(match["ms"])
    held = [(arrived[i] - at) * 1000.0 + took[i] for i, at in sent.items()
            if i in arrived and i in took]
    return held, len(sent) - len(held)


def percentile(values: List[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(round(q * (len(ordered) - 1))))]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rounds", type=int, default=40, help="stop-alls per profile")
    parser.add_argument("--only", default="drc,degraded",
                        help="which profiles (default drc,degraded)")
    parser.add_argument("--each", action="store_true",
                        help="also print every stop's held and acknowledged times, in order")
    options = parser.parse_args()
    wanted = options.only.split(",")
    unknown = sorted(set(wanted) - {profile for profile, _ in CASES})
    if unknown:
        parser.error(f"unknown profile(s) {', '.join(unknown)}: drc or degraded")
    if os.geteuid() != 0:
        print("bench_stop_all: needs root (network namespaces)", file=sys.stderr)
        return 2
    say_machine()
    print(f"{'profile':<10} {'loss':>5} {'rtt':>7} {'n':>4} | {'held median':>11} "
          f"{'p99':>8} {'never':>5} {'goal p99':>9} | {'ack median':>10} {'p99':>8} "
          f"{'failed':>6} {'goal p99':>14} | {'robot median':>12}")
    for profile in wanted:
        # Each profile's own topology: the bridges pace perception to its link (udp_budget).
        measure(profile, [loss for name, loss in CASES if name == profile], options.rounds,
                options.each)
    say_machine()
    return 0


def measure(profile: str, losses: List[float], rounds: int, each: bool = False) -> None:
    """The drc topology started for ``profile``'s link; ``rounds`` stop-alls at each loss."""
    link = EmulatedLink(f"wbs{os.getpid() % 10000}", random.randint(20, 250))
    with tempfile.TemporaryDirectory(prefix="bench-stop-") as root:
        link.up()
        topology = Topology("drc", Path(root), link=link, profile=profile, loss=0.0,
                            extra_env={LOG_TIME_ENV: "1"})     # the stops' times, logged
        try:
            topology.start_name_servers()
            topology.start_all()
            topology.wait_ready(180)
            for module in ("gaze_control", "temperature"):
                topology.pilot.run(["rosservice", "call", f"/{module}/switch_and_wait",
                                    "{command: start, timeout: 60}"], timeout=90)
            for loss in losses:
                link.apply(profile, loss=loss)
                rtt = 2 * PROFILES[profile]["delay"] * 1000.0
                bridges = [topology.process(f"bridge_{side}") for side in ("pilot", "robot")]
                before = [len(bridge.lines) for bridge in bridges]
                client = topology.pilot.run([PYTHON, "-c", CLIENT, str(rounds)],
                                            timeout=60 + rounds * 30)
                acks, robot, failed = [], [], 0
                for line in client.lines:
                    words = line.split()
                    if words[:1] != ["STOP"]:
                        continue
                    if words[1] != "ok":
                        failed += 1
                        continue
                    acks.append(float(words[2]))
                    robot.append(float(words[3]))
                held, never = held_times(*(bridge.lines[start:]
                                           for bridge, start in zip(bridges, before)))
                goal = f"<= {2 * rtt:.0f}" + (" and < 100" if profile == "drc" else "")
                held_goal = HELD_GOALS.get((profile, loss))
                if not acks or not held:
                    print(f"{profile:<10} {loss:>4.0f}%: {len(acks)} stop-alls acknowledged "
                          f"({failed} failed), {len(held)} held:\n{client.output()[-2000:]}")
                    continue
                print(f"{profile:<10} {loss:>4.0f}% {rtt:>5.0f}ms {len(acks):>4} | "
                      f"{statistics.median(held):>9.1f}ms {percentile(held, 0.99):>6.1f}ms "
                      f"{never:>5} {'' if held_goal is None else f'<= {held_goal:.0f}':>9} | "
                      f"{statistics.median(acks):>8.1f}ms {percentile(acks, 0.99):>6.1f}ms "
                      f"{failed:>6} {goal:>14} | {statistics.median(robot):>10.1f}ms")
                if (profile, loss) in BEFORE:
                    print(f"  before the link budget (median / p99): {BEFORE[(profile, loss)]}")
                if each:
                    print(f"  held ms, in order: {' '.join(f'{v:.0f}' for v in held)}")
                    print(f"  acknowledged ms, in order: {' '.join(f'{v:.0f}' for v in acks)}")
        finally:
            topology.close()
            link.down()


if __name__ == "__main__":
    sys.exit(main())
