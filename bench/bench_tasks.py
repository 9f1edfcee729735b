"""DRC task modules: completion time in simulated seconds, and the control tick's cost.

    .venv/bin/python bench/bench_tasks.py

Each task runs in the MuJoCo scene through walkman.gym.offline (the module's own
code, on simulated time, one process), step by step as a pilot sends it.  Per step:
the simulated seconds from the command to the status the pilot waits for.  Per
module: the wall time of one control tick (run(): command, trajectory, IK, move)
against the 2 ms budget of a 500 Hz loop, and the task's outcome in the scene.
"""

from __future__ import annotations

import argparse
import time
from typing import Callable, Dict, List, Tuple

import numpy as np

from walkman.gym.offline import OfflineModule, OfflineWorld
from walkman.hal.sim import SimBackend
from walkman.model.mjcf import PILOT_POSES, PLUG_SOCKETS, task_harness
from walkman.modules import drc_door, drc_drive, drc_plug, drc_valve, drc_wall, walking
from host import say_machine  # noqa: E402  (bench/ is the script's folder)

Step = Tuple[str, str]
#: Each manipulation task: its station, its module, and the module's own steps after the
#: scene's pose (``TASK_STEPS``); what to read in the scene at the end.
MANIPULATION = {"drc_valve": ("valve", drc_valve, "valve"), "drc_drive": ("car", drc_drive, "car"),
                "drc_door": ("door", drc_door, "door"), "drc_plug": ("plug", drc_plug, "plug"),
                "drc_wall": ("wall", drc_wall, "wall")}
OUTCOMES: Dict[str, Callable[[OfflineWorld], str]] = {
    "drc_valve": lambda world: f"valve turned {world.prop('valve'):.3f} rad for 1.571",
    "drc_drive": lambda world: f"steering at {world.prop('steering'):.3f} rad (net -0.5 asked)",
    "drc_door": lambda world: f"door open {np.degrees(world.prop('door')):.1f} deg (goal > 30)",
    "drc_plug": lambda world: f"plug {100 * plug_off_socket_b(world):.1f} cm from socket b's "
                              f"centre",
    "drc_wall": lambda world: f"drywall: {world.backend.plant.drywall.summary()}",
}
TASKS: Dict[str, Tuple[str, type, List[Step], Callable[[OfflineWorld], str]]] = {
    name: (station, module.Module, [(PILOT_POSES[pose], "ready"), *module.TASK_STEPS],
           OUTCOMES[name])
    for name, (station, module, pose) in MANIPULATION.items()}
TASKS.update({
    "walking": ("yard", walking.Module, [
        ("go_straight 1.0", "idle"), ("turn 0.8", "idle"), ("step_side 0.3", "idle"),
        ("go_straight -0.5", "idle")],
        lambda world: "base moved x %.3f y %.3f m, yaw %.3f rad from the start" % tuple(
            np.subtract(world.backend.plant.base_pose(), START[0])[[0, 1, 3]])),
})
START: List[Tuple[float, ...]] = []


def plug_off_socket_b(world: OfflineWorld) -> float:
    """How far (m) the plug's centre stands from socket b's, across the table."""
    plant = world.backend.plant
    adr = plant.m.joint("plug").qposadr[0]
    return float(np.hypot(*np.subtract(plant.d.qpos[adr:adr + 2], PLUG_SOCKETS["b"])))


def timed_ticks(module: OfflineModule) -> List[float]:
    """Wrap the module's run() to record its wall time per call."""
    costs: List[float] = []
    run = module.thread.run

    def timed() -> None:
        start = time.perf_counter()
        run()
        costs.append(time.perf_counter() - start)
    module.thread.run = timed
    return costs


def main() -> int:
    argparse.ArgumentParser(description=__doc__.split("\n\n")[0]).parse_args()
    say_machine()
    print(f"{'task':10s} {'step':54s} {'sim s':>7s}")
    summary = []
    for name, (station, module_class, steps, outcome) in TASKS.items():
        harness = "off" if name == "walking" else task_harness(station)
        world = OfflineWorld(SimBackend(station=station, harness=harness))
        START[:] = [world.backend.plant.base_pose()]
        module = world.add(module_class, name)
        costs = timed_ticks(module)
        module.switch("start")
        world.step(walking.CROUCH_TIME + 0.1 if name == "walking" else 0.05)
        wall, total = time.perf_counter(), 0.0
        for command, state in steps:
            if name == "walking":  # idle before and after: wait for it to start walking
                began = world.time
                module.command(command)
                world.run_until(lambda: module.state != "idle", 2, command)
                world.run_until(lambda: module.state == state, 60, command)
                seconds = world.time - began
            else:
                seconds = module.do(command, state, timeout=60)
            total += seconds
            print(f"{name:10s} {command:54s} {seconds:7.2f}")
        wall = time.perf_counter() - wall
        ms = np.array(costs) * 1e3
        summary.append((name, total, wall, float(np.median(ms)), float(np.percentile(ms, 99)),
                        float(ms.max()), outcome(world)))
    print()
    print(f"{'task':10s} {'sim s':>7s} {'wall s':>7s} {'tick median ms':>15s} "
          f"{'p99 ms':>7s} {'max ms':>7s}  outcome")
    for name, total, wall, median, p99, worst, result in summary:
        print(f"{name:10s} {total:7.2f} {wall:7.2f} {median:15.3f} {p99:7.3f} {worst:7.3f}  "
              f"{result}")
    print("budget: 2 ms per tick at 500 Hz (the modules run at 100 Hz: 10 ms)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
