"""The emulated radio's process: it moves Ethernet frames between the robot's and the pilot's
cables, each direction through a :class:`~netem.radio_model.RadioChannel`.

Theory of operation
-------------------
:mod:`netem.emulation` cuts the robot-pilot cable in two and runs this program, as root, in
the namespace between the halves (``<prefix>_link``), whose two interfaces lead to the robot
and to the pilot.  One ``AF_PACKET`` socket on each hears every frame that end sends; frames
the kernel reports as our own (``PACKET_OUTGOING``) are skipped.

One thread, one loop: wait (``select``) until a frame arrives, a control request comes or the
next frame is due; read every frame waiting and offer it, stamped with the time it was read,
to its direction's channel; write out every frame that is due.  Nothing is ever written
early, so a frame spends at least its serialisation and delay on the link; on a busy machine
it may spend more (the process asks for ``SCHED_FIFO`` to keep that small).

Control: a Unix stream socket.  A request is one JSON line, ``{"set": {...}}`` (fields of
:class:`~netem.radio_model.RadioSettings`, both directions) or ``{}``; the reply is one JSON
line with the settings and each direction's counters, or ``{"error": text}``.

Ideal settings (no rate, delay, loss or blackout: the ``lab`` profile) are the kernel's job:
the stage closes its sockets and makes both interfaces ports of a bridge, so a lab link keeps
a veth's gigabits and microseconds; other settings take them back (frames under way at a
switch are lost).  The program exits when its interfaces are gone.
"""

from __future__ import annotations

import argparse
import json
import os
import select
import socket
import subprocess
import sys
import time
from typing import Dict, List, Optional

from netem.radio_model import RadioChannel, RadioSettings, RadioSettingsError
from walkman.realtime import realtime_refused

ETH_P_ALL = 0x0003
SO_RCVBUFFORCE = getattr(socket, "SO_RCVBUFFORCE", 33)
#: Real-time priority: above every thread of the machine, the robot's loops included
#: (walkman.realtime: 50-60).  The stage stands for the radio, a device that shares no CPU
#: with the robot: at 40, below the loops, a robot PC's physics and modules held frames
#: back on a loaded 2-core machine (fresh-clone run fc68: statuses seconds late), a delay no
#: real link adds.  The stage sleeps in ``select`` and handles a frame in well under a
#: millisecond, so the loops lose no more to it than to a network card's interrupts.
STAGE_PRIORITY = 70
#: How often the loop checks, idle, that its interfaces still exist.
IDLE_CHECK = 1.0
SIDES = ("robot", "pilot")


