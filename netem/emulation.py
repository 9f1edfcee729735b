"""Emulated robot and pilot PCs: network namespaces, a radio between them, bad-link profiles.

Theory of operation
-------------------
``up`` creates the namespaces ``<prefix>_robot`` and ``<prefix>_pilot``, each
with its own loopback (so each runs its own yarpserver and roscore on the
usual ports) and one cable to the radio, addressed 169.254.<subnet>.1 (robot)
and .2 (pilot): link-local, so nothing ever leaves.  The radio is a third
namespace, ``<prefix>_link``, where the two cables end, and a program there,
the link stage (:mod:`netem.radio_stage`, whose timing is the pure
:mod:`netem.radio_model`), moves every Ethernet frame from one cable to the
other::

    robot r0 ==veth== lr  [<prefix>_link: radio stage]  lp ==veth== p0 pilot

This kernel has no ``netem`` (``tc qdisc add ... netem`` fails), and a ``tc
tbf`` shaper lets a burst through at veth speed: a 100-byte command crossed a
"9600 bit/s" link in microseconds.  The stage serialises instead: a frame of N
bytes occupies the link N * 8 / rate seconds, frames queue behind each other
in a bounded buffer that drops the tail, then each takes the one-way delay;
loss and blackouts drop frames on the radio.  The cables' ends compute their
checksums in software (no transmit offload), so the frames the stage copies
are whole.  On ``lab`` (nothing to emulate) the stage steps aside and the two
cables are joined by a kernel bridge: a veth's gigabits and microseconds.

Profiles shape both directions alike:

==========  ================================================================
lab         no shaping
drc         1 Mbit/s, 50 ms one way, 5 % loss unless told otherwise
degraded    9600 bit/s, 50 ms one way; blackouts of 1-30 s when ``blackouts``
            runs
==========  ================================================================

Where the figures come from: the DRC Finals (2015; DARPA, "Communications
between Operator and Robot for the DRC Finals", DISTAR 23912) gave the operators
a 9600 bit/s link both ways, always on, beside a 300 Mbit/s robot-to-operator
link that came in 1 s bursts between blackouts of 1 to 30 s (``degraded`` is
the slow link; ``blackouts`` cuts the whole radio for as long).  The DRC Trials
(2013) alternated every minute between 1 Mbit/s with 100 ms latency and
100 kbit/s with 1000 ms (``drc`` is the good minute); we read the latency as
the round trip, hence 50 ms one way.  The Finals' documents give rates, not a delay: ``degraded``
keeps the Trials' 50 ms of the network between operators and robot.  At 9600
bit/s serialisation dominates anyway: 83 ms for a 100-byte frame, 1.26 s for a
full one.

``flap`` takes the cables down and up (``ip link``), which senders do see; a
blackout is the radio gone (the stage drops every frame, and loses those under
way), which they do not.  Everything needs root; :func:`available` says why not.

An intruder
-----------
``add_intruder`` puts a third host, ``<prefix>_rogue`` at 169.254.<subnet>.3,
on the same radio: an attacker on the DRC wireless.  A radio is a broadcast
medium, so the robot's end of the cable becomes a port of a Linux bridge
(``<prefix>b0``, in the robot's namespace) that learns no addresses and so
floods every frame to every port, like a hub::

    pilot p0 == [radio] == r0 -+- b0 -+- rb ==veth== ri  robot (.1)
                               |      +- x1 ==veth== x0  rogue (.3, promiscuous)

The robot's address moves from ``r0`` to ``ri`` (the bridge delivers frames
for an address on itself only locally, and the rogue would not hear them).
The robot and the pilot still talk over the radio, and the rogue hears exactly
what reached the robot (the pilot's frames after the loss) and what the robot
sent.  The rogue's own path to the robot is unshaped and lossless: an attacker
close to the robot, whose every attempt arrives (so a test can count them).
Add it before starting programs on the robot: its address moves.
"""

from __future__ import annotations

import argparse
import ctypes
import fcntl
import json
import os
import random
import re
import shutil
import signal
import socket
import struct
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Dict, List, Optional, Sequence

