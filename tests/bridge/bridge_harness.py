"""Two PCs for the bridge tests: a robot and a pilot world, each with its name servers.

On loopback both worlds share the host (different ports); on an emulated
network (:class:`~netem.emulation.EmulatedLink`) each runs in its network
namespace and the bridges talk over the veth, through the link profile.
"""

from __future__ import annotations

import os
import re
import signal
import sys
from pathlib import Path
from typing import Dict, List, Optional, Sequence

from netem.emulation import EmulatedLink
from bridge.wire.link import generate_key_file
from system.processes import ROSCORE_READY
from system.topology import GENERATED
from harness import REPO, Implementation, Proc, YarpWorld, free_port, wait_until

PYTHON = sys.executable
HERE = Path(__file__).resolve().parent


class Side:
    def __init__(self, name: str, world: YarpWorld, peer: str, state_dir: Path,
                 ros_port: int) -> None:
        self.name = name
        self.world = world
        self.peer = peer
        self.state_dir = state_dir
        self.ros_port = ros_port
        self.bridge: Optional[Proc] = None
        self.roscore: Optional[Proc] = None

    @property
    def env(self) -> Dict[str, str]:
        env = self.world.env
        env.update({"ROS_MASTER_URI": f"http://127.0.0.1:{self.ros_port}",
                    "ROS_IP": "127.0.0.1", "ROS_HOME": str(self.world.root / "ros"),
                    "PYTHONPATH": os.pathsep.join([str(HERE), str(REPO), str(GENERATED),
                                                   os.environ.get("PYTHONPATH", "")]),
                    # rostopic and rosservice find our messages (walkman_msgs/Link...)
                    "ROS_PACKAGE_PATH": os.pathsep.join([str(REPO / "rosnodes"),
                                                         str(REPO / "build" / "ros" / "share"),
                                                         "/usr/share"])})
        env.pop("ROS_HOSTNAME", None)
        return env

    def start(self, argv: Sequence[str], name: str = "", stdin: bool = False) -> Proc:
        return self.world.start(list(argv), name or f"{self.name} {argv[-1]}", stdin=stdin,
                                env=self.env)

    def python(self, *args: str, name: str = "", stdin: bool = False) -> Proc:
        return self.start([PYTHON, *args], name or f"{self.name} {args[0]}", stdin=stdin)


class TwoPCs:
    """The robot and the pilot, their name servers, and the bridge between them."""

    def __init__(self, root: Path, server_impl: Implementation, config: Path,
                 link: Optional[EmulatedLink] = None) -> None:
        self.config = config
        self.link = link
        self.tcp_port = free_port()
        self.udp_ports = {"robot": free_port(), "pilot": free_port()}
        self.key = generate_key_file(root / "bridge.key")
        self.sides: Dict[str, Side] = {}
        for name, other in (("robot", "pilot"), ("pilot", "robot")):
            wrap = link.exec_argv(name, []) if link else ()
            world = YarpWorld(root / name, server_impl, wrap=wrap)
            peer = link.address(other) if link else "127.0.0.1"
            self.sides[name] = Side(name, world, peer, root / f"{name}-state", free_port())
        self.robot, self.pilot = self.sides["robot"], self.sides["pilot"]

    def start_name_servers(self) -> None:
        for side in self.sides.values():
            side.world.start_server()

    def start_roscore(self, side: Side) -> Proc:
        side.roscore = side.start(["roscore", "-p", str(side.ros_port)], f"{side.name} roscore")
        side.roscore.wait_for(ROSCORE_READY, 60)
        wait_until(lambda: self._ros_master_up(side), 30, message=f"{side.name} ROS master")
        return side.roscore

    def _ros_master_up(self, side: Side) -> bool:
        probe = side.start([PYTHON, "-c", "import rosgraph,sys; "
                            "sys.exit(0 if rosgraph.is_master_online() else 1)"],
                           f"{side.name} master probe")
        return probe.wait(20) == 0

    def bridge_argv(self, side: Side, *extra: str) -> List[str]:
        other = "pilot" if side.name == "robot" else "robot"
        return [PYTHON, "-m", "bridge.main", "--side", side.name, "--config", str(self.config),
                "--peer", side.peer, "--port", str(self.tcp_port),
                "--udp-port", str(self.udp_ports[side.name]),
                "--peer-udp-port", str(self.udp_ports[other]), "--state-dir",
                str(side.state_dir), "--link-timeout", "3", "--key", str(self.key), *extra]

    def start_bridge(self, side: Side, *extra: str, wait: bool = True) -> Proc:
        side.bridge = side.start(self.bridge_argv(side, *extra), f"{side.name} bridge")
        if wait:
            side.bridge.wait_for(r"side running", 30)
        return side.bridge

    def kill_bridge(self, side: Side) -> None:
        assert side.bridge is not None
        side.bridge.kill(signal.SIGKILL)
        side.bridge = None

    def wait_linked(self, timeout: float = 30.0) -> None:
        for side in self.sides.values():
            assert side.bridge is not None
            side.bridge.wait_for(r"TCP channel up", timeout)
            side.bridge.wait_for(r"side ready", timeout)

    def close(self) -> None:
        for side in self.sides.values():
            side.world.close()


def count_lines(path: Path, pattern: str) -> List[str]:
    if not path.exists():
        return []
    return [line for line in path.read_text().splitlines() if re.search(pattern, line)]
