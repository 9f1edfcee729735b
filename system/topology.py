"""The robot and pilot PCs, their name servers and programs, in either topology.

Theory of operation
-------------------
A :class:`Pc` is a private environment -- its own ``YARP_CONFIG_HOME``, a
``yarp-lite server`` and a ``roscore`` on its own ports, its own state folder --
optionally inside an emulated host (a network namespace of
:class:`~netem.emulation.EmulatedLink`).  A :class:`Topology` places the
components on PCs:

``lab``  one PC, one name-server pair, every program connects directly: the
         paper's lab setting;
``drc``  a robot PC and a pilot PC, each with its pair, and ``walkman-bridge``
         on both: the DRC setting.

The name servers start first; every other component can then start in any
order, with delays, because each one waits for what it needs (that is the
property :meth:`Topology.start_all` exercises).  :func:`observe` (run inside a
PC, ``python -m system.topology observe``) lists what a process on that PC can
see: YARP ports and their connections, ROS topics with their publishers and
subscribers -- normalized so two runs can be compared.
"""

from __future__ import annotations

import argparse
import json
import os
import random
import re
import shlex
import subprocess
import sys
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Dict, List, Optional, Sequence, Tuple

from system.processes import REPO, ROSCORE_READY, Proc, WaitTimeout
from yarp_lite.freeport import free_port, release
from walkman import MODELS_DIR
from walkman.gym.lockstep import ENVIRONMENT as LOCKSTEP_ENVIRONMENT

PYTHON = sys.executable
#: The line ``yarp-lite server`` prints once it answers.
YARP_SERVER_READY = r"Ready"
BRIDGE_CONFIG = MODELS_DIR / "bridge_drc.xml"
GENERATED = REPO / "build" / "ros" / "lib"


@dataclass(frozen=True)
class Component:
    name: str
    pc: str                  # "robot" or "pilot" (the same PC in the lab topology)
    argv: Tuple[str, ...]
    ready: str               # a line the program prints once it is up
    topologies: Tuple[str, ...] = ("lab", "drc")

    def command(self, bag: Path) -> List[str]:
        """The command line, with ``{bag}`` (the session recording's path) filled in."""
        return [arg.replace("{bag}", str(bag)) for arg in self.argv]


#: The paper's task modules (its bridge XML): on the robot PC for a pilot who does every DRC
#: task in one session (the scripts and the main job's interactive mode start them; the
#: tests that do not pilot a task leave them out: six more processes to start).
TASK_MODULES = ("drc_valve", "drc_drive", "drc_door", "drc_wall", "drc_plug", "walking")


def hal_component(*arguments: str) -> Component:
    """The simulated robot's HAL on the robot PC (``arguments``: e.g. ``--station wall``)."""
    return Component("hal", "robot", (PYTHON, "-m", "walkman.hal.server", "--backend", "sim",
                                      *arguments), r"HAL for walkman")


def task_component(name: str) -> Component:
    """A task module (``walkman.gym.supervisor NAME``) on the robot PC."""
    return Component(name, "robot", (PYTHON, "-m", "walkman.gym.supervisor", name),
                     r"ready for the pilot")


def task_components() -> List[Component]:
    return [task_component(name) for name in TASK_MODULES]


#: What the robot PC's programs get on simulated time: every GYM module joins the HAL's clock.
SIM_TIME_ENV = {LOCKSTEP_ENVIRONMENT: "1"}
#: The robot's time on the robot PC's roscore (``sim_time``): the HAL's /clock as ROS's.
ROS_CLOCK = Component("ros_clock", "robot", (PYTHON, "-m", "rosnodes.ros_clock"),
                      r"on ROS's /clock", ("drc",))


