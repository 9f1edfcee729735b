"""Emulated robot and pilot PCs: two network namespaces, one veth cable, bad-link profiles.

Theory of operation
-------------------
``up`` creates the namespaces ``<prefix>_robot`` and ``<prefix>_pilot``, each
with its own loopback (so each runs its own yarpserver and roscore on the
usual ports) and one end of a veth pair, addressed 169.254.<subnet>.1 (robot)
and .2 (pilot): link-local, so nothing ever leaves the pair.

Profiles shape both directions:

==========  ==========================================================
lab         no shaping (a veth moves gigabits)
drc         1 Mbit/s token bucket (``tc tbf``) and random loss
            (``nftables`` ``numgen random``), 5 % unless told otherwise
degraded    9600 bit/s, and blackouts of 1-30 s when ``blackouts`` runs
==========  ==========================================================

Loss and blackouts drop Ethernet frames on *arrival* (the netdev ingress hook,
before IP reassembles fragments), so senders see a lossy wire, not an error,
and a 60 kB datagram dies of any one of its 45 fragments, as on a radio.  ``flap`` takes the link down and up
(``ip link``), which senders do see.  This kernel has no ``netem``, hence no
delay emulation.  Everything needs root; :func:`available` says why not.

An intruder
-----------
``add_intruder`` puts a third host, ``<prefix>_rogue`` at 169.254.<subnet>.3,
on the same radio: an attacker on the DRC wireless.  A radio is a broadcast
medium, so the robot's end of the cable becomes a port of a Linux bridge
(``<prefix>b0``, in the robot's namespace) that learns no addresses and so
floods every frame to every port, like a hub::

    pilot p0 ==veth== r0 -+- b0 -+- rb ==veth== ri  robot (.1)
                          |      +- x1 ==veth== x0  rogue (.3, promiscuous)

The robot's address moves from ``r0`` to ``ri`` (the bridge delivers frames
for an address on itself only locally, and the rogue would not hear them).
``r0`` and ``p0`` keep the profile -- shaping on egress, loss on ingress -- so
the robot and the pilot still talk over the bad link, and the rogue hears
exactly what reached the robot (the pilot's frames after the loss) and what the
robot sent.  The rogue's own path to the robot is unshaped and lossless: an
attacker close to the robot, whose every attempt arrives (so a test can count
them).  Add it before starting programs on the robot: its address moves.
"""

from __future__ import annotations

import argparse
import os
import random
import shutil
import subprocess
import sys
import time
from dataclasses import dataclass
from typing import List, Optional, Sequence

PROFILES = {
    "lab": {"rate": None, "loss": 0.0},
    "drc": {"rate": "1mbit", "loss": 5.0},
    "degraded": {"rate": "9600bit", "loss": 0.0},
}
SIDES = ("robot", "pilot")
#: The last byte of each host's address; "rogue" exists after :meth:`EmulatedLink.add_intruder`.
HOSTS = {"robot": 1, "pilot": 2, "rogue": 3}
DEVICES = {"robot": "r0", "pilot": "p0", "rogue": "x0"}
TABLE = "wmnetem"


class EmulationError(Exception):
    """A command building or shaping the emulated network failed; the text says which."""


