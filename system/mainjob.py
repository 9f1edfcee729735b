"""The README's main job: the DRC topology with the simulated robot, piloted with the ROS tools.

Theory of operation
-------------------
By default this is :mod:`system.compare` with the DRC link: the scripted pilot
session (start ``gaze_control``, look at the valve, watch temperatures,
pause, resume, a dangerous command counted down and cancelled, stop) runs in
the ``drc`` topology -- robot PC and pilot PC, each with its yarp-lite server
and roscore, the bridge between them over the emulated link (1 Mbit/s, 5 %
loss) when run as root, over loopback otherwise -- and in the ``lab`` topology
for reference.  Progress is printed step by step; the job ends with the
comparison's summary and the path of the full report.

``--interactive`` brings up the ``drc`` topology only and keeps it up: it
writes an environment file for the pilot PC and prints the exact ``rostopic``
and ``rosservice`` lines to pilot the robot from another shell.
"""

from __future__ import annotations

import argparse
import shlex
import sys
import tempfile
from pathlib import Path
from typing import List, Optional

from system import compare
from system.pc import serve
from system.session import STEPS
from system.topology import REPO, TASK_MODULES, Topology, add_link_arguments
from walkman.model.mjcf import STATIONS


def say(text: str) -> None:
    print(f"[main-job] {text}", flush=True)


def interactive(options: argparse.Namespace) -> int:
    link = compare.open_link(options.loopback, say, prefix="wm", subnet=61)
    root = Path(tempfile.mkdtemp(prefix="walkman-pilot-"))
    topology = Topology("drc", root, link=link, profile=options.profile, loss=options.loss,
                        tasks=True)
    try:
        where = f"emulated hosts ({options.profile} link)" if link else "loopback"
        say(f"starting the robot PC and the pilot PC on {where}")
        for pc in topology.unique_pcs():
            pc.log_dir = pc.root / "logs"
        topology.start_name_servers()
        say(f"starting {', '.join(topology.table)}")
        topology.start_all()
        topology.wait_ready(240)
        env_file = topology.pilot.write_env_file()
        robot_env = topology.robot.write_env_file()
        enter = f"ip netns exec {link.namespace('pilot')} bash\n    " if link else ""
        enter_robot = f"ip netns exec {link.namespace('robot')} bash\n    " if link else ""
        print(f"""
The robot is up. Pilot it from another shell on this machine:

    {enter}cd {shlex.quote(str(REPO))} && source {shlex.quote(str(env_file))}
    rostopic echo /gaze_control/status        # in one shell
    rostopic echo /gaze_control/countdown     # dangerous commands count down here
""", flush=True)
        for step in STEPS:
            if step.argv[0] in ("rostopic", "rosservice"):
                print(f"    {shlex.join(step.argv):<100} # {step.label}")
        print(f"""
    rostopic hz /joint_states                 # robot state through the bridge
    rosrun rviz rviz  (if installed)          # /multisense/points, /tf
    yarp-lite name list                       # the pilot PC's YARP ports
    walkman-pilot --layout main-pilot         # the Pilot Interface (with a display)

Every DRC task's module runs on the robot PC ({", ".join(TASK_MODULES)}): start one from
the PI (or /M/switch), after taking the simulated robot to its station from the robot PC:

    {enter_robot}cd {shlex.quote(str(REPO))} && source {shlex.quote(str(robot_env))}
    echo "set station wall" | yarp-lite rpc /walkman/rpc:i    # {" ".join(STATIONS)}
    echo "set harness off" | yarp-lite rpc /walkman/rpc:i     # walking: on its own feet

Logs of every program: {root}/<pc>/logs/ ; Ctrl-C here stops everything.""", flush=True)
        programs = {name: topology.process(name) for name in topology.table}
        ready = {name: component.ready for name, component in topology.table.items()}
        quiet = lambda text: None if " is up (" in text else say(text)  # noqa: E731 (said above)
        return serve(programs, ready, lambda: None, report=quiet)
    except KeyboardInterrupt:  # Ctrl-C while still starting up
        say("stopping (SIGINT)")
        return 0
    finally:
        topology.close()
        if link is not None:
            link.down()


def main(argv: Optional[List[str]] = None) -> int:
    parser = argparse.ArgumentParser(prog="walkman-main-job", description=__doc__.split("\n")[0])
    parser.add_argument("--interactive", action="store_true",
                        help="keep the DRC topology up and print the lines to pilot it")
    add_link_arguments(parser, "drc")
    parser.add_argument("--out", type=Path, help="report folder (default out/compare-<time>)")
    options = parser.parse_args(argv)
    if options.loss is not None and not 0 <= options.loss <= 100:
        parser.error(f"--loss must be a percentage between 0 and 100, not {options.loss}")
    from nodekit.msgs import generate

    generate()
    if options.interactive:
        return interactive(options)
    say("the scripted pilot session, first in the lab topology (the reference), then in the "
        f"DRC topology ({options.profile} link)")
    args = ["--profile", options.profile]
    args += ["--loss", str(options.loss)] if options.loss is not None else []
    args += ["--loopback"] if options.loopback else []
    args += ["--out", str(options.out)] if options.out else []
    return compare.main(args)


if __name__ == "__main__":
    sys.exit(main())