#: Each profile's rate (a tc-style string, as the tools that pace to it parse it), loss in
#: percent and one-way delay in seconds; the module's docstring says where they come from.
PROFILES: Dict[str, Dict[str, Any]] = {
    "lab": {"rate": None, "loss": 0.0, "delay": 0.0},
    "drc": {"rate": "1mbit", "loss": 5.0, "delay": 0.05},
    "degraded": {"rate": "9600bit", "loss": 0.0, "delay": 0.05},
}
SIDES = ("robot", "pilot")
#: The last byte of each host's address; "rogue" exists after :meth:`EmulatedLink.add_intruder`.
HOSTS = {"robot": 1, "pilot": 2, "rogue": 3}
DEVICES = {"robot": "r0", "pilot": "p0", "rogue": "x0"}
#: The radio's ends of the cables, in the link namespace, and the bridge that joins them on lab.
RADIO_ENDS = {"robot": "lr", "pilot": "lp"}
RADIO_BRIDGE = "lk"
#: Where the link stages' control sockets and logs are, one of each per prefix.
STAGE_DIR = Path("/run/walkman-netem")
STAGE_START_TIMEOUT = 20.0


class EmulationError(Exception):
    """A command building or shaping the emulated network failed; the text says which."""


def available() -> Optional[str]:
    """None when emulated networks can be built here, else the reason they cannot."""
    if os.geteuid() != 0:
        return "emulated networks need root (network namespaces, veth, AF_PACKET sockets)"
    for tool in ("ip", "sysctl"):
        if shutil.which(tool) is None:
            return f"emulated networks need the {tool!r} command"
    return None


def _run(argv: Sequence[str], check: bool = True) -> subprocess.CompletedProcess:
    result = subprocess.run(list(argv), capture_output=True, text=True)
    if check and result.returncode != 0:
        raise EmulationError(f"{' '.join(argv)}: {result.stderr.strip() or result.returncode}")
    return result


