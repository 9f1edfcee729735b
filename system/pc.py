"""``walkman-pc robot|pilot|lab``: bring up one PC of the system, as on the robot or the desk.

Theory of operation
-------------------
The same component table as :mod:`system.topology`, for one real computer:
first its name servers (``yarp-lite server`` and ``roscore`` on this PC's
ports), then every program of that PC, each waiting for what it needs, so
they may start in any order (``--shuffle`` proves it).  The robot and pilot
PCs are linked only by ``walkman-bridge``; give each the other's address with
``--peer``.  ``lab`` is the paper's lab setting: one PC, one name-server pair,
everything connected directly.

The launcher stays in the foreground, says when each program is up, reports a
program that exits (with its last lines) and stops everything on Ctrl-C.
Logs go to ``--dir`` (one file per program).
"""

from __future__ import annotations

import argparse
import os
import random
import re
import signal
import sys
import time
from pathlib import Path
from typing import Callable, Dict, List, Optional

from system.processes import Proc
from system.topology import (BRIDGE_CONFIG, SIM_TIME_ENV, Pc, bridge_argv, components,
                             ensure_bridge_key)

DEFAULT_DIR = Path.home() / ".local" / "state" / "walkman"
DEFAULT_KEY = Path(os.environ.get("XDG_CONFIG_HOME") or Path.home() / ".config") / "walkman" \
    / "bridge.key"


def say(text: str) -> None:
    print(f"[walkman-pc] {text}", flush=True)


def serve(programs: Dict[str, Proc], ready: Dict[str, str], when_up: Callable[[], None],
          report: Callable[[str], None] = say) -> int:
    """Watch running programs until Ctrl-C/SIGTERM (exit 0) or until one exits (exit 1).

    Says when each program is up (its ``ready`` line), calls ``when_up`` once all
    are, and shows the last lines of a program that exits.
    """
    stop: List[str] = []  # why we stop: a signal, or a program that exited
    for sig in (signal.SIGINT, signal.SIGTERM):  # handled even where a shell ignores SIGINT
        signal.signal(sig, lambda number, _: stop.append(signal.Signals(number).name))
    marks = {name: re.compile(ready[name]) for name in programs}
    up: set = set()
    while not stop:
        for name, proc in programs.items():
            if name not in up and any(marks[name].search(line) for line in proc.lines):
                up.add(name)
                report(f"{name} is up ({len(up)}/{len(programs)})")
                if len(up) == len(programs):
                    when_up()
            if proc.popen.poll() is not None:
                report(f"{name} exited ({proc.popen.returncode}); its last lines:\n    " +
                       "\n    ".join(proc.lines[-10:]))
                stop.append(f"{name} exited")
        time.sleep(0.5)
    report(f"stopping ({stop[0]})")
    return 0 if stop[0] in ("SIGINT", "SIGTERM") else 1


def kind_of(side: str) -> str:
    return "lab" if side == "lab" else "drc"


def plan(side: str, options: argparse.Namespace) -> Dict[str, List[str]]:
    """The programs of this PC and their command lines."""
    out = {}
    bag = options.dir / f"{side}-{time.strftime('%Y%m%d-%H%M%S')}.bag"
    for component in components(kind_of(side), tasks=not options.no_tasks,
                                sim_time=options.sim_time):
        if side != "lab" and component.pc != side:
            continue
        if component.name in options.skip:
            continue
        if component.name.startswith("bridge_"):
            argv = bridge_argv(side, options.config, options.peer, options.bridge_port,
                               options.udp_port, options.peer_udp_port or options.udp_port,
                               options.key, options.udp_rate, options.link_rate)
        else:
            argv = component.command(bag)
        out[component.name] = argv
    if side in ("pilot", "lab") and not options.no_gui and os.environ.get("DISPLAY"):
        # The Pilot Interface, where a pilot can see it; --no-gui (or no display): rostopic.
        out["pilot_interface"] = [sys.executable, "-m", "pilot.app", "--layout", options.layout,
                                  "--config", str(options.config)]
    return out


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="walkman-pc", description=__doc__.split("\n")[0])
    parser.add_argument("side", choices=["robot", "pilot", "lab"])
    parser.add_argument("--peer", help="the other PC's address (robot and pilot sides)")
    parser.add_argument("--yarp-port", type=int, default=10000,
                        help="this PC's yarp-lite server port (default 10000, as yarpserver)")
    parser.add_argument("--ros-port", type=int, default=11311,
                        help="this PC's roscore port (default 11311)")
    parser.add_argument("--bridge-port", type=int, default=7000,
                        help="the bridge's TCP port (the same on both PCs; default 7000)")
    parser.add_argument("--udp-port", type=int, default=7001,
                        help="this bridge's UDP port (default 7001)")
    parser.add_argument("--peer-udp-port", type=int, help="the peer's UDP port (default: ours)")
    parser.add_argument("--udp-rate", default="600k",
                        help="perception budget on the link, bit/s (default 600k)")
    parser.add_argument("--link-rate", help="what the link to the other PC carries, bit/s "
                        "(e.g. 9600 or 1M): the bridge keeps the radio's queue short, so a "
                        "stop-all never waits behind telemetry; default: no budget")
    parser.add_argument("--config", type=Path, default=BRIDGE_CONFIG,
                        help="bridge configuration (same file on both PCs)")
    parser.add_argument("--key", type=Path, default=DEFAULT_KEY,
                        help=f"the bridges' shared key file (same file on both PCs, mode 600; "
                             f"created if missing; default {DEFAULT_KEY})")
    parser.add_argument("--dir", type=Path, default=None,
                        help=f"logs, name-server state and rosbags (default {DEFAULT_DIR}/<side>)")
    parser.add_argument("--skip", default="", help="programs not to start (comma separated)")
    parser.add_argument("--no-tasks", action="store_true",
                        help="not the task modules (drc_valve ... walking) on the robot PC")
    parser.add_argument("--no-gui", action="store_true",
                        help="no Pilot Interface even when a display is present (pilot, lab)")
    parser.add_argument("--layout", default="main-pilot",
                        help="the Pilot Interface's layout (models/pilot_layouts.ini)")
    parser.add_argument("--sim-time", action="store_true",
                        help="the robot on simulated time (robot PC): the HAL serves /clock at "
                             "real time, every module joins it in lockstep, and this PC's "
                             "roscore carries it (/clock, /use_sim_time); "
                             "docs/simulated-time.md")
    parser.add_argument("--shuffle", action="store_true",
                        help="start the programs in a random order, 0-2 s apart")
    return parser