def components(kind: str, perception_rate: float = 1.0, tasks: bool = False,
               sim_time: bool = False) -> List[Component]:
    """Every program of a topology besides the name servers (the task modules too if
    ``tasks``; with ``sim_time`` the robot's clock, :class:`Topology`)."""
    module = (PYTHON, "-m", "walkman.gym.supervisor")
    table = [
        hal_component(*(("--clock",) if sim_time else ())),
        *((ROS_CLOCK,) if sim_time else ()),
        Component("gaze_control", "robot", (*module, "gaze_control"), r"ready for the pilot"),
        Component("temperature", "robot", (*module, "temperature"), r"ready for the pilot"),
        # The head camera as a GYM module (the paper's section 3.1: the perception pilot
        # pauses it, changes its rate and picture), streaming from launch.  A 40x30 cloud
        # (every 8th pixel, its .ini) and a 320x240 image per frame: about 0.3 Mbit/s at
        # 1 Hz, inside the bridge's 0.6 Mbit/s UDP budget (the link is < 1 Mbit/s).
        Component("perception", "robot", (*module, "perception", "--start",
                                          "--set", "rate", f"{perception_rate:g}"),
                  r"ready for the pilot"),
        Component("joint_state", "robot", (PYTHON, "-m", "rosnodes.joint_state"),
                  r"joint state: reading"),
        Component("bridge_robot", "robot", (), r"side ready", ("drc",)),
        Component("bridge_pilot", "pilot", (), r"side ready", ("drc",)),
        Component("gateway", "pilot", (PYTHON, "-m", "rosnodes.gateway", "--link", "direct"),
                  r"ROS topics and services up", ("lab",)),
        Component("gateway", "pilot", (PYTHON, "-m", "rosnodes.gateway", "--link", "bridge"),
                  r"ROS topics and services up", ("drc",)),
        Component("joint_state_pilot", "pilot", (PYTHON, "-m", "rosnodes.joint_state",
                                                 "--no-battery"),   # the bridge brings it
                  r"joint state: reading", ("drc",)),
        # The session's log: every topic of the pilot's roscore (commands sent, statuses,
        # warnings, countdowns, robot state, perception), replayable with `rosbag play`.
        Component("rosbag", "pilot", ("stdbuf", "-oL",  # its log lines as they come
                                      "rosbag", "record", "--all", "--exclude",
                                      "/rosout(_agg)?", "--lz4", "--output-name", "{bag}"),
                  r"Recording to|Subscribing to"),
    ]
    return [c for c in table + (task_components() if tasks else []) if kind in c.topologies]


def bridge_argv(side: str, config: Path, peer: str, tcp_port: int, udp_port: int,
                peer_udp_port: int, key: Path, udp_rate: str = "600k",
                link_rate: Optional[str] = None) -> List[str]:
    """``walkman-bridge`` for one side: 0.6 Mbit/s of perception leaves room on a 1 Mbit/s
    link; ``link_rate``: what the link carries (the bridge's budget for the radio's queue)."""
    return [PYTHON, "-m", "bridge.main", "--side", side, "--config", str(config),
            "--peer", peer, "--port", str(tcp_port), "--udp-port", str(udp_port),
            "--peer-udp-port", str(peer_udp_port), "--udp-rate", udp_rate,
            *(("--link-rate", link_rate) if link_rate else ()),
            "--link-timeout", "5", "--key", str(key)]


def add_link_arguments(parser: argparse.ArgumentParser, default_profile: str = "drc",
                       loopback_note: str = "") -> None:
    """``--profile``, ``--loss``, ``--loopback``: the link between the emulated PCs, one
    spelling for every tool that builds a topology (main job, compare, chaos)."""
    parser.add_argument("--profile", default=default_profile, choices=["lab", "drc", "degraded"],
                        help=f"link profile between the emulated PCs (default {default_profile}; "
                             f"drc: 1 Mbit/s, 5 %% loss; degraded: 9600 bit/s)")
    parser.add_argument("--loss", type=float, help="override the profile's loss (percent)")
    parser.add_argument("--loopback", action="store_true",
                        help="both PCs on loopback even when root" + loopback_note)


