"""What the pilot gateway publishes on the pilot roscore, each message built in one place.

The gateway (:mod:`rosnodes.gateway`) decides; this holds its publishers and
turns its events into ``walkman_msgs``: per module ``/M/status`` (latched),
``/M/warning`` and ``/M/countdown``; ``/pilot/sent_commands``,
``/pilot/command_states`` and ``/bridge/link`` (latched).  Until :meth:`open`
(the ROS master not there yet) every call publishes nothing, so the YARP side
can run first; :meth:`open` is called again after a roscore restart.
"""

from __future__ import annotations

import logging
from typing import Any, Dict, Iterable, Optional, Sequence

from nodekit.link_watch import LinkState
from walkman.gym.command_life import CommandLife, CommandState, describe

log = logging.getLogger("walkman.gateway")

#: The lives a gateway also writes in its log: those that did not simply go ahead.
LOGGED_STATES = (CommandState.REFUSED, CommandState.EXPIRED, CommandState.CANCELLED,
                 CommandState.INTERRUPTED,
                 CommandState.QUEUED)


def status_msg(module: str, seq: int, state: str, code: str, data: Sequence[Any]) -> Any:
    """A module's status as ``walkman_msgs/Status``: its words, and its numbers apart."""
    import rospy
    from walkman_msgs.msg import Status

    msg = Status()
    msg.header.stamp = rospy.Time.now()
    msg.module, msg.seq, msg.state, msg.code = module, seq, state, code
    msg.data = " ".join(str(v) for v in data)
    msg.values = [float(v) for v in data
                  if isinstance(v, (int, float)) and not isinstance(v, bool)]
    return msg


class PilotTopics:
    """The gateway's publishers; each method publishes one message (nothing before
    :meth:`open`)."""

    def __init__(self, modules: Iterable[str]) -> None:
        self.modules = list(modules)
        self._per_module: Dict[str, Dict[str, Any]] = {}
        self._sent: Optional[Any] = None
        self._states: Optional[Any] = None
        self._link: Optional[Any] = None

    def open(self) -> None:
        import rospy
        from walkman_msgs.msg import CommandState as CommandStateMsg
        from walkman_msgs.msg import Countdown, Link, SentCommand, Status, Warning

        self._sent = rospy.Publisher("/pilot/sent_commands", SentCommand, queue_size=50)
        self._link = rospy.Publisher("/bridge/link", Link, queue_size=5, latch=True)
        self._states = rospy.Publisher("/pilot/command_states", CommandStateMsg,
                                       queue_size=200)
        for module in self.modules:
            self._per_module[module] = {
                "status": rospy.Publisher(f"/{module}/status", Status, queue_size=10,
                                          latch=True),
                "warning": rospy.Publisher(f"/{module}/warning", Warning, queue_size=20),
                "countdown": rospy.Publisher(f"/{module}/countdown", Countdown,
                                             queue_size=10)}

    def _publisher(self, module: str, topic: str) -> Optional[Any]:
        return self._per_module.get(module, {}).get(topic)

    def status(self, module: str, seq: int, state: str, code: str,
               data: Sequence[Any]) -> None:
        publisher = self._publisher(module, "status")
        if publisher is not None:
            publisher.publish(status_msg(module, seq, state, code, data))

    def warning(self, module: str, seq: int, text: str) -> None:
        publisher = self._publisher(module, "warning")
        if publisher is None:
            return
        import rospy
        from walkman_msgs.msg import Warning

        msg = Warning()
        msg.header.stamp = rospy.Time.now()
        msg.module, msg.seq, msg.text = module, seq, text
        publisher.publish(msg)

    def countdown(self, module: str, command: str, remaining: float, state: str,
                  sender: str) -> None:
        publisher = self._publisher(module, "countdown")
        if publisher is None:
            return
        import rospy
        from walkman_msgs.msg import Countdown

        msg = Countdown()
        msg.header.stamp = rospy.Time.now()
        msg.module, msg.command = module, command
        msg.remaining, msg.state = float(remaining), state
        msg.sender = sender or "rostopic"
        publisher.publish(msg)

    def command_states(self, lives: Iterable[CommandLife]) -> None:
        """Each life that changed (and, in the log, those that did not simply go ahead)."""
        for life in lives:
            if life.state in LOGGED_STATES:
                log.info("gateway: %s", describe(life))
            if self._states is None:
                continue
            import rospy
            from walkman_msgs.msg import CommandState as CommandStateMsg

            msg = CommandStateMsg()
            msg.header.stamp = rospy.Time.now()
            msg.module, msg.port, msg.seq, msg.text = life.module, life.port, life.seq, life.text
            msg.sender, msg.station = life.sender, life.station
            msg.state, msg.reason = life.state.value, life.reason
            self._states.publish(msg)

    def now(self):
        """The stamp the topics give (``rospy.Time``), or None before they are open: the
        gateway takes a command's before sending it, so the command's stamp and its
        receipt's come from one clock, in the order they happened."""
        if self._sent is None:
            return None
        import rospy

        return rospy.Time.now()

    def sent(self, module: str, port: str, text: str, seq: int, sender: str,
             station: int, sent_at: Optional[Any] = None) -> None:
        if self._sent is None:
            return
        import rospy
        from walkman_msgs.msg import SentCommand

        msg = SentCommand()
        msg.header.stamp = sent_at if sent_at is not None else rospy.Time.now()
        msg.module, msg.port, msg.text, msg.seq = module, port, text, seq
        msg.sender, msg.station = sender, station
        self._sent.publish(msg)

    def link(self, state: LinkState, since_s: float) -> None:
        if self._link is None:
            return
        import rospy
        from walkman_msgs.msg import Link

        msg = Link()
        msg.header.stamp = rospy.Time.now()
        msg.state, msg.reason, msg.queued = state.state.value, state.reason, state.queued
        msg.since = float(since_s)
        msg.round_trip_ms = float(state.round_trip_ms)
        self._link.publish(msg)
