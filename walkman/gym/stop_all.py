"""The pilot's stop-all, carried out on the robot: the HAL holds, every module pauses.

Theory of operation
-------------------
A stop-all must hold the robot *at once*, whatever each module is doing: the HAL
first (``[set] halt on`` on ``/<robot>/rpc:i``: every joint held where its servo
is, every module's command refused until the pilot releases it -- the robot
never drops into zero torque), then ``pause`` on every module's switch port (a
module keeping something safe while paused does it against a held robot:
harmless; one that is not running refuses the switch, also harmless).  One
YARP port fans the pause out to every module at once; its connections, and the
one to the HAL, are kept made by a :class:`~nodekit.connections.ConnectionKeeper`
beforehand, so a stop costs one rpc and one write.

The robot bridge runs it when a stop-all arrives over the link (first copy of
each stop id), the pilot gateway in the lab, where there is no bridge.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from dataclasses import dataclass, field
from typing import List, Optional, Sequence

from nodekit.connections import ConnectionKeeper
from walkman.gym.interfaces import SWITCH
from walkman.hal import protocol
from yarp_lite.bottle import Bottle, Vocab
from yarp_lite.errors import YarpError
from yarp_lite.nameclient import NameClient
from yarp_lite.port import Port
from yarp_lite.rpc import RpcClient

log = logging.getLogger("walkman.stop_all")

#: Seconds the HAL has to answer a halt.
HAL_TIMEOUT = 2.0


@dataclass(frozen=True)
class StopReport:
    """What a stop-all (or its release) did."""

    stop_id: int
    hal: bool                     # the HAL said ok
    modules: List[str] = field(default_factory=list)   # switch ports the pause reached
    took_ms: float = 0.0
    problem: str = ""

    def line(self) -> str:
        what = "HAL held" if self.hal else f"HAL NOT held ({self.problem})"
        return (f"stop-all {self.stop_id}: {what}; pause sent to "
                f"{', '.join(self.modules) or 'no module'} in {self.took_ms:.0f} ms")


class StopAll:
    """Keeps the connections a stop-all needs, and carries it out."""

    def __init__(self, robot: str, modules: Sequence[str], name: str,
                 nameclient: Optional[NameClient] = None) -> None:
        self.robot = robot
        self.modules = list(modules)
        self.nameclient = nameclient or NameClient()
        self._lock = threading.Lock()
        self.switches = Port(nameclient=self.nameclient).open(f"{name}/switch:o",
                                                              wait=math.inf)
        self.hal = RpcClient(f"{name}/hal:o", nameclient=self.nameclient)
        self.keeper = ConnectionKeeper()
        for module in self.modules:
            self.keeper.want(self.switches.name, SWITCH.of(module), self.switches,
                             ours_is_source=True)
        self.keeper.want(self.hal.name, protocol.robot_rpc_name(robot), self.hal,
                         ours_is_source=True)
        self.keeper.start()

    def stop(self, stop_id: int) -> StopReport:
        """Hold the HAL, then pause every module reachable now."""
        return self._carry_out(stop_id, halt=True)

    def release(self, stop_id: int) -> StopReport:
        """Let the HAL apply commands again; the modules stay paused until the pilot
        resumes each (it decides what is safe to go on with)."""
        return self._carry_out(stop_id, halt=False)

    def _carry_out(self, stop_id: int, halt: bool) -> StopReport:
        started = time.monotonic()
        with self._lock:
            problem = ""
            try:
                reply = self.hal.call(Bottle([Vocab("set"), "halt", "on" if halt else "off"]),
                                      timeout=HAL_TIMEOUT)
                hal = bool(reply) and str(reply[0]) == "ok"
                if not hal:
                    problem = f"the HAL answered {reply.to_text()[:80]}"
            except YarpError as exc:
                hal, problem = False, f"the HAL did not answer: {exc}"
            reached: List[str] = []
            if halt:
                reached = [module for module in self.modules
                           if self.switches_reach(module)]
                try:
                    self.switches.write(Bottle(["pause", stop_id]))
                except YarpError as exc:
                    problem = problem or f"the pause was not written: {exc}"
                    reached = []
        report = StopReport(stop_id, hal, reached, (time.monotonic() - started) * 1000.0,
                            problem)
        (log.warning if halt or not hal else log.info)("%s", report.line()
                                                        if halt else
                                                        f"released {stop_id}: HAL "
                                                        f"{'free' if hal else problem}")
        return report

    def switches_reach(self, module: str) -> bool:
        return any(route.target == SWITCH.of(module) for route in self.switches.output_routes())

    def close(self) -> None:
        self.keeper.stop()
        self.switches.close()
        self.hal.close()