def udp_budget(profile: str) -> str:
    """The bridges' UDP pacing for a link profile: 60 % of the link, leaving room for TCP;
    15 % of a link slower than 100 kbit/s.

    Perception paced at 600 kbit/s into a 9600 bit/s radio starved the TCP channel (a
    reconnect's handshake timed out after a blackout; found by walkman-chaos --soak).  At
    60 % of 9600 bit/s it still overflowed the radio: the TCP channel's frames every 0.5 s
    with their TCP/IP headers and acknowledgements take most of the rest, so every status
    and the stop-all's acknowledgement waited 2-3.5 s behind perception in the radio's
    queue (bench/bench_valve_topologies.py: the valve task took 2.1x the lab's time; 1.2x
    at 15 %, as without perception).
    """
    bits = link_rate(profile)
    if bits is None:
        return "600k"      # lab: the link is fast; pace to what a DRC radio would carry
    return f"{float(bits) * (0.6 if float(bits) >= 100_000 else 0.15):.0f}"


def link_rate(profile: str) -> Optional[str]:
    """What a profile's link carries, bit/s, as the bridges' ``--link-rate`` (None: lab)."""
    from netem.emulation import PROFILES
    from bridge.main import parse_rate

    rate = PROFILES.get(profile, {}).get("rate")
    return None if rate is None else f"{parse_rate(rate.replace('bit', '')):.0f}"


def ensure_bridge_key(path: Path) -> bool:
    """Create the bridges' shared key file if there is none; True when it was created.

    Two launchers starting at once on one machine both call this: the file is
    created exclusively, so the second one finds the first one's key.
    """
    from bridge.errors import BridgeUsageError
    from bridge.wire.link import generate_key_file

    try:
        generate_key_file(path)
    except BridgeUsageError:
        return False
    return True



def ros_environment(root: Path, ros_port: int) -> Dict[str, str]:
    """What a process needs to be a ROS node of the roscore on ``ros_port`` (its files under
    ``root``) that knows our messages -- ``rostopic echo /M/command`` included."""
    return {
        "ROS_MASTER_URI": f"http://127.0.0.1:{ros_port}", "ROS_IP": "127.0.0.1",
        "ROS_HOME": str(root / "ros"), "ROS_LOG_DIR": str(root / "ros" / "log"),
        "PYTHONPATH": os.pathsep.join(p for p in (str(GENERATED), str(REPO),
                                                  os.environ.get("PYTHONPATH", "")) if p),
        "ROS_PACKAGE_PATH": os.pathsep.join([str(REPO / "rosnodes"),
                                             str(REPO / "build" / "ros" / "share"),
                                             "/usr/share"]),
    }

