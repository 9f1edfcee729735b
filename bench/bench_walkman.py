#!/usr/bin/env python3
"""walkman core benchmark: physics real-time factor, GYM loop timing, sense->move latency.

* MuJoCo alone on the full DRC scene at 1 kHz, and each HAL backend's step;
* a GYM module at 500 Hz (sense, then move, every 2 ms) against the ``sim`` HAL
  running in real time, all on this machine: the loop's period error (median,
  p99) and the latency from the HAL publishing a state to receiving the
  command computed from it (median, p99).

Goals (issue): real-time factor >= 5, p99 period error <= 0.5 ms, sense->move <= 2 ms.
Usage: ``.venv/bin/python bench/bench_walkman.py [--seconds 20]``.
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

from yarp_lite.freeport import free_port  # noqa: E402
from host import say_machine  # noqa: E402  (bench/ is the script's folder)
from walkman import MODELS_DIR  # noqa: E402

HAL_ARGS: list = []


def physics() -> dict:
    import mujoco

    from walkman.hal.ethercat.master import EthercatBackend
    from walkman.hal.sim import SimBackend
    from walkman.model import SCENE_PATH

    model = mujoco.MjModel.from_xml_path(str(SCENE_PATH))
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    started = time.perf_counter()
    for _ in range(5000):
        mujoco.mj_step(model, data)
    results = {"mujoco_rtf": 5.0 / (time.perf_counter() - started)}
    for name, backend in (("sim_rtf", SimBackend()), ("ethercat_rtf", EthercatBackend())):
        started = time.perf_counter()
        for _ in range(3000):
            backend.step()
        results[name] = 3.0 / (time.perf_counter() - started)
    return results


def loop(seconds: float) -> dict:
    tmp = Path(tempfile.mkdtemp(prefix="walkman-bench-"))
    env = dict(os.environ, YARP_CONFIG_HOME=str(tmp / "c"), YARP_DATA_HOME=str(tmp / "d"),
               PYTHONPATH=f"{HERE.parent}:{HERE}")
    py = sys.executable
    children = []
    try:
        children.append(subprocess.Popen([py, "-m", "yarp_lite", "server", "--socket",
                                          str(free_port(60)), "--ip", "127.0.0.1", "--silent"],
                                         env=env, stderr=subprocess.DEVNULL))
        time.sleep(1.5)
        children.append(subprocess.Popen([py, "-m", "walkman.hal.server", "--backend", "sim",
                                          *HAL_ARGS],
                                         env=env, stderr=subprocess.DEVNULL))
        module = subprocess.Popen([py, "-m", "walkman.gym.runner", "loop_module:Module",
                                   "--period", "2", "--name", "/bench_loop"], env=env,
                                  stderr=subprocess.PIPE, text=True)
        children.append(module)
        time.sleep(6)
        subprocess.run([py, "-m", "yarp_lite", "write", "/bench/switch", "/bench_loop/switch:i"],
                       input="start\n", env=env, capture_output=True, text=True, timeout=30)
        time.sleep(seconds)
        stats_text = subprocess.run([py, "-m", "yarp_lite", "rpc", "/walkman/rpc:i"],
                                    input="[get] stats\n", env=env, capture_output=True,
                                    text=True, timeout=30).stdout
        module.terminate()
        _, err = module.communicate(timeout=30)
        match = re.search(r"period error median ([0-9.]+) ms, p99 ([0-9.]+) ms over (\d+) "
                          r"ticks(?: \((\d+) on the robot's states\); "
                          r"interval error p99 ([0-9.]+) ms)?", err)
        results = {}
        if match:
            results.update(period_median_ms=float(match.group(1)),
                           period_p99_ms=float(match.group(2)), ticks=int(match.group(3)),
                           locked=int(match.group(4) or 0),
                           interval_p99_ms=float(match.group(5) or "nan"))
        for key in ("sense_to_move_median_ms", "sense_to_move_p99_ms", "real_time_factor",
                    "overruns"):
            found = re.search(rf"\({key} ([0-9.]+)\)", stats_text)
            if found:
                results[key] = float(found.group(1))
        return results
    finally:
        for child in children:
            child.kill()
            child.wait()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=20.0)
    options = parser.parse_args()
    say_machine()
    print("walkman core benchmark", flush=True)
    phys = physics()
    print()
    print("Physics (simulated seconds per wall second)")
    print(f"  MuJoCo, full DRC scene, 1 kHz         {phys['mujoco_rtf']:8.1f}   (goal >= 5)")
    print(f"  sim backend step (servos, grasps)      {phys['sim_rtf']:8.1f}")
    print(f"  ethercat backend step (38 boards)      {phys['ethercat_rtf']:8.1f}")
    models = MODELS_DIR
    for title, config in (("8 chains, state every 2 ms (hal_chains.ini)", "hal_chains.ini"),
                          ("1 chain, state every 1 ms (hal_whole_body.ini)",
                           "hal_whole_body.ini")):
        HAL_ARGS[:] = ["--config", str(models / config)]
        timing = loop(options.seconds)
        nan = float("nan")
        print(f"GYM module at 500 Hz, sim HAL in real time, {title}, "
              f"{timing.get('ticks', 0)} ticks, {timing.get('locked', 0)} on the robot's states")
        print(f"  loop period error median / p99 (ms)    {timing.get('period_median_ms', nan):8.3f}"
              f" {timing.get('period_p99_ms', nan):8.3f}   (goal p99 <= 0.5)")
        print(f"  tick interval error p99 (ms)                    "
              f"{timing.get('interval_p99_ms', nan):8.3f}")
        print(f"  sense -> move median / p99 (ms)         "
              f"{timing.get('sense_to_move_median_ms', nan):8.3f}"
              f" {timing.get('sense_to_move_p99_ms', nan):8.3f}   (goal <= 2)")
        print(f"  HAL real-time factor, overruns          {timing.get('real_time_factor', nan):8.3f}"
              f" {timing.get('overruns', nan):8.0f}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
