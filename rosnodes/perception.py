"""``walkman-perception``: the head camera of the simulated robot, on the robot's roscore.

A plain ROS node around :class:`walkman.head_camera.HeadCamera` (the same camera
the ``perception`` GYM module drives, for a pilot to start, pause and retarget):

=================================  ============================================
``/multisense/left/image_color``   ``sensor_msgs/Image`` rgb8
``/multisense/depth``              ``sensor_msgs/Image`` 32FC1, metres, NaN = sky
``/multisense/left/camera_info``   ``sensor_msgs/CameraInfo`` (pinhole from fovy)
``/multisense/points``             ``sensor_msgs/PointCloud2`` organized, xyz + rgb,
                                   one point every ``--cloud-step`` pixels
=================================  ============================================

Every 10 s the node logs the rate it delivered and the median time of each
stage (render, cloud, messages, publish).
"""

from __future__ import annotations

import argparse
import logging
import os
import sys
import threading
import time

from walkman.head_camera import FrameClock, HeadCamera, topics

log = logging.getLogger("walkman.perception")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="walkman-perception",
                                     description="The simulated head camera as ROS topics.")
    parser.add_argument("--robot", default="walkman")
    parser.add_argument("--rate", type=float, default=2.0, help="frames per second (default 2)")
    parser.add_argument("--width", type=int, default=320)
    parser.add_argument("--height", type=int, default=240)
    parser.add_argument("--cloud-step", type=int, default=4,
                        help="one cloud point every N pixels (default 4)")
    options = parser.parse_args(argv)
    if not 0 < options.rate <= 30 or options.width < 16 or options.height < 16 or \
            options.cloud_step < 1:
        parser.error("need 0 < rate <= 30, width and height >= 16, cloud-step >= 1")
    os.environ.setdefault("MUJOCO_GL", "osmesa")
    from nodekit.logs import configure_logging

    configure_logging("perception", False)
    from nodekit.connections import ConnectionKeeper
    from nodekit.ros_node import RosNode

    node = HeadCamera(options.robot, options.rate, options.width, options.height,
                      options.cloud_step)
    ros = RosNode("walkman_perception")
    publishers = {}

    def open_topics() -> None:
        publishers.update(topics())

    ros.when_ready(open_topics)
    ros.start()
    keeper = ConnectionKeeper()
    node.open_yarp(keeper)
    keeper.start()
    stop = threading.Event()
    import signal

    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    said = 0.0
    frames_due = FrameClock(options.rate)
    while not stop.wait(frames_due.wait()):
        if not publishers:
            continue
        import rospy

        if not node.publish(publishers, rospy.Time.now()):
            if time.monotonic() - said > 10:
                log.info("perception: waiting for /%s/sim/world:o (is walkman-hal running "
                         "the sim?)", options.robot)
                said = time.monotonic()
            continue
        progress = node.progress()
        if progress:
            log.info("perception: %s", progress)
    keeper.stop()
    node.camera.close()
    ros.stop()
    return 0


if __name__ == "__main__":
    sys.exit(main())