@dataclass
class EmulatedLink:
    """The two hosts, the radio between them and its link stage."""

    prefix: str = "wm"
    subnet: int = 10
    _stage: Optional[subprocess.Popen] = field(default=None, init=False, repr=False,
                                               compare=False)

    def __post_init__(self) -> None:
        if not self.prefix.isalnum() or len(self.prefix) > 8:
            raise EmulationError(f"prefix {self.prefix!r} must be up to 8 letters or digits")
        if not 0 <= self.subnet <= 255:
            raise EmulationError(f"subnet {self.subnet} must be 0..255")

    def namespace(self, side: str) -> str:
        """``side``: a host (robot, pilot, rogue) or ``link``, the radio's namespace."""
        return f"{self.prefix}_{side}"

    def device(self, side: str) -> str:
        """A host's interface on the radio (robot and pilot: their cables to it)."""
        return f"{self.prefix}{DEVICES[side]}"

    def radio_end(self, side: str) -> str:
        """The radio's end of ``side``'s cable, in the link namespace."""
        return f"{self.prefix}{RADIO_ENDS[side]}"

    def address(self, side: str) -> str:
        return f"169.254.{self.subnet}.{HOSTS[side]}"

    def exec_argv(self, side: str, argv: Sequence[str]) -> List[str]:
        return ["ip", "netns", "exec", self.namespace(side), *argv]

    def _ns(self, side: str, *argv: str, check: bool = True) -> subprocess.CompletedProcess:
        return _run(self.exec_argv(side, argv), check)

    @property
    def control_path(self) -> Path:
        """The link stage's control socket."""
        return STAGE_DIR / f"{self.prefix}.sock"

    @property
    def stage_log(self) -> Path:
        return STAGE_DIR / f"{self.prefix}.log"

    # -- building ----------------------------------------------------------------------

    def exists(self) -> bool:
        names = _run(["ip", "netns", "list"]).stdout.split()
        return all(self.namespace(side) in names for side in (*SIDES, "link"))

    def up(self) -> None:
        """Both hosts, their cables, the radio between them (lab: an ideal wire)."""
        reason = available()
        if reason:
            raise EmulationError(reason)
        self.down()
        for side in (*SIDES, "link"):
            self._add_namespace(side)
        self._ns("link", "ip", "link", "set", "lo", "up")
        bridge = f"{self.prefix}{RADIO_BRIDGE}"
        self._ns("link", "ip", "link", "add", bridge, "type", "bridge")
        self._ns("link", "ip", "link", "set", bridge, "up")
        for side in SIDES:
            device, end = self.device(side), self.radio_end(side)
            _run(["ip", "link", "add", device, "type", "veth", "peer", "name", end])
            _software_checksums(device)
            _run(["ip", "link", "set", end, "netns", self.namespace("link")])
            _run(["ip", "link", "set", device, "netns", self.namespace(side)])
            self._ns("link", "ip", "link", "set", end, "up")
            self._ns(side, "ip", "addr", "add", f"{self.address(side)}/24", "dev", device)
            self._ns(side, "ip", "link", "set", "lo", "up")
            self._ns(side, "ip", "link", "set", device, "up")
        self._start_stage(bridge)

    def _add_namespace(self, side: str) -> None:
        """A namespace whose interfaces speak IPv4 only, as the DRC's radios carried it:
        IPv6's own chatter (router solicitations, MLD reports: 70-90 bytes, 75 ms each of a
        9600 bit/s link) would share the radio with what is measured.  Loopback keeps ::1."""
        _run(["ip", "netns", "add", self.namespace(side)])
        self._ns(side, "sysctl", "-qw", "net.ipv6.conf.default.disable_ipv6=1")

    def _start_stage(self, bridge: str) -> None:
        """Start the link stage, detached (it outlives ``walkman-netem up``); return once it
        answers on its control socket."""
        STAGE_DIR.mkdir(mode=0o700, parents=True, exist_ok=True)
        root = str(Path(__file__).resolve().parents[1])  # netem/ is importable from here
        env = dict(os.environ, PYTHONPATH=os.pathsep.join(
            filter(None, [root, os.environ.get("PYTHONPATH")])))
        argv = self.exec_argv("link", [
            sys.executable, "-m", "netem.radio_stage", "--robot", self.radio_end("robot"),
            "--pilot", self.radio_end("pilot"), "--bridge", bridge,
            "--control", str(self.control_path)])
        with open(self.stage_log, "wb") as log:
            self._stage = subprocess.Popen(argv, stdin=subprocess.DEVNULL, stdout=log,
                                           stderr=subprocess.STDOUT, env=env, cwd="/",
                                           start_new_session=True)
        deadline = time.monotonic() + STAGE_START_TIMEOUT
        while True:
            try:
                self.status()
                return
            except EmulationError as exc:
                if self._stage.poll() is not None or time.monotonic() > deadline:
                    raise EmulationError(f"the link stage did not start ({exc}); its log, "
                                         f"{self.stage_log}:\n{self._stage_log_tail()}") \
                        from None
            time.sleep(0.05)

    def _stage_log_tail(self) -> str:
        try:
            return self.stage_log.read_text(errors="replace")[-2000:]
        except OSError:
            return "(no log)"

    def down(self) -> None:
        self._stop_stage()
        for host in (*HOSTS, "link"):
            _run(["ip", "netns", "del", self.namespace(host)], check=False)
        for path in (self.control_path, self.stage_log):
            try:
                path.unlink()
            except FileNotFoundError:
                pass  # never made or already removed: nothing to clean

    def _stop_stage(self) -> None:
        """End the processes in the link namespace (the stage; nothing else runs there)."""
        listed = _run(["ip", "netns", "pids", self.namespace("link")], check=False)
        pids = [int(word) for word in listed.stdout.split()] if listed.returncode == 0 else []
        for sig in (signal.SIGTERM, signal.SIGKILL):
            for pid in pids:
                try:
                    os.kill(pid, sig)
                except ProcessLookupError:
                    pass  # already exited: nothing to signal
            deadline = time.monotonic() + 5
            while any(self._alive(pid) for pid in pids) and time.monotonic() < deadline:
                time.sleep(0.02)
            pids = [pid for pid in pids if self._alive(pid)]
            if not pids:
                break
        self._stage = None

    def _alive(self, pid: int) -> bool:
        if self._stage is not None and self._stage.pid == pid:
            return self._stage.poll() is None  # our child: reap it
        try:
            with open(f"/proc/{pid}/stat") as stat:
                return stat.read().rsplit(")", 1)[1].split()[0] != "Z"
        except (OSError, IndexError):
            return False

    # -- the intruder --------------------------------------------------------------

    def has_intruder(self) -> bool:
        return self.namespace("rogue") in _run(["ip", "netns", "list"]).stdout.split()

    def add_intruder(self) -> None:
        """The rogue host on the robot/pilot radio (see the module's docstring)."""
        if not self.exists():
            raise EmulationError(f"no emulated link {self.prefix!r} to intrude on; "
                                 f"bring it up first")
        if self.has_intruder():
            raise EmulationError(f"link {self.prefix!r} already has an intruder")
        hub, cable = f"{self.prefix}b0", self.device("robot")
        inner, inner_port = f"{self.prefix}ri", f"{self.prefix}rb"
        rogue, rogue_port = self.device("rogue"), f"{self.prefix}x1"
        robot = f"{self.address('robot')}/24"
        self._add_namespace("rogue")
        self._ns("robot", "ip", "link", "add", hub, "type", "bridge")
        # The hub holds no address, but the namespace's kernel would answer the pilot's ARP
        # for the robot on it too (any local address, any interface), with the hub's MAC: the
        # pilot's frames would then stop at the hub, unheard by the rogue.
        self._ns("robot", "ip", "link", "set", hub, "arp", "off")
        self._ns("robot", "ip", "link", "add", inner, "type", "veth", "peer", "name",
                 inner_port)
        self._ns("robot", "ip", "link", "add", rogue_port, "type", "veth", "peer", "name",
                 rogue, "netns", self.namespace("rogue"))
        self._ns("robot", "ip", "addr", "del", robot, "dev", cable)
        for port in (cable, inner_port, rogue_port):
            self._ns("robot", "ip", "link", "set", port, "master", hub)
            # A switch would learn where each address is and stop showing the rogue the
            # others' unicast frames; a radio cannot.
            self._ns("robot", "ip", "link", "set", port, "type", "bridge_slave", "learning",
                     "off")
            self._ns("robot", "ip", "link", "set", port, "up")
        self._ns("robot", "ip", "addr", "add", robot, "dev", inner)
        for device in (inner, hub):
            self._ns("robot", "ip", "link", "set", device, "up")
        self._ns("pilot", "ip", "neigh", "flush", "dev", self.device("pilot"))
        self._ns("rogue", "ip", "addr", "add", f"{self.address('rogue')}/24", "dev", rogue)
        for device in ("lo", rogue):
            self._ns("rogue", "ip", "link", "set", device, "up")
        self._ns("rogue", "ip", "link", "set", rogue, "promisc", "on")

    def block_tcp(self, on: bool) -> None:
        """Drop every TCP segment the robot sends or receives on the radio (``on``), or let
        them through again: what crosses the link then goes by UDP alone."""
        table, device = f"{self.prefix}_no_tcp", self.device("robot")
        self._ns("robot", "nft", "delete", "table", "inet", table, check=False)
        if on:
            rules = (f"table inet {table} {{\n"
                     f"  chain out {{ type filter hook output priority 0; "
                     f"oifname \"{device}\" meta l4proto tcp counter drop; }}\n"
                     f"  chain in {{ type filter hook input priority 0; "
                     f"iifname \"{device}\" meta l4proto tcp counter drop; }}\n}}\n")
            result = subprocess.run(self.exec_argv("robot", ["nft", "-f", "-"]), input=rules,
                                    capture_output=True, text=True)
            if result.returncode != 0:
                raise EmulationError(f"blocking TCP on {device}: {result.stderr.strip()}")

    def tcp_dropped(self) -> int:
        """TCP segments :meth:`block_tcp` dropped so far, both ways (0: not blocking)."""
        listed = self._ns("robot", "nft", "list", "table", "inet", f"{self.prefix}_no_tcp",
                          check=False).stdout
        return sum(int(n) for n in re.findall(r"counter packets (\d+)", listed))

    # -- shaping -----------------------------------------------------------------------

    def _request(self, request: Dict[str, Any]) -> Dict[str, Any]:
        """One request to the link stage, its reply (see :mod:`netem.radio_stage`)."""
        try:
            with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as sock:
                sock.settimeout(10)
                sock.connect(str(self.control_path))
                sock.sendall(json.dumps(request).encode() + b"\n")
                line = sock.makefile("r").readline()
        except OSError as exc:
            log = (f"; its log:\n{self._stage_log_tail()}" if self.stage_log.exists()
                   else ": is the link up?")
            raise EmulationError(f"the link stage of {self.prefix!r} does not answer at "
                                 f"{self.control_path} ({exc}){log}") from None
        reply = json.loads(line) if line else {"error": "it closed without a reply"}
        if "error" in reply:
            raise EmulationError(f"the link stage of {self.prefix!r}: {reply['error']}")
        return reply

    def configure(self, **settings: Any) -> Dict[str, Any]:
        """Change the radio's settings (:class:`~netem.radio_model.RadioSettings` fields,
        both directions); returns the stage's status."""
        return self._request({"set": settings})

    def status(self) -> Dict[str, Any]:
        """The stage's settings, and per direction what it delivered and dropped."""
        return self._request({})

    def settings(self) -> Dict[str, Any]:
        return self.status()["settings"]

    def apply(self, profile: str, loss: Optional[float] = None,
              rate: Optional[str] = None, delay: Optional[float] = None) -> None:
        """A profile, optionally with its loss (percent), rate or delay (s) replaced; ends a
        blackout."""
        if profile not in PROFILES:
            raise EmulationError(f"unknown profile {profile!r} ({', '.join(PROFILES)})")
        settings = PROFILES[profile]
        rate = rate if rate is not None else settings["rate"]
        self.configure(rate=_bits(rate) if rate else None,
                       loss=_fraction(settings["loss"] if loss is None else loss),
                       delay=settings["delay"] if delay is None else delay,
                       queue_bytes=None, blackout=False)

    def set_rate(self, rate: Optional[str]) -> None:
        """``rate`` as tc spells it (1mbit, 9600bit); None: unlimited."""
        self.configure(rate=_bits(rate) if rate else None)

    def set_loss(self, percent: float) -> None:
        self.configure(loss=_fraction(percent))

    def blackout(self, on: bool) -> None:
        """The radio gone (every frame dropped, those under way too), or back with its
        settings as they were."""
        self.configure(blackout=on)

    def flap(self, down: bool) -> None:
        for side in SIDES:
            self._ns(side, "ip", "link", "set", self.device(side), "down" if down else "up")

    def tx_counters(self, side: str) -> tuple:
        """``(bytes, packets)`` sent by ``side`` on the cable, Ethernet headers included."""
        base = f"/sys/class/net/{self.device(side)}/statistics"
        output = self._ns(side, "cat", f"{base}/tx_bytes", f"{base}/tx_packets").stdout.split()
        return int(output[0]), int(output[1])


