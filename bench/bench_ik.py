"""IK cost per control tick against the 2 ms budget of a 500 Hz loop (issue: DRC task modules).

    .venv/bin/python bench/bench_ik.py [--ticks N]

Tracking: the hand follows a 10 cm circle at 500 Hz (the solver starts from the
previous tick's answer, as a module does).  Cold: reachable poses solved from
the home posture (what a module does once per new target).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from walkman.control.ik import InverseKinematics
from walkman.control.kinematics import Kinematics
from host import say_machine  # noqa: E402  (bench/ is the script's folder)

LEFT_ARM = ["LShSag", "LShLat", "LShYaw", "LElbj", "LForearmPlate", "LWrj1", "LWrj2"]


def percentiles(values):
    ms = np.array(values) * 1000
    return float(np.median(ms)), float(np.percentile(ms, 99))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--ticks", type=int, default=2000)
    options = parser.parse_args()
    say_machine()
    ik = InverseKinematics(Kinematics())
    home = np.clip(np.zeros(33), ik.lower, ik.upper)
    q = home.copy()
    q[ik.joints_of(LEFT_ARM)] = [0.3, 0.6, 0.0, -1.0, 0.0, 0.2, 0.0]
    center, rotation = ik.kinematics.pose(q, "l_hand")
    times, iterations, worst = [], [], 0.0
    for tick in range(options.ticks):
        angle = 2 * np.pi * tick / 500  # one turn per second
        target = center + 0.1 * np.array([0.0, np.cos(angle) - 1, np.sin(angle)])
        start = time.perf_counter()
        result = ik.solve("l_hand", target, rotation, q, LEFT_ARM)
        times.append(time.perf_counter() - start)
        iterations.append(result.iterations)
        worst = max(worst, result.position_error)
        q = result.q
    rng = np.random.default_rng(7)
    index = ik.joints_of(LEFT_ARM)
    cold, reached = [], 0
    for _ in range(100):
        sample = home.copy()
        sample[index] = ik.lower[index] + (ik.upper[index] - ik.lower[index]) * \
            rng.uniform(0.2, 0.8, len(index))
        position, orientation = ik.kinematics.pose(sample, "l_hand")
        start = time.perf_counter()
        result = ik.solve("l_hand", position, orientation, home, LEFT_ARM)
        cold.append(time.perf_counter() - start)
        reached += result.reached
    track = percentiles(times)
    first = percentiles(cold)
    print("Inverse kinematics, left hand, 7 arm joints, Pinocchio DLS (ms)    median      p99")
    print(f"  tracking at 500 Hz, {options.ticks} ticks                        "
          f"{track[0]:8.3f} {track[1]:8.3f}   (budget 2.0 per tick)")
    print(f"  iterations per tick (median / max)                        "
          f"{np.median(iterations):8.0f} {max(iterations):8d}")
    print(f"  worst position error while tracking (mm)                  {worst * 1000:8.3f}")
    print(f"  cold solve from home, 100 reachable poses                 "
          f"{first[0]:8.3f} {first[1]:8.3f}   reached {reached}/100")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
