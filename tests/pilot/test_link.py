"""The PI's ROS link: what it refuses to send rather than lose.

The first test runs the link as the PI does -- its own process (one rospy node per
process), a real roscore, its real publishers -- with ``rostopic echo`` as the only
listener.  The rest stand its publishers in with counted fakes, for the cases a real
graph makes slow to set up.
"""

from __future__ import annotations

import sys
from typing import List

import pytest

from harness import YarpWorld, free_port, lite_implementation
from pilot.link import PilotLink, _Sender
from nodekit.msgs import ensure_importable
from system.processes import ROSCORE_READY
from system.topology import ros_environment

ensure_importable()          # walkman_msgs, built as the PI builds it


#: The PI's link in a process of its own: it says what each send returned, one per line.
LINK_PROCESS = """
import sys, threading, time
from pilot.link import PilotLink, RosEvent
ready = threading.Event()
link = PilotLink("pi_test", ["gaze_control"],
                 post=lambda event: ready.set() if isinstance(event, RosEvent) else None)
link.start()
ready.wait(60)
print("refused:", link.command("gaze_control", "look_at", [1.0, 0.2, 0.1]), flush=True)
sys.stdin.readline()                     # the test has started a listener
deadline = time.monotonic() + 30
while link.command("gaze_control", "look_at", [1.0, 0.2, 0.1]) and time.monotonic() < deadline:
    time.sleep(0.1)                      # until the listener is connected: nothing leaves before
print("sent:", link.command("gaze_control", "look_at", [1.0, 0.2, 0.1]), flush=True)
sys.stdin.readline()
link.close()
"""


@pytest.fixture
def ros_world(tmp_path):
    """``(world, env)``: a YARP name server and a real roscore, and the environment that
    finds both; closed after the test, even on failure."""
    world = YarpWorld(tmp_path / "yarp", lite_implementation())
    ros_port = free_port()
    env = {**world.env, **ros_environment(tmp_path, ros_port)}
    try:
        world.start_server()
        world.start(["roscore", "-p", str(ros_port)], "roscore", env=env) \
            .wait_for(ROSCORE_READY, 60)
        yield world, env
    finally:
        world.close()


def test_the_pi_link_sends_on_its_real_topics_only_to_a_listener(ros_world):
    world, env = ros_world
    link = world.start([sys.executable, "-c", LINK_PROCESS], "pilot link", stdin=True,
                       env=env)
    refused = link.wait_for(r"refused: (.*)", timeout=90).group(1)
    assert "no gateway listens to /gaze_control/command" in refused
    echo = world.start(["rostopic", "echo", "-n", "1", "/gaze_control/command"],
                       "rostopic echo", env=env)
    link.popen.stdin.write("go\n")
    link.popen.stdin.flush()
    assert link.wait_for(r"sent: (.*)", timeout=60).group(1).strip() == ""
    echo.wait_for(r"command: \"?look_at", timeout=30)
    assert "pi_test" in echo.output() and "1.0" in echo.output()
    link.popen.stdin.write("done\n")
    link.popen.stdin.flush()


#: The link in a process whose generated messages cannot be imported: it says why it is down.
FAILING_LINK_PROCESS = """
import queue, sys
sys.modules["walkman_msgs.msg"] = None
from pilot.link import PilotLink, RosEvent
events = queue.Queue()
link = PilotLink("pi_test", ["gaze_control"],
                 post=lambda event: events.put(event) if isinstance(event, RosEvent) else None)
link.start()
event = events.get(timeout=60)
print("event:", event.up, event.failed, flush=True)
print("refused:", link.command("gaze_control", "look_at", [1.0, 0.2, 0.1]), flush=True)
"""


def test_a_pi_link_whose_topics_cannot_open_tells_the_window_why(ros_world):
    world, env = ros_world
    link = world.start([sys.executable, "-c", FAILING_LINK_PROCESS], "pilot link", env=env)
    said = link.wait_for(r"event: (\w+) (.*)", timeout=90)
    assert said.group(1) == "False", link.output()
    assert said.group(2).startswith("PilotLink._open_topics raised ModuleNotFoundError"), \
        link.output()
    assert "walkman_msgs.msg" in said.group(2)
    assert "not connected" in link.wait_for(r"refused: (.*)", timeout=30).group(1)


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


# -- frames and what of them arrived -----------------------------------------------------------


def stamped(msg, secs: int = 1700000000, nsecs: int = 250):
    msg.header.stamp.secs, msg.header.stamp.nsecs = secs, nsecs
    return msg


def test_frames_are_posted_with_their_stamp_and_no_guess_about_loss():
    """A black sky or a cloud without depth is content: the link posts the frame as it is."""
    import numpy as np
    from sensor_msgs.msg import Image, PointCloud2

    from pilot.link import CloudEvent, ImageEvent

    events = []
    link = PilotLink("pi_test", [], post=events.append)
    link._on_image(stamped(Image(height=4, width=6, encoding="rgb8", step=18,
                                 data=bytes(4 * 6 * 3))))
    cloud = PointCloud2(height=2, width=3, point_step=16, row_step=48,
                        data=np.full(24, np.nan, np.float32).tobytes())
    link._on_cloud(stamped(cloud, nsecs=500))
    image, points = events
    assert isinstance(image, ImageEvent) and image.stamp_ns == 1700000000 * 10**9 + 250
    assert image.rgb.shape == (4, 6, 3) and not image.rgb.any()
    assert isinstance(points, CloudEvent) and (points.points, points.stamp_ns) == \
        (6, 1700000000 * 10**9 + 500)


def test_the_bridges_report_becomes_an_event_naming_its_frame():
    from walkman_msgs.msg import Arrival, Region

    from pilot.link import CLOUD_TOPIC, arrival_event

    msg = stamped(Arrival(height=60, width=80, fraction=0.75, tiles=12, tiles_arrived=9,
                          missing=[Region(0, 0, 40, 30)]), nsecs=7)
    event = arrival_event(CLOUD_TOPIC, msg)
    assert (event.topic, event.stamp_ns, event.height, event.width, event.fraction,
            event.missing) == (CLOUD_TOPIC, 1700000000 * 10**9 + 7, 60, 80, 0.75,
                               ((0, 0, 40, 30),))


class ClosedPublisher(Publisher):
    """A publisher whose topic is gone (rospy shut down, or unregistered meanwhile)."""

    def publish(self, msg) -> None:
        import rospy

        raise rospy.ROSException("publish() to a closed topic")


def test_a_scene_edit_or_a_ghost_rospy_cannot_publish_is_said_not_raised(caplog):
    """Both are called from Qt slots (a marker's drag, the PI's timer), where an exception
    would abort the PI."""
    link = PilotLink("pi_test", ["gaze_control"], post=lambda event: None)
    assert "not connected to the pilot roscore" in link.place("drc_valve", "valve", [0] * 6)
    link.publish_ghost([("l_hand", (0, 0, 0), (0, 0, 0, 1))])        # before: nothing to do
    link._scene_edits, link._tf = ClosedPublisher(1), ClosedPublisher(1)
    assert "drc_valve not placed in the shared scene: publish() to a closed topic" in \
        link.place("drc_valve", "valve", [0.6, 0.2, 0.0, 0.0, 0.0, 0.0])
    link.publish_ghost([("l_hand", (0, 0, 0), (0, 0, 0, 1))])
    assert "the preview's ghost not published on /tf" in caplog.text