@dataclass
class Pc:
    """One computer: its environment, name servers and programs."""

    name: str
    root: Path
    wrap: Sequence[str] = ()
    address: str = "127.0.0.1"
    # the server hands out the numbers after its own to every port registered: room for 400
    yarp_port: int = field(default_factory=lambda: free_port(span=400))
    ros_port: int = field(default_factory=free_port)
    processes: Dict[str, Proc] = field(default_factory=dict)
    log_dir: Optional[Path] = None   # when set, each program's output also goes to a file
    #: set in every program's environment last (a run's marker, a module's log file...)
    extra_env: Dict[str, str] = field(default_factory=dict)

    @property
    def env(self) -> Dict[str, str]:
        env = dict(os.environ)
        for key in ("YARP_NAMESPACE", "YARP_PORT_PREFIX", "ROS_HOSTNAME"):
            env.pop(key, None)
        env.update({
            "YARP_CONFIG_HOME": str(self.root / "yarp"), "YARP_DATA_HOME": str(self.root / "data"),
            "XDG_STATE_HOME": str(self.root / "state"), "MUJOCO_GL": "osmesa",
            "PYTHONUNBUFFERED": "1", **ros_environment(self.root, self.ros_port),
        })
        env.update(self.extra_env)
        return env

    #: What a shell needs to act as a program of this PC (see :meth:`write_env_file`).
    SHELL_KEYS = ("YARP_CONFIG_HOME", "YARP_DATA_HOME", "ROS_MASTER_URI", "ROS_IP", "ROS_HOME",
                  "ROS_LOG_DIR", "PYTHONPATH", "ROS_PACKAGE_PATH")

    def write_env_file(self) -> Path:
        """A file to ``source`` in a shell so its yarp/ros tools use this PC's name servers."""
        env = self.env
        lines = [f"# {self.name} PC: source me, then use rostopic, rosservice, yarp-lite ..."]
        lines += [f"export {key}={shlex.quote(env[key])}" for key in self.SHELL_KEYS]
        lines.append(f"export PATH={shlex.quote(str(REPO / '.venv' / 'bin'))}:\"$PATH\"")
        path = self.root / f"{self.name}.env"
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text("\n".join(lines) + "\n")
        return path

    def start(self, name: str, argv: Sequence[str], stdin: bool = False) -> Proc:
        log = self.log_dir / f"{name}.log" if self.log_dir else None
        proc = Proc([*self.wrap, *argv], self.env, f"{self.name}:{name}", stdin=stdin, log=log)
        self.processes[name] = proc
        return proc

    def run(self, argv: Sequence[str], timeout: float = 30.0) -> Proc:
        """Run a tool to completion (raises :class:`WaitTimeout` if it hangs)."""
        proc = Proc([*self.wrap, *argv], self.env, f"{self.name}:{argv[0]}")
        try:
            proc.wait(timeout)
        except subprocess.TimeoutExpired:
            proc.kill()
            raise WaitTimeout(f"{' '.join(argv)} did not finish in {timeout} s:\n"
                              + proc.output())
        return proc

    def use_sim_time(self) -> None:
        """``/use_sim_time`` on this PC's roscore, before any node starts (a node reads it
        once, at its start): its nodes follow ``/clock``."""
        setting = self.run(["rosparam", "set", "/use_sim_time", "true"])
        if setting.wait(1) != 0:
            raise WaitTimeout(f"rosparam set /use_sim_time failed:\n{setting.output()}")

    def start_name_servers(self) -> None:
        server = self.start_yarp_server()
        roscore = self.start_roscore()
        server.wait_for(YARP_SERVER_READY, 30)
        roscore.wait_for(ROSCORE_READY, 60)

    def start_yarp_server(self) -> Proc:
        """Start this PC's ``yarp-lite server`` without waiting; it is usable once it prints
        :data:`YARP_SERVER_READY`."""
        (self.root / "yarp").mkdir(parents=True, exist_ok=True)
        return self.start("yarp-server", [PYTHON, "-m", "yarp_lite", "server", "--socket",
                                          str(self.yarp_port), "--ip", "127.0.0.1", "--write"])

    def start_roscore(self) -> Proc:
        """Start this PC's ``roscore`` without waiting; it is usable once it prints
        :data:`ROSCORE_READY`."""
        return self.start("roscore", ["roscore", "-p", str(self.ros_port)])

    def kill(self, name: str) -> None:
        proc = self.processes.pop(name, None)
        if proc is not None:
            proc.kill()

    def close(self) -> None:
        for name in reversed(list(self.processes)):
            self.processes[name].kill()
        self.processes.clear()
        release(self.yarp_port)


