#!/usr/bin/env python3
"""Ten pilot stations on one pilot PC: what each gateway costs and what the pilot feels.

    .venv/bin/python bench/bench_stations.py [--quick] [--stations 10] [--count 40]

The DRC had three pilot PCs, each a roscore and a gateway on the one pilot YARP
name server; labs run more.  The ``drc`` topology runs on loopback (HAL,
modules, both bridges, gateway 1 on the pilot roscore); then stations 2..N
start on this same machine, each its own roscore and gateway on the pilot's
YARP name server (as ``tests/system/test_pilot_gui.py``'s second pilot PC).
Everything real; the programs log wall-clock times (``WALKMAN_LOG_TIME``).

1. **Command to module**, one way: a rospy publisher (``bench_pilot.py
   --publisher``) sends ``look_at`` on a station's roscore at 4 Hz and
   gaze_control logs when it took each one.  With station 1 alone, then with
   all N up, from station 1 and from station N in interleaved rounds.
2. **What the stations cost**: each station's start (gateway started to its
   ready line, with the roscore already up), the CPU of every gateway and of
   the pilot bridge over 20 s with all N idle, their resident memory, and the
   ports on the pilot name server.
"""

from __future__ import annotations

import argparse
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Dict, List, Optional, Tuple

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bench_pilot import one_way, percentile, sent_at  # noqa: E402  (bench/ is the folder)
from host import cpu_seconds, say_machine  # noqa: E402
from nodekit.logs import LOG_TIME_ENV  # noqa: E402
from system.processes import ROSCORE_READY, Proc  # noqa: E402
from system.topology import PYTHON, Pc, Topology  # noqa: E402

PILOT_BENCH = ROOT / "bench" / "bench_pilot.py"


def say(text: str) -> None:
    print(text, flush=True)


def resident_mib(pid: int) -> float:
    with open(f"/proc/{pid}/status", encoding="ascii") as status:
        for line in status:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    return 0.0


def start_station(topology: Topology, number: int, root: Path) -> Tuple[Pc, float]:
    """Station ``number``: a roscore and a gateway on the pilot YARP name server; returns the
    PC and the seconds from the gateway's start to its ready line."""
    pc = Pc(f"station{number}", root / f"station{number}")
    (pc.root / "yarp").mkdir(parents=True)
    for conf in (topology.pilot.root / "yarp").glob("*.conf"):
        shutil.copy(conf, pc.root / "yarp" / conf.name)
    pc.extra_env.update(topology.pilot.extra_env)
    pc.start_roscore().wait_for(ROSCORE_READY, 60)
    began = time.monotonic()
    pc.start("gateway", topology.command_line("gateway")).wait_for(
        topology.table["gateway"].ready, 120)
    return pc, time.monotonic() - began


def latency(topology: Topology, pc: Pc, count: int, base: float) -> List[float]:
    """One-way ms of ``count`` look_at commands published on ``pc``'s roscore."""
    proc = pc.start(f"publisher_{base:g}", [PYTHON, str(PILOT_BENCH), "--publisher", str(count),
                                            "--base", f"{base:g}"])
    proc.wait_for(r"DONE", 60 + count)
    proc.kill()
    return one_way(sent_at(proc), topology)


def start_gaze(pc: Pc) -> None:
    reply = pc.run(["rosservice", "call", "/gaze_control/switch_and_wait", "start", "10"],
                   timeout=60).output()
    if "ok: True" not in reply:
        raise RuntimeError(f"gaze_control did not start: {reply}")


def cpu_shares(procs: Dict[str, Proc], seconds: float) -> Dict[str, float]:
    """% of one core of each process over ``seconds``."""
    before = {name: cpu_seconds(proc.popen.pid) for name, proc in procs.items()}
    began = time.monotonic()
    time.sleep(seconds)
    elapsed = time.monotonic() - began
    return {name: (cpu_seconds(proc.popen.pid) - before[name]) / elapsed * 100
            for name, proc in procs.items()}


