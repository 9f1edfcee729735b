"""The PI's ROS link: what it refuses to send rather than lose.

The link's publishers are stood in for here (one rospy node per process, and the
test process must not become one); the GUI tests drive the real ones.
"""

from __future__ import annotations

from typing import List

from pilot.link import PilotLink, _Sender
from rosnodes.msgs import ensure_importable

ensure_importable()          # walkman_msgs, built as the PI builds it


class Publisher:
    def __init__(self, connections: int) -> None:
        self.connections = connections
        self.published: List = []

    def get_num_connections(self) -> int:
        return self.connections

    def publish(self, msg) -> None:
        self.published.append(msg)


def link_with(switch: Publisher, command: Publisher) -> PilotLink:
    link = PilotLink("pi_test", ["gaze_control"], post=lambda event: None)
    link._senders["gaze_control"] = _Sender(switch, command)
    return link


def test_a_command_no_gateway_listens_to_is_refused_not_dropped():
    switch, command = Publisher(1), Publisher(0)
    link = link_with(switch, command)
    problem = link.command("gaze_control", "look_at", [1.0, 0.2, 0.1])
    assert "no gateway listens to /gaze_control/command" in problem
    assert "nothing was sent" in problem
    assert command.published == []
    assert link.switch("gaze_control", "start") == ""
    assert [m.command for m in switch.published] == ["start"]


def test_a_switch_no_gateway_listens_to_is_refused_and_a_listened_command_leaves():
    switch, command = Publisher(0), Publisher(1)
    link = link_with(switch, command)
    assert "no gateway listens to /gaze_control/switch" in link.switch("gaze_control", "start")
    assert switch.published == []
    assert link.command("gaze_control", "look_at", [1.0, 0.2, 0.1]) == ""
    assert [(m.command, list(m.numbers), m.sender) for m in command.published] == \
        [("look_at", [1.0, 0.2, 0.1], "pi_test")]


def test_before_the_roscore_nothing_can_leave():
    link = PilotLink("pi_test", ["gaze_control"], post=lambda event: None)
    assert "not connected to the pilot roscore" in link.command("gaze_control", "look_at", [1])
    assert "not connected to the pilot roscore" in link.switch("gaze_control", "start")


def test_cannot_send_names_the_first_topic_no_gateway_listens_to():
    link = link_with(Publisher(1), Publisher(0))
    assert "/gaze_control/command" in link.cannot_send("gaze_control")
    link = link_with(Publisher(0), Publisher(1))
    assert "/gaze_control/switch" in link.cannot_send("gaze_control")
    assert link_with(Publisher(1), Publisher(1)).cannot_send("gaze_control") == ""
