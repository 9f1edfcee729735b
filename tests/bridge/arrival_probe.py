"""Prints what the pilot bridge publishes of each frame, and what it says arrived.  For tests.

``image SECS NSECS`` / ``cloud SECS NSECS`` for each frame, and for each
``walkman_msgs/Arrival`` on ``<topic>/arrived``:
``arrived image|cloud SECS NSECS FRACTION TILES ARRIVED X,Y,W,H;...`` (``-`` when
nothing is missing).  Run with the pilot's ROS_MASTER_URI.
"""

import sys
import threading

import rospy
from sensor_msgs.msg import Image, PointCloud2

from bridge.endpoints.ros import arrival_topic
from nodekit.msgs import ensure_importable

LOCK = threading.Lock()


def say(line: str) -> None:
    """One whole line at a time: the subscribers print from their own threads."""
    with LOCK:
        sys.stdout.write(line + "\n")
        sys.stdout.flush()


TOPICS = {"image": ("/multisense/left/image_color", Image),
          "cloud": ("/multisense/points", PointCloud2)}


def main() -> int:
    ensure_importable()
    from walkman_msgs.msg import Arrival

    rospy.init_node("test_arrival_probe")
    for kind, (topic, cls) in TOPICS.items():
        rospy.Subscriber(topic, cls, lambda msg, kind=kind: say(
            f"{kind} {msg.header.stamp.secs} {msg.header.stamp.nsecs}"),
            queue_size=20, buff_size=1 << 24)
        rospy.Subscriber(arrival_topic(topic), Arrival, lambda msg, kind=kind: say(
            f"arrived {kind} {msg.header.stamp.secs} {msg.header.stamp.nsecs} "
            f"{msg.fraction:.6f} {msg.tiles} {msg.tiles_arrived} "
            + (";".join(f"{r.x},{r.y},{r.width},{r.height}" for r in msg.missing) or "-")),
            queue_size=20)
    say("probe ready")
    rospy.spin()
    return 0


if __name__ == "__main__":
    sys.exit(main())