def pilot_ports(topology: Topology) -> int:
    out = topology.pilot.run([PYTHON, "-m", "yarp_lite", "name", "list"], timeout=60).output()
    return sum(1 for line in out.splitlines() if line.startswith("registration name /"))


def row(label: str, values: List[float]) -> str:
    return (f"   {label:<40} {statistics.median(values):8.1f} {percentile(values, 0.99):8.1f}"
            f"   ({len(values)} commands)")


def run(options, root: Path) -> None:
    topology = Topology("drc", root / "drc", extra_env={LOG_TIME_ENV: "1"})
    stations: List[Pc] = []
    try:
        topology.start_name_servers()
        topology.start_all([name for name in topology.table if name != "rosbag"])
        topology.table.pop("rosbag", None)
        topology.wait_ready(180)
        start_gaze(topology.pilot)
        say(f"\n1. Command -> gaze_control took it, one way (ms)          median      p99")
        alone = latency(topology, topology.pilot, options.count, 1.0)
        say(row("station 1, the only station", alone))
        starts = []
        for number in range(2, options.stations + 1):
            pc, seconds = start_station(topology, number, root)
            stations.append(pc)
            starts.append(seconds)
            say(f"   (station {number} up: gateway ready in {seconds:.1f} s)")
        time.sleep(5)
        last = stations[-1] if stations else topology.pilot
        first_rounds: List[float] = []
        last_rounds: List[float] = []
        per_round = max(1, options.count // 4)
        for index in range(4):               # interleaved: station 1, station N, ...
            first_rounds += latency(topology, topology.pilot, per_round, 2.0 + index)
            last_rounds += latency(topology, last, per_round, 2.5 + index)
        say(row(f"station 1, {options.stations} stations up", first_rounds))
        say(row(f"station {options.stations}, {options.stations} stations up", last_rounds))

        gateways = {"station 1": topology.process("gateway")}
        gateways.update({pc.name.replace("station", "station "): pc.processes["gateway"]
                         for pc in stations})
        shares = cpu_shares({**gateways, "bridge_pilot": topology.process("bridge_pilot")},
                            options.seconds)
        gateway_cpu = [shares[name] for name in gateways]
        memory = [resident_mib(proc.popen.pid) for proc in gateways.values()]
        say(f"\n2. {options.stations} stations, idle, over {options.seconds:.0f} s")
        if starts:
            say(f"   station start (gateway to ready)        median {statistics.median(starts):.1f} s,"
                f" max {max(starts):.1f} s")
        say(f"   CPU per gateway (% of one core)         median {statistics.median(gateway_cpu):.1f},"
            f" max {max(gateway_cpu):.1f}, all {sum(gateway_cpu):.1f}")
        say(f"   CPU of the pilot bridge                 {shares['bridge_pilot']:.1f} %")
        say(f"   resident memory per gateway             median {statistics.median(memory):.0f}"
            f" MiB, all {sum(memory):.0f} MiB")
        say(f"   ports on the pilot name server          {pilot_ports(topology)}")
    finally:
        for pc in reversed(stations):
            pc.close()
        topology.close()


def main(argv: Optional[List[str]] = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="4 stations, fewer commands")
    parser.add_argument("--stations", type=int, default=10, help="pilot stations (2..15)")
    parser.add_argument("--count", type=int, default=40, help="commands per measurement")
    parser.add_argument("--seconds", type=float, default=20.0, help="CPU measured over (s)")
    options = parser.parse_args(argv)
    if options.quick:
        options.stations, options.count, options.seconds = 4, 12, 10.0
    if not 1 <= options.stations <= 15:
        parser.error("--stations must be 1..15 (the gateway's station numbers)")
    say_machine()
    with tempfile.TemporaryDirectory() as tmp:
        run(options, Path(tmp))
    say_machine("after")
    return 0


if __name__ == "__main__":
    sys.exit(main())
