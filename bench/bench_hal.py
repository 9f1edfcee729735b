#!/usr/bin/env python3
"""The HAL as a YARP robot, against a real one: rpc round trips and streaming CPU.

* ``[get] [encs]`` round trip from a C++ client (real YARP 3.5, ``cpp/yarp_bench.cpp``)
  to ``/walkman/head/rpc:i`` (the HAL, sim backend) and to ``/fake/head/rpc:i``
  (``yarpdev --device controlboardwrapper2 --subdevice fakeMotionControl``),
  interleaved A, B, A, B... in one run; median of the rounds' medians, and p99.
  (A C++ ``remote_controlboard``'s ``getEncoders`` reads its last ``stateExt:o``
  locally and makes no round trip; ``[get] [encs]`` is what ``yarp rpc`` and any
  client asking the board directly pay.)
* ``state:o`` of all 8 chains streamed at 1 kHz (``period_ms 1``), each read by a C++
  sink over tcp and over udp: the HAL process's CPU (% of one core) per backend,
  beside the same HAL with no reader.

Usage: ``.venv/bin/python bench/bench_hal.py [--quick]``.  Needs the reference
build with its devices (``launch_scripts/build_reference_yarp.sh``).
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Dict, List

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

from walkman.hal.config import load_config  # noqa: E402
from yarp_lite import reference  # noqa: E402
from yarp_lite.freeport import free_port  # noqa: E402
from host import say_machine  # noqa: E402  (bench/ is the script's folder)

PYTHON = sys.executable
#: How the readers connect: tcp (an acknowledgement per message, ``yarp read``'s
#: default) and udp (``remote_controlboard``'s default for its state ports).
CARRIERS = ("tcp", "udp")
TICKS = os.sysconf("SC_CLK_TCK")


class Bench:
    def __init__(self, quick: bool) -> None:
        self.quick = quick
        self.rounds = 3 if quick else 7
        self.count = 1000 if quick else 3000
        self.cpu_seconds = 5.0 if quick else 15.0
        self.prefix = reference.prefix()
        if reference.devices() is None:
            raise SystemExit(reference.DEVICES_MISSING)
        self.cpp = reference.compile_cpp(HERE / "cpp" / "yarp_bench.cpp", "yarp_bench")
        self.tmp = Path(tempfile.mkdtemp(prefix="walkman-hal-bench-"))
        self.env = dict(os.environ, YARP_CONFIG_HOME=str(self.tmp / "config"),
                        YARP_DATA_HOME=str(self.tmp / "data"),
                        YARP_DATA_DIRS=str(reference.devices()), PYTHONUNBUFFERED="1")
        self.children: List[subprocess.Popen] = []

    def spawn(self, argv: List, ready: str = "") -> subprocess.Popen:
        """Start a child whose output goes to a log file (a pipe nobody reads would fill
        and stall it); wait until the log shows ``ready``."""
        log = self.tmp / f"child{len(self.children)}.log"
        # stdbuf: YARP's programs print through stdio, fully buffered otherwise.
        with open(log, "w") as out:
            child = subprocess.Popen(["stdbuf", "-oL", "-eL", *map(str, argv)], env=self.env,
                                     stdout=out, stderr=subprocess.STDOUT, text=True)
        self.children.append(child)
        deadline = time.time() + 90
        while ready and ready not in log.read_text(errors="replace"):
            if child.poll() is not None or time.time() > deadline:
                raise RuntimeError(f"{argv[:3]} did not print {ready!r}:\n{log.read_text()}")
            time.sleep(0.1)
        return child

    def stop(self, child: subprocess.Popen) -> None:
        child.terminate()
        try:
            child.wait(timeout=10)
        except subprocess.TimeoutExpired:
            child.kill()
            child.wait()
        self.children.remove(child)

    def close(self) -> None:
        for child in list(self.children):
            self.stop(child)

    def tool(self, *args: str) -> str:
        return subprocess.run([str(self.prefix / "bin" / "yarp"), *args], env=self.env,
                              capture_output=True, text=True, timeout=30).stdout

    def start(self) -> None:
        self.spawn([self.prefix / "bin" / "yarpserver", "--socket", free_port(span=400),
                    "--write"], ready="Ready")

    def hal(self, backend: str, config: Path = None) -> subprocess.Popen:
        argv = [PYTHON, "-m", "walkman.hal.server", "--backend", backend, "--scene", "robot"]
        if config is not None:
            argv += ["--config", config]
        return self.spawn(argv, ready="HAL for walkman")

    # -- rpc round trips ---------------------------------------------------------------

    def rpc(self, target: str) -> Dict[str, float]:
        out = subprocess.run([str(self.cpp), "rpc-client", target, str(self.count),
                              "[get] [encs]"], env=self.env, capture_output=True, text=True,
                             timeout=300).stdout
        words = next(line for line in out.splitlines() if line.startswith("rpc ")).split()
        return {"median": float(words[1]), "p99": float(words[2])}

    def rpc_interleaved(self) -> Dict[str, Dict[str, float]]:
        hal = self.hal("sim")
        fake = self.spawn([self.prefix / "bin" / "yarpdev", "--device", "controlboardwrapper2",
                           "--subdevice", "fakeMotionControl", "--name", "/fake/head",
                           "--GENERAL::Joints", "2"], ready="device active in background")
        rounds: Dict[str, List[Dict[str, float]]] = {"hal": [], "yarp": []}
        for index in range(self.rounds):
            for key, target in (("hal", "/walkman/head/rpc:i"), ("yarp", "/fake/head/rpc:i")):
                rounds[key].append(self.rpc(target))
            print(f"  rpc round {index + 1}/{self.rounds}: HAL {rounds['hal'][-1]['median']:.0f} us,"
                  f" real wrapper {rounds['yarp'][-1]['median']:.0f} us", flush=True)
        self.stop(hal)
        self.stop(fake)
        return {key: {"median": statistics.median(r["median"] for r in runs),
                      "p99": statistics.median(r["p99"] for r in runs)}
                for key, runs in rounds.items()}

    # -- streaming CPU -----------------------------------------------------------------

    def cpu_percent(self, pid: int) -> float:
        def ticks() -> int:
            fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
            return int(fields[11]) + int(fields[12])  # utime + stime
        start, begin = ticks(), time.monotonic()
        time.sleep(self.cpu_seconds)
        return 100.0 * (ticks() - start) / TICKS / (time.monotonic() - begin)

    def streaming_cpu(self, backend: str) -> Dict[str, float]:
        chains = load_config(None).chains
        config = self.tmp / "hal_1khz.ini"
        config.write_text("robot walkman\nperiod_ms 1\n[chains]\n" + "".join(
            f"{name} {' '.join(joints)}\n" for name, joints in chains.items()))
        hal = self.hal(backend, config)
        time.sleep(2.0)
        figures = {"idle": self.cpu_percent(hal.pid)}
        for carrier in CARRIERS:
            sinks = []
            for chain in chains:
                sink = f"/bench/sink/{carrier}/{chain}"
                sinks.append(self.spawn([self.cpp, "sink", sink, 10 ** 9], ready="ready"))
                self.tool("connect", f"/walkman/{chain}/state:o", sink, carrier)
            time.sleep(2.0)
            figures[carrier] = self.cpu_percent(hal.pid)
            for sink in sinks:
                self.stop(sink)
            time.sleep(1.0)
        self.stop(hal)
        return figures


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="fewer rounds (a smoke run)")
    options = parser.parse_args()
    say_machine()
    bench = Bench(options.quick)
    try:
        bench.start()
        rpc = bench.rpc_interleaved()
        cpu = {backend: bench.streaming_cpu(backend) for backend in ("sim", "ethercat")}
    finally:
        bench.close()
    ratio = rpc["hal"]["median"] / rpc["yarp"]["median"]
    print()
    print(f"[get] [encs] round trip from a C++ client, {bench.rounds} interleaved rounds of "
          f"{bench.count} (median of medians, us)")
    print(f"  {'':<34}{'median':>10}{'p99':>10}")
    print(f"  {'HAL /walkman/head (sim)':<34}{rpc['hal']['median']:>10.1f}"
          f"{rpc['hal']['p99']:>10.1f}")
    print(f"  {'controlboardwrapper2+fakeMotionControl':<34}{rpc['yarp']['median']:>10.1f}"
          f"{rpc['yarp']['p99']:>10.1f}")
    print(f"  ratio HAL / real YARP: {ratio:.2f} (goal <= 1.0)")
    print()
    print(f"HAL process CPU, % of one core over {bench.cpu_seconds:g} s, state:o of 8 chains "
          f"at 1 kHz to 8 C++ readers (8000 messages/s)")
    print(f"  {'backend':<12}{'no reader':>12}" + "".join(f"{c + ' readers':>14}"
                                                          for c in CARRIERS))
    for backend, figures in cpu.items():
        print(f"  {backend:<12}{figures['idle']:>11.0f}%" +
              "".join(f"{figures[c]:>13.0f}%" for c in CARRIERS))
    say_machine("after")
    return 0


if __name__ == "__main__":
    sys.exit(main())