def _bits(rate: str) -> float:
    text = rate.lower().replace("bit", "").replace("ps", "")
    scale = {"k": 1e3, "m": 1e6, "g": 1e9}.get(text[-1:], 1)
    try:
        bits = float(text.rstrip("kmg")) * scale
    except ValueError:
        raise EmulationError(f"rate {rate!r} is not like 1mbit or 9600bit") from None
    if not bits > 0:
        raise EmulationError(f"rate {rate!r} must be positive")
    return bits


def _fraction(percent: float) -> float:
    if not 0 <= percent <= 100:
        raise EmulationError(f"loss {percent} % is not a percentage")
    return percent / 100


#: ``ethtool -K DEV tx off`` by hand (the ioctl; this machine has no ethtool).
SIOCETHTOOL = 0x8946
ETHTOOL_STXCSUM = 0x17


class _EthtoolValue(ctypes.Structure):
    _fields_ = [("cmd", ctypes.c_uint32), ("data", ctypes.c_uint32)]


def _software_checksums(device: str) -> None:
    """No transmit checksum offload on ``device`` (nor, as it depends on it, segmentation
    offload): a veth otherwise hands its peer frames whose checksums are still to be filled
    in and 64 kB TCP super-frames, which the link stage would copy as they are."""
    value = _EthtoolValue(ETHTOOL_STXCSUM, 0)
    request = struct.pack("16sP", device.encode(), ctypes.addressof(value)).ljust(40, b"\0")
    try:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
            fcntl.ioctl(sock.fileno(), SIOCETHTOOL, request)
    except OSError as exc:
        raise EmulationError(f"turning off {device}'s checksum offload: {exc}") from None


