"""The chaos run's pilot: a ROS node on the pilot PC that keeps modules running and commands one.

Theory of operation
-------------------
This is what a pilot does with the gateway, as one long-lived node instead of a
hand on ``rosservice``: it watches ``/M/status`` of every module given, calls
``/M/switch_and_wait start`` when one shows ``initializing`` or ``stopped``
(a module that was killed comes back in its constructor state), and sends
numbered commands ``count N`` to one module through ``/M/send_command``, one
every ``--interval`` seconds.  A command the gateway refuses (the module's
port is not reachable) or a call that fails (no gateway, no roscore) is tried
again with the same N until the gateway accepts it; the gateway numbers each
accepted one with its own sequence number, which the reply carries.

Everything it sees and does is one JSON line on stdout, with the wall-clock
time it happened (``ev``: ``ready``, ``status``, ``switch``, ``sent``,
``refused``, ``failed``); :mod:`system.chaos` reads them.  The node survives
its roscore being killed: :class:`~nodekit.ros_node.RosNode` registers its
subscriptions again, and a service proxy looks the service up on every call.
SIGINT or SIGTERM stops it between two calls.
"""

from __future__ import annotations

import argparse
import json
import signal
import sys
import threading
import time
from typing import Any, Dict, List, Optional

#: the states in which the pilot says ``start``.  Not ``waiting_hal``: a module shows it both
#: when started before the HAL (its start is pending) and when it lost the HAL while running.
NEEDS_START = ("initializing", "stopped")
START_RETRY = 3.0  # s between two starts of one module (a start crosses the link)


class Pilot:
    """What the pilot knows (each module's last state, the next N) and does."""

    def __init__(self, modules: List[str], command_module: str, interval: float,
                 first: int) -> None:
        self.modules = modules
        self.command_module = command_module
        self.interval = interval
        self.number = first
        self.stop = threading.Event()
        self.state: Dict[str, str] = {}
        self.started_at: Dict[str, float] = {}
        self._print_lock = threading.Lock()

    def emit(self, event: str, **fields: Any) -> None:
        line = json.dumps({"ev": event, "t": time.time(), **fields})
        with self._print_lock:  # rospy calls back from one thread per topic
            print(line, flush=True)

    # -- what the pilot watches --------------------------------------------------------

    def subscribe(self) -> None:
        import rospy
        from walkman_msgs.msg import Status

        for module in self.modules:
            rospy.Subscriber(f"/{module}/status", Status,
                             lambda msg, mod=module: self.on_status(mod, msg))
        self.emit("ready", modules=self.modules)

    def on_status(self, module: str, msg: Any) -> None:
        self.state[module] = msg.state
        self.emit("status", module=module, seq=msg.seq, state=msg.state,
                  values=list(msg.values))

    # -- what the pilot does -----------------------------------------------------------

    def keep_running(self) -> None:
        """Start every module that shows :data:`NEEDS_START` (a thread)."""
        while not self.stop.wait(0.5):
            for module in self.modules:
                if self.state.get(module) not in NEEDS_START:
                    continue
                if time.monotonic() - self.started_at.get(module, -START_RETRY) < START_RETRY:
                    continue
                self.started_at[module] = time.monotonic()
                self.switch(module, "start")

    def switch(self, module: str, word: str) -> None:
        import rospy
        from walkman_msgs.srv import SwitchModule

        try:
            reply = rospy.ServiceProxy(f"/{module}/switch_and_wait", SwitchModule)(
                command=word, timeout=5.0)
        except (rospy.ServiceException, rospy.ROSException, OSError) as exc:
            self.emit("switch", module=module, word=word, ok=False, error=str(exc))
            return
        self.emit("switch", module=module, word=word, ok=reply.ok, state=reply.state,
                  message=reply.message)

    def command_loop(self) -> None:
        """``count N`` for N = first, first + 1 ...; each until the gateway accepts it."""
        import rospy
        from walkman_msgs.srv import SendCommand

        service = f"/{self.command_module}/send_command"
        while not self.stop.is_set():
            try:
                reply = rospy.ServiceProxy(service, SendCommand)(
                    command="count", words=[], numbers=[float(self.number)], text="")
            except (rospy.ServiceException, rospy.ROSException, OSError) as exc:
                # The call may or may not have reached the gateway: its log tells.
                self.emit("failed", n=self.number, error=str(exc).splitlines()[0][:200])
                self.stop.wait(0.5)
                continue
            if not reply.ok:
                self.emit("refused", n=self.number, message=reply.message)
                self.stop.wait(0.5)
                continue
            self.emit("sent", n=self.number, seq=reply.seq)
            self.number += 1
            self.stop.wait(self.interval)


def main(argv: Optional[List[str]] = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m system.chaos_pilot",
                                     description=__doc__.split("\n")[0])
    parser.add_argument("--modules", required=True,
                        help="modules to watch and keep running (comma separated)")
    parser.add_argument("--command", required=True, help="the module to send count N to")
    parser.add_argument("--interval", type=float, default=0.5,
                        help="seconds between two accepted commands (default 0.5)")
    parser.add_argument("--first", type=int, default=1, help="first N (default 1)")
    options = parser.parse_args(argv)
    from nodekit.ros_node import RosNode
    from rosnodes.msgs import ensure_importable

    ensure_importable()
    modules = [m.strip() for m in options.modules.split(",") if m.strip()]
    pilot = Pilot(modules, options.command, options.interval, options.first)
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: pilot.stop.set())
    node = RosNode("chaos_pilot")
    node.when_ready(pilot.subscribe)
    node.start()
    while not node.ready.wait(0.5):
        if pilot.stop.is_set():
            return 0
    threading.Thread(target=pilot.keep_running, name="keep running", daemon=True).start()
    pilot.command_loop()
    node.stop()
    return 0


if __name__ == "__main__":
    sys.exit(main())
