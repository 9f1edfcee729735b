"""Walking without the harness: speed, accuracy, balance, pushes, and the control tick's cost.

    .venv/bin/python bench/bench_walking.py            # everything (about 5 minutes)
    .venv/bin/python bench/bench_walking.py --quick    # the walks only
    .venv/bin/python bench/bench_walking.py --rough --contact soft firm   # the courses, both

The walking module runs offline (walkman.gym.offline: its own code on simulated time,
MuJoCo at 1 kHz, the harness off).  Per command, from a fresh robot standing: the speed
(distance over the time from the command to ``idle``), the distance error, the most the
torso tilted, the smallest margin of the measured ZMP to the edge of the feet, and the
wall time of one control tick against the 2 ms budget of a 500 Hz loop.  Then the largest
push (N*s on the torso, over 0.1 s) survived standing, in 5 N*s steps, each way; and
sideways in mid-walk.  Survived: upright (tilt < 0.1 rad, pelvis not sunk) 4 s after.
The rough-ground courses (walkman/courses.py): up a 5-cm step, along it and down
(station ``terrain``); onto a 10-degree ramp, up it and onto its top (station ``ramp``), and
back down from the top (station ``ramp_top``), at once and, as through the PI, standing 15 s
before each pair of footsteps is measured: each command's time and smallest ZMP margin,
each course's speed; then the step, the ramp and the debris field (boards lying across the
way, stepped over) on footsteps the head camera places, look by look.  ``--contact`` runs
the courses on each of the simulator's contact models (walkman.hal.sim.CONTACT_MODELS:
``soft``, MuJoCo's defaults, where a loaded sole creeps down a slope, and ``firm``), side
by side.
"""

from __future__ import annotations

import argparse
import functools
import math
import sys
import tempfile
import time
from pathlib import Path
from typing import List, Optional, Tuple

import numpy as np

# this checkout's walkman first, over any the venv installed
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from bench_tasks import timed_ticks  # noqa: E402  (bench/ is the script's folder)
from host import say_machine  # noqa: E402
from walkman.control.ground_ahead import GroundError  # noqa: E402
from walkman.courses import (DEBRIS_FIELD_END, camera_course, ramp_course,  # noqa: E402
                             ramp_down_course, terrain_course, tilt, upright, walker)
from walkman.gym.offline import OfflineModule, OfflineWorld
from walkman.hal.sim import CONTACT_MODELS, SimBackend
from walkman.model.mjcf import TERRAIN_RAMP, TERRAIN_STEP
from walkman.modules import walking

COMMANDS = [("go_straight 1.0", 0, 1.0), ("go_straight -0.5", 0, -0.5), ("turn 0.8", 3, 0.8),
            ("turn -1.5", 3, -1.5), ("step_side 0.3", 1, 0.3), ("step_side -0.3", 1, -0.3)]


def standing(station: str = "yard") -> Tuple[OfflineWorld, OfflineModule, List[float]]:
    world = OfflineWorld(SimBackend(station=station, harness="off"))
    world.step(0.5)
    module = world.add(walking.Module, "walking")
    costs = timed_ticks(module)
    module.switch("start")
    world.step(walking.CROUCH_TIME + 0.5)
    return world, module, costs


def walk(command: str, axis: int, amount: float) -> Tuple[str, List[float]]:
    world, module, costs = standing()
    costs.clear()
    before = np.array(world.backend.plant.base_pose())
    began = world.time
    module.command(command)
    most_tilted, margins, fell = 0.0, [], False
    world.step(0.1)
    while module.state != "idle" and world.time - began < 60:
        world.step(0.01)
        most_tilted = max(most_tilted, tilt(world.backend))
        if module.thread.margin is not None:
            margins.append(module.thread.margin)
        fell = fell or not upright(world.backend)
    seconds = world.time - began
    moved = np.array(world.backend.plant.base_pose()) - before
    unit = "rad" if axis == 3 else "m"
    error = moved[axis] - amount
    drift = "" if axis == 3 else f" (drift {moved[1 - axis]:+.3f} m)"   # across the walk
    row = (f"{command:18s} {abs(moved[axis]) / seconds:6.3f} {unit}/s {error:+7.3f} {unit}"
           f"{drift:18s} {math.degrees(most_tilted):6.2f} "
           f"{min(margins) * 100 if margins else math.nan:7.1f}"
           f"  {'FELL' if fell else 'ok'}")
    return row, costs


def by_camera(goal: float):
    """A course on the camera's footsteps to world x ``goal``, as the tests walk it."""
    def course(world, module):
        with tempfile.TemporaryDirectory() as folder:
            legs, plans = camera_course(world, module, goal, Path(folder))
        return [(f"look {number}: {len(plan)} steps", margin, seconds)
                for number, ((_, margin, seconds), plan) in enumerate(zip(legs, plans), 1)]
    return course


