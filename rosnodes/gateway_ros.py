"""The pilot gateway's ROS face: its services and command topics, as ROS messages.

Theory of operation
-------------------
:class:`~rosnodes.gateway.Gateway` decides and sends; this module only turns ROS requests
into its calls and its answers into ROS responses, per module (``/M/switch``,
``/M/command``, ``/M/switch_and_wait``, ``/M/send_command``, ``/M/get_status``,
``/M/cancel``) and for the whole robot (``/pilot/stop_all``, ``/pilot/release``).  A topic's
message is handed to a sender thread of its module and topic (:meth:`Gateway.ask_switch`,
:meth:`Gateway.ask_command`): a rospy callback never waits for a module's connection.  A
service waits for its answer, as a ROS service does, in the thread rospy gives each call.
"""

from __future__ import annotations

import logging
from typing import Any, Dict, List, Mapping, Protocol

from rosnodes.module_link import ModuleLink, Sent
from rosnodes.pilot_topics import status_msg

log = logging.getLogger("walkman.gateway")


class Desk(Protocol):
    """What the face asks of the gateway (:class:`rosnodes.gateway.Gateway`), which imports
    this module: the face may not import it back."""

    modules: Mapping[str, List[str]]
    links: Dict[str, ModuleLink]

    def ask_switch(self, module: str, msg: Any) -> None: ...
    def ask_command(self, module: str, msg: Any) -> None: ...
    def switch_and_wait(self, module: str, word: str, timeout: float) -> Any: ...
    def send_request(self, module: str, request: Any) -> Sent: ...
    def stop_all(self, word: str) -> Any: ...
    def cancel(self, module: str, seq: int) -> Any: ...


class RosFace:
    """Every ROS service and command topic of one gateway."""

    def __init__(self, gateway: Desk) -> None:
        self.gateway = gateway

    def open(self) -> List[Any]:
        """Subscribe and advertise (once the node is registered); the handles, to keep."""
        import rospy
        from walkman_msgs.srv import StopAll

        return [rospy.Service("/pilot/stop_all", StopAll, lambda r: self.stop("stop_all")),
                rospy.Service("/pilot/release", StopAll, lambda r: self.stop("release")),
                *[handle for module in self.gateway.modules
                  for handle in self._open_module(module)]]

    def _open_module(self, module: str) -> List[Any]:
        import rospy
        from walkman_msgs.msg import Command, Switch
        from walkman_msgs.srv import Cancel, GetStatus, SendCommand, SwitchModule

        gateway = self.gateway
        return [rospy.Subscriber(f"/{module}/switch", Switch,
                                 lambda m: gateway.ask_switch(module, m)),
                rospy.Subscriber(f"/{module}/command", Command,
                                 lambda m: gateway.ask_command(module, m)),
                rospy.Service(f"/{module}/switch_and_wait", SwitchModule,
                              lambda r: self.switch_and_wait(module, r)),
                rospy.Service(f"/{module}/send_command", SendCommand,
                              lambda r: self.send_command(module, r)),
                rospy.Service(f"/{module}/get_status", GetStatus,
                              lambda r: self.get_status(module)),
                rospy.Service(f"/{module}/cancel", Cancel,
                              lambda r: self.cancel(module, r))]

    # -- the services ------------------------------------------------------------------

    def switch_and_wait(self, module: str, request: Any) -> Any:
        from walkman_msgs.srv import SwitchModuleResponse

        switched = self.gateway.switch_and_wait(module, request.command,
                                                float(request.timeout) or 5.0)
        return SwitchModuleResponse(switched.ok, switched.state, switched.message)

    def send_command(self, module: str, request: Any) -> Any:
        from walkman_msgs.srv import SendCommandResponse

        sent = self.gateway.send_request(module, request)
        return SendCommandResponse(sent.ok, sent.seq if sent.ok else 0, sent.message)

    def stop(self, word: str) -> Any:
        from walkman_msgs.srv import StopAllResponse

        stopped = self.gateway.stop_all(word)
        (log.warning if word == "stop_all" else log.info)("gateway: %s (%.0f ms)",
                                                           stopped.message, stopped.round_trip_ms)
        return StopAllResponse(stopped.ok, stopped.message, stopped.round_trip_ms,
                               stopped.robot_ms, stopped.paused)

    def cancel(self, module: str, request: Any) -> Any:
        from walkman_msgs.srv import CancelResponse

        outcome = self.gateway.cancel(module, int(request.seq))
        return CancelResponse(outcome.ok, outcome.numbers, outcome.message)

    def get_status(self, module: str) -> Any:
        from walkman_msgs.msg import Status
        from walkman_msgs.srv import GetStatusResponse

        link = self.gateway.links[module]
        heard = link.last_status
        if heard is None:
            return GetStatusResponse(False, "unknown", Status())
        return GetStatusResponse(True, link.lifecycle,
                                 status_msg(module, heard.seq, heard.state, heard.code,
                                            heard.data))
