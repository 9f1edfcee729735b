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

Two kinds of numbered commands test what a pilot may take back (:func:`plan`):
every ``--short-every``-th is sent with a short validity (``--short-validity``
seconds: one held through an outage longer than that must expire, never run),
and every ``--cancel-every``-th is cancelled with ``/M/cancel`` right after the
gateway accepted it (taken back if the pilot bridge still holds it -- the link
or the robot's bridge is down --, else "too late" and it must run once).  The
pilot also follows ``/pilot/command_states`` for the commanded module: each
command's life (sent, queued, delivered, accepted, expired, cancelled).

Everything it sees and does is one JSON line on stdout, with the wall-clock
time it happened (``ev``: ``ready``, ``status``, ``switch``, ``sent``,
``refused``, ``failed``, ``cancel``, ``state``, ``drained``);
:mod:`system.chaos_run` reads them.  The node survives its roscore being
killed: :class:`~nodekit.ros_node.RosNode` registers its subscriptions again,
and a service proxy looks the service up on every call.  SIGUSR1 stops the
commands but not the watching (the run's drain: what was sent still ends,
and the pilot still hears how); SIGINT or SIGTERM stops it between two calls.
"""

from __future__ import annotations

import argparse
import json
import signal
import sys
import threading
import time
from dataclasses import dataclass
from typing import Any, Dict, List, Optional

#: the states in which the pilot says ``start``.  Not ``waiting_hal``: a module shows it both
#: when started before the HAL (its start is pending) and when it lost the HAL while running.
NEEDS_START = ("initializing", "stopped")
START_RETRY = 3.0  # s between two starts of one module (a start crosses the link)


@dataclass(frozen=True)
class Plan:
    """How the pilot sends its command number N."""

    validity: float = 0.0   # seconds it may wait before it starts; 0: the module's own
    cancel: bool = False    # take it back right after the gateway accepted it

    @property
    def plain(self) -> bool:
        """Neither short-lived nor cancelled: it must run, whatever happens."""
        return not self.validity and not self.cancel


def plan(number: int, short_every: int, short_validity: float, cancel_every: int) -> Plan:
    """Command ``number``'s plan: every ``short_every``-th short-lived, every
    ``cancel_every``-th cancelled (0: never)."""
    short = short_every > 0 and number % short_every == 0
    return Plan(short_validity if short else 0.0, cancel_every > 0 and number % cancel_every == 0)


class Pilot:
    """What the pilot knows (each module's last state, the next N) and does."""

    def __init__(self, modules: List[str], command_module: str, interval: float,
                 first: int, short_every: int = 0, short_validity: float = 0.0,
                 cancel_every: int = 0) -> None:
        self.modules = modules
        self.command_module = command_module
        self.interval = interval
        self.number = first
        self.short_every, self.short_validity = short_every, short_validity
        self.cancel_every = cancel_every
        self.stop = threading.Event()          # SIGINT, SIGTERM: the end
        self.no_more = threading.Event()       # SIGUSR1 too: no more commands
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
        from walkman_msgs.msg import CommandState, Status

        for module in self.modules:
            rospy.Subscriber(f"/{module}/status", Status,
                             lambda msg, mod=module: self.on_status(mod, msg))
        rospy.Subscriber("/pilot/command_states", CommandState, self.on_command_state)
        self.emit("ready", modules=self.modules)

    def on_status(self, module: str, msg: Any) -> None:
        self.state[module] = msg.state
        self.emit("status", module=module, seq=msg.seq, state=msg.state,
                  values=list(msg.values))

    def on_command_state(self, msg: Any) -> None:
        if msg.module == self.command_module and msg.port == "command":
            self.emit("state", seq=msg.seq, state=msg.state, reason=msg.reason)

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
        while not self.no_more.is_set():
            how = plan(self.number, self.short_every, self.short_validity, self.cancel_every)
            try:
                reply = rospy.ServiceProxy(service, SendCommand)(
                    command="count", words=[], numbers=[float(self.number)], text="",
                    validity=how.validity)
            except (rospy.ServiceException, rospy.ROSException, OSError) as exc:
                # The call may or may not have reached the gateway: its log tells.
                self.emit("failed", n=self.number, error=str(exc).splitlines()[0][:200])
                self.no_more.wait(0.5)
                continue
            if not reply.ok:
                self.emit("refused", n=self.number, message=reply.message)
                self.no_more.wait(0.5)
                continue
            self.emit("sent", n=self.number, seq=reply.seq, validity=how.validity,
                      cancel=how.cancel)
            if how.cancel:
                self.cancel(self.number, reply.seq)
            self.number += 1
            self.no_more.wait(self.interval)
        self.emit("drained", next=self.number)

    def cancel(self, number: int, seq: int) -> None:
        """Take back command ``seq``; what the gateway answered (or why it could not)."""
        import rospy
        from walkman_msgs.srv import Cancel

        try:
            reply = rospy.ServiceProxy(f"/{self.command_module}/cancel", Cancel)(seq=seq)
        except (rospy.ServiceException, rospy.ROSException, OSError) as exc:
            # Taken back or not, unknown here: the pilot bridge's log says.
            self.emit("cancel", n=number, seq=seq, ok=False, cancelled=[],
                      error=str(exc).splitlines()[0][:200])
            return
        self.emit("cancel", n=number, seq=seq, ok=reply.ok, cancelled=list(reply.cancelled),
                  message=reply.message)


def main(argv: Optional[List[str]] = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m system.chaos_pilot",
                                     description=__doc__.split("\n")[0])
    parser.add_argument("--modules", required=True,
                        help="modules to watch and keep running (comma separated)")
    parser.add_argument("--command", required=True, help="the module to send count N to")
    parser.add_argument("--interval", type=float, default=0.5,
                        help="seconds between two accepted commands (default 0.5)")
    parser.add_argument("--first", type=int, default=1, help="first N (default 1)")
    parser.add_argument("--short-every", type=int, default=0,
                        help="every K-th command short-lived (default 0: none)")
    parser.add_argument("--short-validity", type=float, default=3.0,
                        help="their validity in seconds (default 3)")
    parser.add_argument("--cancel-every", type=int, default=0,
                        help="cancel every K-th command once accepted (default 0: none)")
    options = parser.parse_args(argv)
    from nodekit.ros_node import RosNode
    from nodekit.msgs import ensure_importable

    ensure_importable()
    modules = [m.strip() for m in options.modules.split(",") if m.strip()]
    pilot = Pilot(modules, options.command, options.interval, options.first,
                  options.short_every, options.short_validity, options.cancel_every)

    def finish(*_) -> None:
        pilot.no_more.set()
        pilot.stop.set()

    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, finish)
    signal.signal(signal.SIGUSR1, lambda *_: pilot.no_more.set())
    node = RosNode("chaos_pilot")
    node.when_ready(pilot.subscribe)
    node.start()
    while not node.ready.wait(0.5):
        if pilot.stop.is_set():
            return 0
    threading.Thread(target=pilot.keep_running, name="keep running", daemon=True).start()
    pilot.command_loop()
    while not pilot.stop.wait(0.5):   # drained: still watching until told to end
        pass
    node.stop()
    return 0


if __name__ == "__main__":
    sys.exit(main())