def available() -> Optional[str]:
    """None when emulated networks can be built here, else the reason they cannot."""
    if os.geteuid() != 0:
        return "emulated networks need root (network namespaces, tc, nftables)"
    for tool in ("ip", "tc", "nft"):
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
    """The two hosts and the cable between them."""

    prefix: str = "wm"
    subnet: int = 10

    def __post_init__(self) -> None:
        if not self.prefix.isalnum() or len(self.prefix) > 8:
            raise EmulationError(f"prefix {self.prefix!r} must be up to 8 letters or digits")
        if not 0 <= self.subnet <= 255:
            raise EmulationError(f"subnet {self.subnet} must be 0..255")

    def namespace(self, side: str) -> str:
        return f"{self.prefix}_{side}"

    def device(self, side: str) -> str:
        """A host's interface on the radio (robot and pilot: the cable's ends, shaped)."""
        return f"{self.prefix}{DEVICES[side]}"

    def address(self, side: str) -> str:
        return f"169.254.{self.subnet}.{HOSTS[side]}"

    def exec_argv(self, side: str, argv: Sequence[str]) -> List[str]:
        return ["ip", "netns", "exec", self.namespace(side), *argv]

    def _ns(self, side: str, *argv: str, check: bool = True) -> subprocess.CompletedProcess:
        return _run(self.exec_argv(side, argv), check)

    # -- building ----------------------------------------------------------------------

    def exists(self) -> bool:
        names = _run(["ip", "netns", "list"]).stdout.split()
        return all(self.namespace(side) in names for side in SIDES)

    def up(self) -> None:
        reason = available()
        if reason:
            raise EmulationError(reason)
        self.down()
        for side in SIDES:
            _run(["ip", "netns", "add", self.namespace(side)])
        _run(["ip", "link", "add", self.device("robot"), "type", "veth", "peer", "name",
              self.device("pilot")])
        for side in SIDES:
            _run(["ip", "link", "set", self.device(side), "netns", self.namespace(side)])
            self._ns(side, "ip", "addr", "add", f"{self.address(side)}/24", "dev",
                     self.device(side))
            self._ns(side, "ip", "link", "set", "lo", "up")
            self._ns(side, "ip", "link", "set", self.device(side), "up")
            self._ns(side, "nft", "add", "table", "netdev", TABLE)
            self._ns(side, "nft", "add", "chain", "netdev", TABLE, "ingress",
                     f"{{ type filter hook ingress device {self.device(side)} priority 0; "
                     f"policy accept; }}")

    def down(self) -> None:
        for host in HOSTS:
            _run(["ip", "netns", "del", self.namespace(host)], check=False)

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
        _run(["ip", "netns", "add", self.namespace("rogue")])
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

    # -- shaping -----------------------------------------------------------------------

    def apply(self, profile: str, loss: Optional[float] = None,
              rate: Optional[str] = None) -> None:
        if profile not in PROFILES:
            raise EmulationError(f"unknown profile {profile!r} ({', '.join(PROFILES)})")
        settings = PROFILES[profile]
        self.set_rate(rate if rate is not None else settings["rate"])
        self.set_loss(settings["loss"] if loss is None else loss)

    def set_rate(self, rate: Optional[str]) -> None:
        for side in SIDES:
            self._ns(side, "tc", "qdisc", "del", "dev", self.device(side), "root", check=False)
            if rate:
                bits = _bits(rate)
                burst = max(3000, int(bits / 8 * 0.02))
                self._ns(side, "tc", "qdisc", "add", "dev", self.device(side), "root", "tbf",
                         "rate", rate, "burst", str(burst), "latency", "500ms")

    def set_loss(self, percent: float) -> None:
        if not 0 <= percent <= 100:
            raise EmulationError(f"loss {percent} % is not a percentage")
        for side in SIDES:
            self._ns(side, "nft", "flush", "chain", "netdev", TABLE, "ingress")
            chance = int(round(percent * 100))
            if chance >= 10000:
                self._ns(side, "nft", "add", "rule", "netdev", TABLE, "ingress", "drop")
            elif chance > 0:
                self._ns(side, "nft", "add", "rule", "netdev", TABLE, "ingress", "numgen",
                         "random", "mod", "10000", "<", str(chance), "drop")

    def blackout(self, on: bool) -> None:
        """Drop everything arriving on either side (the radio is gone)."""
        self.set_loss(100.0 if on else 0.0)

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
    return float(text.rstrip("kmg")) * scale


def run_blackouts(link: EmulatedLink, durations: Sequence[float], gap: float,
                  loss: float = 0.0) -> None:
    """DARPA-style schedule: ``gap`` seconds of link, then a blackout, in turn."""
    for duration in durations:
        time.sleep(gap)
        print(f"blackout for {duration:g} s", flush=True)
        link.blackout(True)
        time.sleep(duration)
        link.set_loss(loss)
        print("link back", flush=True)


def main(argv: Optional[List[str]] = None) -> int:
    parser = argparse.ArgumentParser(prog="walkman-netem",
                                     description="Emulated robot/pilot hosts and bad links.")
    parser.add_argument("--prefix", default="wm", help="namespace prefix (default wm)")
    parser.add_argument("--subnet", type=int, default=10, help="169.254.SUBNET.x (default 10)")
    sub = parser.add_subparsers(dest="verb", required=True)
    sub.add_parser("up", help="create the robot and pilot namespaces")
    sub.add_parser("down", help="remove them")
    shape = sub.add_parser("profile", help="apply lab, drc or degraded")
    shape.add_argument("name", choices=sorted(PROFILES))
    shape.add_argument("--loss", type=float, help="random loss in percent")
    shape.add_argument("--rate", help="tc rate, e.g. 1mbit or 9600bit")
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
            link.apply(options.name, options.loss, options.rate)
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
