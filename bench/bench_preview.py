"""The pilot PC's preview of a dangerous command: how long it takes, how near it lands.

    .venv/bin/python bench/bench_preview.py [--repeat N]

Each DRC manipulation task runs in the MuJoCo scene (walkman.gym.offline) step by step,
as in bench_tasks.py; a shadow of its module (walkman.gym.preview, as the PI keeps it)
follows every command at the posture it was sent at.  Before each dangerous command
(valve turn, door open, drive accelerate, plug insert, wall push_in and cut) the
preview is worked out ``--repeat`` times: its wall time against issue 32's budget of
50 ms from the click, and, once the command has run on the simulated robot, the
distance between the previewed and the real end of the hand's grip point.  A refused
preview is timed too (the valve's three-quarter turn, whose path leaves the arm's reach).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from bench_tasks import TASKS
from host import say_machine  # noqa: E402  (bench/ is the script's folder)
from walkman.control.kinematics import Kinematics
from walkman.gym.offline import OfflineWorld
from walkman.gym.preview import Shadow
from walkman.hal.sim import SimBackend
from walkman.modules.task import GRIP

BUDGET_MS = 50.0


def grip(kinematics: Kinematics, q) -> np.ndarray:
    return kinematics.point(q, "l_hand", GRIP)


def timed(shadow: Shadow, command: str, state: str, posture, repeat: int):
    times, preview = [], None
    for _ in range(repeat):
        preview = shadow.preview(command, state, posture)
        times.append(preview.seconds * 1e3)
    return preview, np.array(times)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeat", type=int, default=20)
    options = parser.parse_args()
    say_machine()
    kinematics = Kinematics()
    print(f"{'task':10s} {'command':16s} {'median ms':>10s} {'p99 ms':>8s} {'max ms':>8s} "
          f"{'preview to real end':>20s}")
    for name, (station, module_class, steps, _) in TASKS.items():
        if name == "walking":
            continue
        world = OfflineWorld(SimBackend(station=station))
        module = world.add(module_class, name)
        module.switch("start")
        world.step(0.05)
        shadow = Shadow(module_class, name)
        for command, state in steps:
            before, posture = module.thread.fsm.state, world.backend.positions()
            preview = None
            if command.split()[0] in module_class.dangerous:
                preview, times = timed(shadow, command, before, posture, options.repeat)
            module.do(command, state, timeout=60)
            shadow.follow(command, before, posture)
            if preview is None:
                continue
            miss = "refused: " + preview.refusal if preview.refused else \
                f"{100 * np.linalg.norm(grip(kinematics, preview.posture) - grip(kinematics, world.backend.positions())):.1f} cm"
            print(f"{name:10s} {command:16s} {np.median(times):10.2f} "
                  f"{np.percentile(times, 99):8.2f} {times.max():8.2f} {miss:>20s}")
            if name == "drc_valve" and command.startswith("turn"):
                refused, times = timed(shadow, "turn 4.7", state, world.backend.positions(),
                                       options.repeat)
                print(f"{name:10s} {'turn 4.7':16s} {np.median(times):10.2f} "
                      f"{np.percentile(times, 99):8.2f} {times.max():8.2f} "
                      f"{'refused' if refused.refused else 'NOT refused':>20s}")
    print(f"budget: {BUDGET_MS:.0f} ms from the click to the ghost (issue 32)")
    return 0


if __name__ == "__main__":
    started = time.perf_counter()
    code = main()
    print(f"({time.perf_counter() - started:.0f} s)")
    raise SystemExit(code)
