"""``walkman-ros-clock``: the robot's simulated time on ROS's ``/clock``, as gazebo_ros publishes it.

It follows the robot's YARP clock (``walkman-hal --clock``, ``--source``) and publishes
``rosgraph_msgs/Clock`` on ``/clock`` whenever the robot's time moved, at most every
``--period`` of wall time (so at ``--rtf max`` ROS is not flooded), and always the time it
stopped at, latched: a paused robot stops ROS time exactly where it stands, for a node that
subscribes later too.  With ``--use-sim-time`` it sets ``/use_sim_time`` first: ROS nodes
started after it follow ``/clock`` (``rospy.Time.now``, ``rospy.sleep``, ``Rate``), their bags
and RViz show robot time.  Its own ROS time is never used: it is the clock's source.
"""

from __future__ import annotations

import argparse
import logging
import signal
import sys
import threading
from typing import List, Optional

from yarp_lite.contact import is_valid_port_name

log = logging.getLogger("walkman.ros_clock")


def main(argv: Optional[List[str]] = None) -> int:
    parser = argparse.ArgumentParser(prog="walkman-ros-clock", description=__doc__.split("\n\n")[0])
    parser.add_argument("--source", default="/clock",
                        help="the robot's YARP clock port (default /clock)")
    parser.add_argument("--period", type=float, default=10.0, metavar="MS",
                        help="publish the newest time at most every MS milliseconds of wall "
                             "time (default 10)")
    parser.add_argument("--use-sim-time", action="store_true",
                        help="set /use_sim_time true on the master before publishing")
    options = parser.parse_args(argv)
    if not is_valid_port_name(options.source):
        parser.error(f"--source {options.source!r}: a YARP port name starts with '/'")
    if not 0.1 <= options.period <= 10_000:
        parser.error(f"--period {options.period:g}: from 0.1 to 10000 ms")
    from nodekit.logs import configure_logging
    from nodekit.ros_node import RosNode
    from yarp_lite.time import NetworkClock

    configure_logging("ros_clock", False)
    ros = RosNode("walkman_ros_clock")
    publisher = []

    def open_topic() -> None:
        import rospy
        from rosgraph_msgs.msg import Clock

        if options.use_sim_time:
            rospy.set_param("/use_sim_time", True)
        # Latched: a node that subscribes while the robot is paused (no new time to publish)
        # gets the time it stands at, instead of reading 0 ("no clock yet") until it moves.
        publisher.append(rospy.Publisher("/clock", Clock, queue_size=1, latch=True))
        log.info("publishing %s on ROS's /clock, at most every %g ms",
                 options.source, options.period)

    ros.when_ready(open_topic)
    ros.start()
    clock = NetworkClock(options.source).open()
    stop = threading.Event()

    def end(*_) -> None:
        stop.set()

    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, end)
    import rospy
    from rosgraph_msgs.msg import Clock

    published = None
    while not stop.wait(options.period / 1000.0):
        now = clock.now()
        if publisher and now != published:
            publisher[0].publish(Clock(clock=rospy.Time.from_sec(now)))
            published = now
    clock.close()
    ros.stop()
    return 0


if __name__ == "__main__":
    sys.exit(main())