def run_blackouts(link: EmulatedLink, durations: Sequence[float], gap: float) -> None:
    """DARPA-style schedule: ``gap`` seconds of link, then a blackout, in turn (the link
    comes back with its profile even when interrupted)."""
    for duration in durations:
        time.sleep(gap)
        print(f"blackout for {duration:g} s", flush=True)
        link.blackout(True)
        try:
            time.sleep(duration)
        finally:
            link.blackout(False)
        print("link back", flush=True)


def main(argv: Optional[List[str]] = None) -> int:
    parser = argparse.ArgumentParser(prog="walkman-netem",
                                     description="Emulated robot/pilot hosts and bad links.")
    parser.add_argument("--prefix", default="wm", help="namespace prefix (default wm)")
    parser.add_argument("--subnet", type=int, default=10, help="169.254.SUBNET.x (default 10)")
    sub = parser.add_subparsers(dest="verb", required=True)
    sub.add_parser("up", help="create the robot and pilot namespaces and the radio between")
    sub.add_parser("down", help="remove them")
    sub.add_parser("status", help="the radio's settings and what it delivered and dropped")
    shape = sub.add_parser("profile", help="apply lab, drc or degraded")
    shape.add_argument("name", choices=sorted(PROFILES))
    shape.add_argument("--loss", type=float, help="random loss in percent")
    shape.add_argument("--rate", help="rate as tc spells it, e.g. 1mbit or 9600bit")
    shape.add_argument("--delay", type=float, help="one-way delay in milliseconds")
    flap = sub.add_parser("flap", help="take the link down for SECONDS, then up")
    flap.add_argument("seconds", type=float)
    black = sub.add_parser("blackouts", help="blackouts of the given lengths")
    black.add_argument("durations", type=float, nargs="*", help="seconds (default: 1-30 s)")
    black.add_argument("--gap", type=float, default=10.0, help="seconds of link between")
    black.add_argument("--count", type=int, default=5)
    sub.add_parser("intruder", help="add a rogue host on the same radio (prefix_rogue, .3)")
    sub.add_parser("addresses", help="print the two addresses")
    options = parser.parse_args(argv)
    link = EmulatedLink(options.prefix, options.subnet)
    try:
        if options.verb == "up":
            link.up()
            print(f"robot {link.namespace('robot')} {link.address('robot')}; "
                  f"pilot {link.namespace('pilot')} {link.address('pilot')}")
        elif options.verb == "down":
            link.down()
        elif options.verb == "intruder":
            link.add_intruder()
            print(f"rogue {link.namespace('rogue')} {link.address('rogue')} on "
                  f"{link.device('rogue')}, hearing everything the robot hears")
        elif options.verb == "profile":
            link.apply(options.name, options.loss, options.rate,
                       None if options.delay is None else options.delay / 1000)
        elif options.verb == "status":
            print(json.dumps(link.status(), indent=1))
        elif options.verb == "flap":
            link.flap(True)
            time.sleep(options.seconds)
            link.flap(False)
        elif options.verb == "blackouts":
            durations = options.durations or [random.uniform(1, 30)
                                              for _ in range(options.count)]
            run_blackouts(link, durations, options.gap)
        elif options.verb == "addresses":
            print(link.address("robot"), link.address("pilot"))
    except EmulationError as exc:
        print(f"walkman-netem: {exc}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
