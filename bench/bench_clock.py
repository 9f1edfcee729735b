#!/usr/bin/env python3
"""The robot's simulated clock: how fast the HAL's physics runs on it, beside real time.

* For scale, in this process: MuJoCo's own ``mj_step`` on the robot's model and
  ``SimBackend.step`` (the HAL's step: servos, sensors, thermal model), as real-time factors.
* ``walkman-hal --clock /clock`` as a process, drc scene: at ``--rtf 1`` (the real-time
  baseline: what the main job and the PI run) and at ``--rtf max``; alone, and two robots
  side by side, each with its own name server.  The factor is read as a follower reads it:
  simulated time from the ``/clock`` ticks (``yarp_lite.time.NetworkClock``) over wall time.
* The HAL at ``--rtf max`` and the walking module in lockstep with it (``--lockstep``,
  started on launch: it crouches, then balances on its own feet, the harness off), as
  processes; alone, and two such robots side by side.

Usage: ``.venv/bin/python bench/bench_clock.py [--seconds S]``.  Needs only this project.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path
from typing import Dict, List

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

from host import say_machine  # noqa: E402  (bench/ is the script's folder)
from system.processes import Proc  # noqa: E402
from yarp_lite.freeport import free_port  # noqa: E402

PYTHON = sys.executable
#: A /clock follower: simulated over wall seconds, measured over argv[1] wall seconds.
FOLLOWER = """
import sys, time
from yarp_lite.time import NetworkClock
clock = NetworkClock("/clock").open(wait=30)
sim0, wall0 = clock.now(), time.perf_counter()
time.sleep(float(sys.argv[1]))
print("factor", (clock.now() - sim0) / (time.perf_counter() - wall0), flush=True)
clock.close()
"""


def in_process_factors(seconds: float) -> Dict[str, float]:
    """Real-time factors of mj_step alone and of SimBackend.step, ``seconds`` of wall each."""
    import mujoco

    from walkman.hal.sim import SimBackend

    backend = SimBackend(scene=True, harness="locked")
    factors = {}
    plant = backend.plant
    for name, step in (("mj_step alone", lambda: mujoco.mj_step(plant.m, plant.d)),
                       ("SimBackend.step", backend.step)):
        steps, start = 0, time.perf_counter()
        while time.perf_counter() - start < seconds:
            for _ in range(100):
                step()
            steps += 100
        factors[name] = steps * backend.dt / (time.perf_counter() - start)
    backend.close()
    return factors


class Robot:
    """A name server and ``walkman-hal --clock`` of its own."""

    def __init__(self, name: str, rtf: str, walking: bool = False) -> None:
        self.root = Path(tempfile.mkdtemp(prefix=f"walkman-clock-bench-{name}-"))
        self.env = dict(os.environ, YARP_CONFIG_HOME=str(self.root / "config"),
                        YARP_DATA_HOME=str(self.root / "data"), PYTHONUNBUFFERED="1")
        self.env.pop("YARP_CLOCK", None)
        self.children: List[Proc] = []
        server = Proc([PYTHON, "-m", "yarp_lite", "server", "--socket",
                       str(free_port(span=400)), "--write"], self.env, f"{name} server")
        self.children.append(server)
        server.wait_for("Ready|running", timeout=30)
        standing = ["--harness", "off", "--station", "yard"] if walking else []
        hal = Proc([PYTHON, "-m", "walkman.hal.server", "--clock", "/clock", "--rtf", rtf,
                    *standing], self.env, f"{name} hal")
        self.children.append(hal)
        hal.wait_for("simulated time on /clock", timeout=120)
        if walking:
            module = Proc([PYTHON, "-m", "walkman.gym.runner", "walking", "--lockstep",
                           "--start"], self.env, f"{name} walking")
            self.children.append(module)
            hal.wait_for("lockstep: /walking joined", timeout=120)

    def factor(self, seconds: float) -> float:
        """Simulated seconds per wall second over ``seconds``, as a /clock follower sees it
        (a process of its own, in this robot's YARP network)."""
        follower = Proc([PYTHON, "-c", FOLLOWER, str(seconds)], self.env, "follower")
        return float(follower.wait_for(r"^factor (\S+)$", timeout=seconds + 60).group(1))

    def close(self) -> None:
        for child in reversed(self.children):
            child.kill()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=10.0,
                        help="wall seconds each figure is measured over (default 10)")
    options = parser.parse_args()
    say_machine()
    figures: Dict[str, str] = {}
    for name, factor in in_process_factors(min(options.seconds, 5.0)).items():
        figures[f"{name} (in process, for scale)"] = f"{factor:.1f}x"
    for rtf in ("1", "max"):
        robot = Robot("alone", rtf)
        try:
            figures[f"walkman-hal --rtf {rtf}, alone"] = f"{robot.factor(options.seconds):.2f}x"
        finally:
            robot.close()
    measure_side_by_side(figures, "walkman-hal --rtf max, two side by side",
                         [Robot("first", "max"), Robot("second", "max")], options.seconds)
    robot = Robot("lockstep", "max", walking=True)
    try:
        figures["HAL --rtf max + walking --lockstep, alone"] = \
            f"{robot.factor(options.seconds):.2f}x"
    finally:
        robot.close()
    measure_side_by_side(figures, "HAL + walking in lockstep, two side by side",
                         [Robot("first", "max", walking=True),
                          Robot("second", "max", walking=True)], options.seconds)
    print()
    print("real-time factor: simulated seconds per wall second (drc scene, 1 ms steps)")
    for label, value in figures.items():
        print(f"  {label:<48}{value:>16}")
    say_machine("after")
    return 0


def measure_side_by_side(figures: Dict[str, str], label: str, robots: List[Robot],
                         seconds: float) -> None:
    try:
        import threading

        results: Dict[int, float] = {}
        threads = [threading.Thread(target=lambda i=i, r=r: results.__setitem__(
            i, r.factor(seconds))) for i, r in enumerate(robots)]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join()
        figures[label] = " and ".join(f"{results[i]:.2f}x" for i in sorted(results))
    finally:
        for robot in robots:
            robot.close()


if __name__ == "__main__":
    sys.exit(main())