class Stage:
    """The two ends, the two channels and the control socket."""

    def __init__(self, interfaces: Dict[str, str], bridge: str, control: str) -> None:
        self.interfaces = interfaces
        self.bridge = bridge
        self.settings = RadioSettings()
        # channels[side]: the frames ``side`` sent, toward the other side
        self.channels = {side: RadioChannel(self.settings) for side in SIDES}
        self.sockets: Dict[str, socket.socket] = {}
        self.errors: Dict[str, int] = {"send": 0, "switch_lost": 0}
        if os.path.exists(control):
            os.unlink(control)
        self.control = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        self.control.bind(control)
        os.chmod(control, 0o600)
        self.control.listen(8)
        self.bridged = False  # the ends as :mod:`netem.emulation` leaves them: in no bridge
        self._apply(self.settings)  # ideal: they join the bridge

    # -- frames ----------------------------------------------------------------------------

    def _attach(self) -> None:
        """Take the frames from the kernel's bridge: the ends leave it, the sockets open."""
        for name in self.interfaces.values():
            _ip("link", "set", name, "nomaster")
        for side, name in self.interfaces.items():
            # Protocol 0 until bound: a socket opened for ETH_P_ALL hears every interface
            # until bind() narrows it to one, and would send a frame back where it came from.
            sock = socket.socket(socket.AF_PACKET, socket.SOCK_RAW, 0)
            sock.setsockopt(socket.SOL_SOCKET, SO_RCVBUFFORCE, 4 << 20)  # a burst waits
            sock.bind((name, ETH_P_ALL))
            sock.setblocking(False)
            self.sockets[side] = sock
        self.bridged = False

    def _detach(self) -> None:
        """Give the frames to the kernel's bridge: sockets closed, the ends made its ports."""
        for sock in self.sockets.values():
            sock.close()
        self.sockets.clear()
        for name in self.interfaces.values():
            _ip("link", "set", name, "master", self.bridge)
        self.bridged = True

    def _read(self, side: str) -> None:
        sock, channel = self.sockets[side], self.channels[side]
        while True:
            try:
                frame, address = sock.recvfrom(65536)
            except BlockingIOError:
                return
            if address[2] != socket.PACKET_OUTGOING:
                channel.offer(frame, time.monotonic())

    def _deliver(self, now: float) -> None:
        for side, channel in self.channels.items():
            frames = channel.take_due(now)
            if not frames:
                continue
            out = self.sockets[_other(side)]
            for frame in frames:
                try:
                    out.send(frame)
                except OSError:  # the far cable unplugged (flap), its queue full: lost
                    self.errors["send"] += 1

    # -- control ---------------------------------------------------------------------------

    def _apply(self, settings: RadioSettings) -> None:
        now = time.monotonic()
        if settings.ideal and not self.bridged:
            for channel in self.channels.values():
                self.errors["switch_lost"] += len(channel.clear(now))
            self._detach()
        elif not settings.ideal and self.bridged:
            self._attach()
        for channel in self.channels.values():
            channel.configure(settings, now)
        self.settings = settings

    def _answer(self, client: socket.socket) -> None:
        client.settimeout(2.0)
        with client:
            try:
                request = json.loads(client.makefile("r").readline() or "{}")
                changes = request.get("set", {})
                if not isinstance(changes, dict):
                    raise RadioSettingsError(f"'set' must be an object, not {changes!r}")
                if changes:
                    self._apply(self.settings.updated(changes))
                reply = self.status()
            except (ValueError, TypeError, AttributeError) as exc:  # bad JSON or settings
                reply = {"error": str(exc)}
            try:
                client.sendall(json.dumps(reply).encode() + b"\n")
            except OSError:
                pass  # the client gave up waiting; the settings stand

    def status(self) -> Dict:
        directions = {f"{side}_to_{_other(side)}": channel
                      for side, channel in self.channels.items()}
        return {"settings": self.settings.as_dict(), "bridged": self.bridged,
                "errors": dict(self.errors),
                "counters": {name: dict(c.counters) for name, c in directions.items()},
                "under_way": {name: c.under_way() for name, c in directions.items()}}

    # -- the loop --------------------------------------------------------------------------

    def _timeout(self, now: float) -> float:
        due = [t for t in (c.next_due() for c in self.channels.values()) if t is not None]
        return max(0.0, min([IDLE_CHECK, *(t - now for t in due)]))

    def run(self) -> int:
        print("radio stage ready", flush=True)
        while True:
            waiting: List = [self.control, *self.sockets.values()]
            readable, _, _ = select.select(waiting, [], [], self._timeout(time.monotonic()))
            try:
                for side, sock in list(self.sockets.items()):
                    if sock in readable:
                        self._read(side)
            except OSError as exc:  # ENETDOWN: the interface went away
                if not self._interfaces_exist():
                    return _gone()
                raise exc
            if self.sockets:
                self._deliver(time.monotonic())
            if self.control in readable:
                client, _ = self.control.accept()
                self._answer(client)
            if not readable and not self._interfaces_exist():
                return _gone()

    def _interfaces_exist(self) -> bool:
        try:
            for name in self.interfaces.values():
                socket.if_nametoindex(name)
        except OSError:
            return False
        return True


def _other(side: str) -> str:
    return SIDES[1 - SIDES.index(side)]


def _ip(*argv: str) -> None:
    result = subprocess.run(["ip", *argv], capture_output=True, text=True)
    if result.returncode != 0:
        raise OSError(f"ip {' '.join(argv)}: {result.stderr.strip()}")


def _gone() -> int:
    print("radio stage: the interfaces are gone; exiting", flush=True)
    return 0


def main(argv: Optional[List[str]] = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--robot", required=True, help="the interface toward the robot")
    parser.add_argument("--pilot", required=True, help="the interface toward the pilot")
    parser.add_argument("--bridge", required=True, help="the bridge that joins them when ideal")
    parser.add_argument("--control", required=True, help="the control socket's path")
    options = parser.parse_args(argv)
    refused = realtime_refused(STAGE_PRIORITY)
    if refused:
        print(f"radio stage: normal priority ({refused})", flush=True)
    stage = Stage({"robot": options.robot, "pilot": options.pilot}, options.bridge,
                  options.control)
    return stage.run()


if __name__ == "__main__":
    sys.exit(main())
