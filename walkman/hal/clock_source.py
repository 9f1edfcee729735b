"""The HAL's clock ports: ``NAME`` (the ticks), ``NAME/rpc`` (the ClockServer verbs) and
``NAME/lockstep:i`` (the modules in lockstep, :mod:`walkman.hal.lockstep`).

The thin I/O layer around :mod:`walkman.hal.clock_server`.  The physics thread only posts
the step count it reached (latest only, never blocking); one writer thread turns it into a
tick and writes it to every follower, waiting for a slow one rather than skipping it, so
the last tick before a pause always arrives and a follower's time ends exactly where the
physics stopped.  Requests on ``NAME/rpc`` and the members' messages are taken by the
ports' own threads.
"""

from __future__ import annotations

import logging
import threading
from typing import Optional

from walkman.hal import lockstep
from walkman.hal.clock_server import WAIT_SLICE_S, ClockServer, SimulationTime, StepGate
from walkman.hal.lockstep import LockstepGate
from yarp_lite.clock_wire import encode_tick
from yarp_lite.nameclient import NameClient
from yarp_lite.port import Port
from yarp_lite.rpc import RpcServer

log = logging.getLogger("walkman.hal.clock")


class ClockSource:
    """Ticks out on ``name``, the ClockServer on ``name/rpc`` (see the module's docstring)."""

    def __init__(self, name: str, gate: StepGate, time: SimulationTime,
                 nameclient: Optional[NameClient] = None,
                 members: Optional[LockstepGate] = None) -> None:
        self.name = name
        self.gate = gate
        self.time = time
        self.nameclient = nameclient or NameClient()
        #: The modules in lockstep with the physics.
        self.members = members or LockstepGate()
        self.server = ClockServer(gate, time, on_reset=self.members.refuse_reset,
                                  published=self.wait_written)
        self._cond = threading.Condition()
        self._pending: Optional[int] = None
        self._written = -1
        self._running = False
        self._tick_port: Optional[Port] = None
        self._rpc_port: Optional[RpcServer] = None
        self._lockstep_port: Optional[Port] = None
        self._thread = threading.Thread(target=self._write_ticks, daemon=True,
                                        name=f"clock {name}")
        self.ticks_written = 0

    def open(self) -> "ClockSource":
        self._tick_port = Port(nameclient=self.nameclient).open(self.name)
        self._rpc_port = RpcServer(nameclient=self.nameclient, handler=self._answer)
        self._rpc_port.open(f"{self.name}/rpc")
        self._lockstep_port = Port(nameclient=self.nameclient, reader=self.members.receive)
        self._lockstep_port.open(lockstep.port_name(self.name))
        self._running = True
        self._thread.start()
        self.post(self.gate.taken)          # the first tick: followers start at once
        log.info("simulated time on %s (ClockServer on %s/rpc), %g ms steps, from %g s",
                 self.name, self.name, self.time.step * 1e3, self.time.at(self.gate.taken))
        return self

    def _answer(self, request):
        reply = self.server.answer(request)
        if request and request[0] == "resetSimulationTime":
            self.post(self.gate.taken)      # followers see the time go back, paused or not
        return reply

    def post(self, taken: int) -> None:
        """The physics reached ``taken`` steps: write its tick when the writer is free."""
        with self._cond:
            self._pending = taken
            self._cond.notify_all()

    def wait_written(self, taken: int) -> bool:
        """Wait until a tick at ``taken`` steps or later went out (False: closing)."""
        with self._cond:
            while self._written < taken:
                if not self._running:
                    return False
                self._cond.wait(WAIT_SLICE_S)
            return True

    def _write_ticks(self) -> None:
        while True:
            with self._cond:
                while self._pending is None and self._running:
                    self._cond.wait(WAIT_SLICE_S)
                if not self._running:
                    return
                taken, self._pending = self._pending, None
            self._tick_port.write(encode_tick(self.time.at(taken)))
            with self._cond:
                self._written = max(self._written, taken)
                self.ticks_written += 1
                self._cond.notify_all()

    def close(self) -> None:
        with self._cond:
            self._running = False
            self._cond.notify_all()
        if self._thread.is_alive():
            self._thread.join(timeout=2.0)
        self.members.close()
        for port in (self._lockstep_port, self._rpc_port, self._tick_port):
            if port is not None:
                port.close()