def _options(argv: Optional[List[str]]) -> argparse.Namespace:
    """The command line, checked: each mistake named with its option."""
    parser = _parser()
    options = parser.parse_args(argv)
    options.skip = {name.strip() for name in options.skip.split(",") if name.strip()}
    if options.sim_time and options.side != "robot":
        parser.error("--sim-time is the robot PC's: the pilot's programs, countdowns and link "
                     "stay on the wall clock (and the lab's one roscore is the pilot's too)")
    if options.side != "lab" and not options.peer:
        parser.error(f"the {options.side} PC needs --peer (the other PC's address)")
    for name in ("yarp_port", "ros_port", "bridge_port", "udp_port"):
        if not 0 < getattr(options, name) < 65536:
            parser.error(f"--{name.replace('_', '-')} must be a port number (1-65535)")
    known = {c.name for c in components("lab", tasks=True) + components("drc", tasks=True)}
    unknown = options.skip - known
    if unknown:
        parser.error(f"--skip: unknown program(s) {', '.join(sorted(unknown))}; the programs "
                     f"are {', '.join(sorted(known))}")
    if not options.config.is_file():
        parser.error(f"--config: no such file {options.config}")
    options.dir = (options.dir or DEFAULT_DIR / options.side).resolve()
    if options.side != "lab":
        options.key = options.key.expanduser().resolve()
        if ensure_bridge_key(options.key):
            print(f"[{options.side}] created a new bridge key {options.key}: copy it to the "
                  f"other PC (scp -p {options.key} <other>:{options.key})", flush=True)
    return options


def main(argv: Optional[List[str]] = None) -> int:
    options = _options(argv)
    from nodekit.msgs import generate

    generate()
    pc = Pc(options.side, options.dir, yarp_port=options.yarp_port, ros_port=options.ros_port,
            log_dir=options.dir / "logs", extra_env=dict(SIM_TIME_ENV) if options.sim_time else {})
    programs = plan(options.side, options)
    names = list(programs)
    if options.shuffle:
        random.shuffle(names)
    try:
        say(f"{options.side} PC: name servers (yarp-lite :{options.yarp_port}, "
            f"roscore :{options.ros_port}), state in {options.dir}")
        pc.start_name_servers()
        if options.sim_time:
            pc.use_sim_time()
        for name in names:
            say(f"starting {name}: {' '.join(programs[name])}")
            pc.start(name, programs[name])
            if options.shuffle:
                time.sleep(random.uniform(0, 2))
        env_file = pc.write_env_file()
        ready = {c.name: c.ready for c in components(kind_of(options.side), tasks=True,
                                                     sim_time=options.sim_time)}
        ready["pilot_interface"] = r"window up"
        return serve({name: pc.processes[name] for name in names}, ready, lambda: say(
            f"all up. In another shell: source {env_file} (then rostopic, rosservice, "
            f"yarp-lite ...); Ctrl-C here stops this PC"))
    except KeyboardInterrupt:  # Ctrl-C while still starting up
        say("stopping (SIGINT)")
        return 0
    finally:
        recorder = pc.processes.get("rosbag")
        if recorder is not None:
            recorder.interrupt()
        pc.close()


if __name__ == "__main__":
    sys.exit(main())