_, RAMP_FOOT, RAMP_LENGTH, RAMP_SLOPE = TERRAIN_RAMP
COURSES = (("terrain", "terrain", terrain_course), ("ramp", "ramp", ramp_course),
           ("ramp down", "ramp_top", ramp_down_course),
           # as the PI walks it: the robot stands while the pilot drags each pair of footsteps
           ("ramp down, 15 s to place", "ramp_top",
            functools.partial(ramp_down_course, standing=15.0)),
           ("terrain by camera", "terrain", by_camera(TERRAIN_STEP[1] + 0.40)),
           ("ramp by camera", "ramp",
            by_camera(RAMP_FOOT + RAMP_LENGTH * math.cos(RAMP_SLOPE) + 0.30)),
           ("debris field by camera", "debris_field", by_camera(DEBRIS_FIELD_END + 0.40)))


def rough_ground(contact: str = "soft") -> List[str]:
    """The rough-ground courses (walkman/courses.py): the 5-cm step of station
    ``terrain`` and the 10-degree ramp of station ``ramp``, up and (``ramp_top``) down, by
    commands, then the step, the ramp and the debris field by the camera's footsteps: per
    command its time and smallest ZMP margin, then each course's speed and balance trips."""
    rows = []
    for label, station, course in COURSES:
        world, module = walker(station, contact)
        start = np.array(world.backend.plant.base_pose()[:2])
        try:
            legs = course(world, module)
        except AssertionError as exc:      # the base not upright: fell
            rows.append(f"{label} course ({contact}): FELL ({str(exc)[:120]})")
            continue
        except GroundError as exc:         # the camera's footsteps refused, before a step
            rows.append(f"{label} course ({contact}): REFUSED ({exc})")
            continue
        for command, margin, seconds in legs:
            rows.append(f"  {command[:18]:18s} {seconds:5.1f} s  smallest ZMP margin "
                        f"{margin * 100:4.1f} cm")
        distance = float(np.linalg.norm(np.array(world.backend.plant.base_pose()[:2]) - start))
        seconds = sum(leg[2] for leg in legs)
        trips = sum("balance:" in warning for warning in module.warnings)
        rows.append(f"{label} course ({contact}): {distance:.2f} m in {seconds:.1f} s "
                    f"({distance / seconds:.3f} m/s), smallest ZMP margin "
                    f"{min(leg[1] for leg in legs) * 100:.1f} cm, {trips} balance trip(s), "
                    f"{'standing' if upright(world.backend) else 'FALLEN'} at the end")
    return rows


def survives(impulse: Tuple[float, float, float], while_walking: bool) -> bool:
    world, module, _ = standing()
    if while_walking:
        module.command("go_straight 1.0")
        world.step(1.5)      # in the first step's single support (1.0 to 1.8 s)
    world.backend.push(impulse)
    for _ in range(40):
        world.step(0.1)
        if not upright(world.backend):
            return False
    return True


def largest_push(direction: Tuple[float, float, float], while_walking: bool = False,
                 limit: float = 150.0) -> Optional[float]:
    """The largest impulse survived along ``direction`` in 5 N*s steps (None: not even 5)."""
    best = None
    impulse = 5.0
    while impulse <= limit:
        if not survives(tuple(impulse * d for d in direction), while_walking):
            break
        best = impulse
        impulse += 5.0
    return best


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="the walks only, no pushes")
    parser.add_argument("--rough", action="store_true",
                        help="the rough-ground courses only (no walks, no pushes)")
    parser.add_argument("--contact", nargs="+", choices=sorted(CONTACT_MODELS),
                        default=["soft"], metavar="MODEL",
                        help="the contact model(s) to run the courses on: "
                             f"{', '.join(CONTACT_MODELS)} (default: soft)")
    options = parser.parse_args()
    say_machine()
    if options.rough:
        for contact in options.contact:
            for row in rough_ground(contact):
                print(row, flush=True)
        say_machine("after")
        return 0
    print(f"{'command':18s} {'speed':>10s} {'error':>11s} {'':18s} {'tilt °':>6s} "
          f"{'ZMP margin cm':>7s}")
    ticks: List[float] = []
    for command, axis, amount in COMMANDS:
        row, costs = walk(command, axis, amount)
        ticks += costs
        print(row, flush=True)
    ms = np.array(ticks) * 1e3
    print(f"control tick: median {np.median(ms):.2f} ms, p99 {np.percentile(ms, 99):.2f} ms, "
          f"max {ms.max():.2f} ms (budget 2 ms at 500 Hz; the module runs at 100 Hz)")
    for contact in options.contact:
        for row in rough_ground(contact):
            print(row, flush=True)
    if not options.quick:
        started = time.perf_counter()
        for label, direction, moving in (("standing, sideways", (0.0, 1.0, 0.0), False),
                                         ("standing, forwards", (1.0, 0.0, 0.0), False),
                                         ("standing, backwards", (-1.0, 0.0, 0.0), False),
                                         ("walking, sideways", (0.0, 1.0, 0.0), True)):
            best = largest_push(direction, moving)
            print(f"largest push survived {label:20s} "
                  f"{'< 5' if best is None else f'{best:.0f}'} N*s", flush=True)
        print(f"(pushes: {time.perf_counter() - started:.0f} s wall)")
    say_machine("after")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