class Topology:
    """The PCs of ``lab`` or ``drc`` and the programs on them."""

    def __init__(self, kind: str, root: Path, link=None, profile: str = "lab",
                 loss: Optional[float] = None, perception_rate: float = 1.0,
                 bridge_config: Path = BRIDGE_CONFIG, extra: Sequence[Component] = (),
                 extra_env: Optional[Dict[str, str]] = None, tasks: bool = False,
                 sim_time: bool = False) -> None:
        """``extra`` components join the table (a test's witness module); ``extra_env`` goes
        into every program's environment; ``tasks`` adds the paper's task modules.

        ``sim_time``: the robot on simulated time (docs/simulated-time.md).  The HAL serves
        its clock (``--clock``, at real time), every GYM module on the robot PC joins it in
        lockstep (``WALKMAN_LOCKSTEP``), and the robot PC's roscore carries it on ``/clock``
        with ``/use_sim_time`` set before any node starts, so its nodes and bags show robot
        time.  The pilot PC, the bridges and the link stay on the wall clock: they are
        physical.  Only ``drc``: the lab's one roscore is the pilot's too, whose countdowns
        must stay on the wall clock."""
        if kind not in ("lab", "drc"):
            raise ValueError(f"topology must be lab or drc, not {kind!r}")
        if sim_time and kind != "drc":
            raise ValueError("simulated time needs the drc topology: the lab's one roscore "
                             "is the pilot's too, whose countdowns stay on the wall clock")
        self.sim_time = sim_time
        self.kind = kind
        self.root = root
        self.link = link
        self.profile, self.loss = profile, loss
        self.bridge_config = bridge_config
        self.table = {c.name: c for c in [*components(kind, perception_rate, tasks, sim_time),
                                          *extra]
                      if kind in c.topologies}
        hal = self.table.get("hal")
        if sim_time and hal is not None and "--clock" not in hal.argv:   # a test's own HAL
            self.table["hal"] = replace(hal, argv=(*hal.argv, "--clock"))
        env = dict(extra_env or {})
        if kind == "lab":
            lab = Pc("lab", root / "lab", link.exec_argv("robot", []) if link else (),
                     extra_env=env)
            self.pcs = {"robot": lab, "pilot": lab}
        else:
            robot_env = {**env, **SIM_TIME_ENV} if sim_time else env
            self.pcs = {side: Pc(side, root / side, link.exec_argv(side, []) if link else (),
                                 link.address(side) if link else "127.0.0.1",
                                 extra_env=robot_env if side == "robot" else env)
                        for side in ("robot", "pilot")}
        self.tcp_port = free_port()
        self.udp_ports = {"robot": free_port(), "pilot": free_port()}
        self.bridge_key = root / "bridge.key"   # both emulated PCs share this machine's disk
        if kind == "drc":
            ensure_bridge_key(self.bridge_key)

    @property
    def robot(self) -> Pc:
        return self.pcs["robot"]

    @property
    def pilot(self) -> Pc:
        return self.pcs["pilot"]

    def unique_pcs(self) -> List[Pc]:
        return list({id(pc): pc for pc in self.pcs.values()}.values())

    def start_name_servers(self) -> None:
        if self.link is not None:
            self.link.apply(self.profile, loss=self.loss)
        for pc in self.unique_pcs():
            pc.start_name_servers()
        if self.sim_time:
            self.robot.use_sim_time()

    def _argv(self, component: Component) -> List[str]:
        if component.name.startswith("bridge_"):
            side = component.pc
            other = "pilot" if side == "robot" else "robot"
            return bridge_argv(side, self.bridge_config, self.pcs[other].address,
                               self.tcp_port, self.udp_ports[side], self.udp_ports[other],
                               self.bridge_key, udp_budget(self.profile),
                               link_rate(self.profile))
        if component.name == "gateway":  # the modules the bridges carry, from the same file
            return [*component.command(self.bag_path), "--config", str(self.bridge_config)]
        return component.command(self.bag_path)

    @property
    def bag_path(self) -> Path:
        return self.pilot.root / "pilot.bag"

    def command_line(self, name: str) -> List[str]:
        """How this topology runs ``name`` (a second pilot PC runs a gateway so too)."""
        return self._argv(self.table[name])

    def start(self, name: str) -> Proc:
        return self.pcs[self.table[name].pc].start(name, self.command_line(name))

    def start_all(self, order: Optional[Sequence[str]] = None, delay: float = 0.0,
                  rng: Optional[random.Random] = None) -> List[str]:
        """Start every component (in ``order``, or shuffled by ``rng``), ``delay`` s apart."""
        names = list(order) if order is not None else list(self.table)
        if order is None and rng is not None:
            rng.shuffle(names)
        for index, name in enumerate(names):
            if index and delay:
                time.sleep(delay * (rng.random() if rng else 1.0))
            self.start(name)
        return names

    def wait_ready(self, timeout: float = 120.0) -> None:
        deadline = time.monotonic() + timeout
        for name, component in self.table.items():
            proc = self.pcs[component.pc].processes[name]
            proc.wait_for(component.ready, max(1.0, deadline - time.monotonic()))

    def process(self, name: str) -> Proc:
        return self.pcs[self.table[name].pc].processes[name]

    def observe(self, pc: Pc) -> dict:
        proc = pc.run([PYTHON, "-m", "system.topology", "observe"], timeout=60)
        lines = [line for line in proc.lines if line.startswith("{")]
        if not lines:
            raise WaitTimeout(f"observe on {pc.name} printed nothing:\n{proc.output()}")
        return json.loads(lines[-1])

    def close(self) -> None:
        recorder = self.pilot.processes.get("rosbag")
        if recorder is not None:
            recorder.interrupt()  # Ctrl-C: rosbag closes the bag properly
        for pc in self.unique_pcs():
            pc.close()


# -- what a process can see -----------------------------------------------------------------

_VOLATILE = [(re.compile(r"/pilot_gateway/\d+"), "/pilot_gateway/N"),
             (re.compile(r"pilot_gateway_[\w]+_\d+"), "pilot_gateway"),
             (re.compile(r"/rostopic_\d+_\d+"), "/rostopic"),
             (re.compile(r"/rosservice_\d+_\d+"), "/rosservice"),
             (re.compile(r"/observer\d*"), "/observer"),
             (re.compile(r"/record_\d+"), "/record"),
             (re.compile(r"/session_recorder_\d+_\d+"), "/session_recorder")]


def normalize(name: str) -> str:
    for pattern, replacement in _VOLATILE:
        name = pattern.sub(replacement, name)
    return name


def observe_here() -> dict:
    """YARP ports with their outputs, ROS topics with their ends, as seen from this PC."""
    from yarp_lite import network
    from yarp_lite.bottle import Vocab
    from yarp_lite.errors import YarpError
    from yarp_lite.nameclient import NameClient

    client = NameClient()
    ports: Dict[str, List[str]] = {}
    for line in client.text("list"):
        match = re.search(r"registration name (\S+) ip", line)
        if not match or match.group(1) in ("/root",) or match.group(1).startswith("fallback"):
            continue
        name = match.group(1)
        contact = client.query(name)
        outputs: List[str] = []
        if contact is not None:
            try:
                reply = network.request(contact, [Vocab("list"), Vocab("out")], admin=True,
                                        timeout=3)
                outputs = sorted(normalize(str(v)) for v in reply if isinstance(v, str))
            except YarpError:
                outputs = ["<no answer>"]
        ports[normalize(name)] = outputs
    topics: Dict[str, dict] = {}
    try:
        import rosgraph

        master = rosgraph.Master("/observer")
        publishers, subscribers, services = master.getSystemState()
        types = dict(master.getTopicTypes())
        for topic, nodes in publishers:
            entry = topics.setdefault(topic, {"type": types.get(topic, ""), "pub": [], "sub": []})
            entry["pub"] = sorted({normalize(n) for n in nodes})
        for topic, nodes in subscribers:
            entry = topics.setdefault(topic, {"type": types.get(topic, ""), "pub": [], "sub": []})
            entry["sub"] = sorted({normalize(n) for n in nodes})
        service_names = sorted(normalize(name) for name, _ in services)
    except Exception as exc:  # noqa: BLE001 -- report it, the caller compares
        topics = {"<error>": {"type": str(exc), "pub": [], "sub": []}}
        service_names = []
    return {"ports": ports, "topics": topics, "services": service_names}


def main(argv: Optional[List[str]] = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m system.topology")
    parser.add_argument("verb", choices=["observe"])
    parser.parse_args(argv)
    print(json.dumps(observe_here(), sort_keys=True), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
