"""``walkman-joint-state``: the HAL's joints as ``sensor_msgs/JointState`` and TF.

Runs on either PC: it reads the whole-body state from the local name server
(the HAL on the robot; on the pilot, the bridge's copy of the HAL's ports, in
the Table 1 resolution) and publishes on the local roscore:

* ``/joint_states`` -- names, positions, velocities, efforts: each new reading,
  at most ``--rate`` Hz (50 on the robot; on the pilot, as often as the bridge
  brings the state: every period T);
* ``/tf`` -- every link of the model in the ``pelvis`` frame (forward
  kinematics with Pinocchio on ``models/walkman.urdf``) and the camera's optical
  frame (perception's cloud), so RViz or ``tf_echo`` can place the robot;
* ``/joint_temperatures`` -- ``walkman_msgs/JointTemperatures``, once a second;
* ``/battery`` -- ``sensor_msgs/BatteryState``, as the HAL's ``batteryWrapper`` stream
  brings it (once a second; on the robot only: the bridge carries the topic);
* the ``/robot_description`` parameter (the URDF), as ``robot_state_publisher``
  sets it, for RViz's RobotModel -- set again after a roscore restart.
"""

from __future__ import annotations

import argparse
import logging
import sys
import threading
import time

import numpy as np

from nodekit import tf
from walkman.head_camera import OPTICAL_ROTATION
from walkman.model import URDF_PATH

log = logging.getLogger("walkman.joint_state")


def robot_tf(kinematics, q: np.ndarray, now):
    """``/tf``: every link in the pelvis frame, and the camera's optical frame."""
    optical = tf.transform("multisense_frame", "multisense_optical_frame", (0, 0, 0),
                           OPTICAL_ROTATION, now)   # the camera's optical frame: z ahead, y down
    return tf.tf_message(kinematics.link_placements(q), now, extra=[optical])


def publish_slow(publisher, robot, now) -> None:
    """Temperatures, and ``/robot_description`` when the master lacks it (a new roscore)."""
    import rospy
    from walkman_msgs.msg import JointTemperatures

    msg = JointTemperatures(name=list(robot.joint_names),
                            celsius=robot.sense_temperature().tolist())
    msg.header.stamp = now
    publisher.publish(msg)
    try:
        if not rospy.has_param("/robot_description"):
            rospy.set_param("/robot_description", URDF_PATH.read_text())
    except (OSError, ConnectionError) as exc:
        log.warning("joint state: cannot set /robot_description: %s", exc)


def battery_state(values, stamp):
    """``sensor_msgs/BatteryState`` of a ``batteryWrapper`` reading (None if malformed)."""
    from sensor_msgs.msg import BatteryState

    from walkman.hal.battery import CAPACITY_WH, FULL_V, decode_reading

    try:
        reading = decode_reading(list(values))
    except ValueError as exc:
        log.warning("joint state: battery: %s", exc)
        return None
    msg = BatteryState(voltage=reading.voltage, current=-reading.current,  # discharging: < 0
                       percentage=reading.charge / 100.0, temperature=reading.temperature,
                       design_capacity=CAPACITY_WH / FULL_V, present=True,
                       power_supply_status=BatteryState.POWER_SUPPLY_STATUS_DISCHARGING,
                       power_supply_technology=BatteryState.POWER_SUPPLY_TECHNOLOGY_LION,
                       location=f"yarp status {int(reading.status)}")
    msg.charge = msg.design_capacity * msg.percentage
    msg.capacity = msg.design_capacity
    msg.header.stamp = stamp
    return msg


def follow_battery(robot: str, publishers) -> "tuple":
    """A port that publishes each battery reading of the HAL on ``/battery``."""
    from nodekit.connections import ConnectionKeeper
    from walkman.hal.protocol import battery_port_name
    from yarp_lite.port import Port

    def on_reading(bottle) -> None:
        import rospy

        if "battery" in publishers:
            msg = battery_state(bottle, rospy.Time.now())
            if msg is not None:
                publishers["battery"].publish(msg)

    port = Port(reader=on_reading)
    port.open(f"/joint_state/{robot}/battery:i", wait=float("inf"))
    keeper = ConnectionKeeper(period=1.0)
    keeper.want(battery_port_name(robot), port.name, port, ours_is_source=False)
    keeper.start()
    return port, keeper


def main(argv=None) -> int:
    options = _arguments(argv)
    from nodekit.logs import configure_logging

    configure_logging("joint_state", False)
    from nodekit.msgs import ensure_importable
    from nodekit.ros_node import RosNode
    from walkman.control.kinematics import Kinematics
    from walkman.hal.protocol import state_interval
    from walkman.hal.robot import Robot

    kinematics = None if options.no_tf else Kinematics()
    ros = RosNode("walkman_joint_state")
    publishers: dict = {}
    ensure_importable()
    ros.when_ready(lambda: publishers.update(_topics(options.battery, kinematics is not None)))
    ros.start()
    robot = Robot("/joint_state", robot=options.robot, connect_timeout=float("inf"),
                  state_interval=state_interval(1.0 / options.rate), sensors=False)
    log.info("joint state: reading %d joints of /%s", len(robot.joint_names), options.robot)
    battery = follow_battery(options.robot, publishers) if options.battery else None
    stop = threading.Event()
    import signal

    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    _publish_until(stop, robot, publishers, kinematics, options.rate)
    if battery is not None:
        battery[1].stop()
        battery[0].close()
    robot.close()
    ros.stop()
    return 0


def _arguments(argv) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="walkman-joint-state",
                                     description="The HAL's joints as JointState and TF.")
    parser.add_argument("--robot", default="walkman")
    parser.add_argument("--rate", type=float, default=50.0, help="Hz (default 50)")
    parser.add_argument("--no-tf", action="store_true", help="only /joint_states")
    parser.add_argument("--no-battery", dest="battery", action="store_false",
                        help="no /battery (the pilot's copy: the bridge brings the robot's)")
    options = parser.parse_args(argv)
    if not 0 < options.rate <= 500:
        parser.error("--rate must be in (0, 500]")
    return options


def _topics(battery: bool, tf: bool) -> dict:
    """The node's publishers, opened once the ROS side is up."""
    import rospy
    from sensor_msgs.msg import JointState
    from walkman_msgs.msg import JointTemperatures

    publishers = {"joints": rospy.Publisher("/joint_states", JointState, queue_size=5),
                  "temperatures": rospy.Publisher("/joint_temperatures", JointTemperatures,
                                                  queue_size=2)}
    if battery:
        from sensor_msgs.msg import BatteryState

        publishers["battery"] = rospy.Publisher("/battery", BatteryState, queue_size=2)
    if tf:
        from tf2_msgs.msg import TFMessage

        publishers["tf"] = rospy.Publisher("/tf", TFMessage, queue_size=5)
    return publishers


def _publish_until(stop: threading.Event, robot, publishers: dict, kinematics,
                   rate: float) -> None:
    """Each new state read at ``rate`` as /joint_states, /tf at 10 Hz, the temperatures once
    a second, until ``stop``."""
    tf_every = max(1, int(round(rate / 10)))  # TF at 10 Hz is plenty for display
    tick, published_seq, slow_at = 0, 0, 0.0
    while not stop.wait(1.0 / rate):
        if not publishers or robot.last_seq == published_seq:
            continue
        published_seq = robot.last_seq
        import rospy
        from sensor_msgs.msg import JointState

        now = rospy.Time.now()
        if time.monotonic() >= slow_at:     # once a second: temperatures, the description
            slow_at = time.monotonic() + 1.0
            publish_slow(publishers["temperatures"], robot, now)
        q = robot.sense_position()
        msg = JointState(name=list(robot.joint_names), position=q.tolist(),
                         velocity=robot.sense_velocity().tolist(),
                         effort=robot.sense_torque().tolist())
        msg.header.stamp = now
        publishers["joints"].publish(msg)
        tick += 1
        if "tf" in publishers and tick % tf_every == 0:
            publishers["tf"].publish(robot_tf(kinematics, q, now))


if __name__ == "__main__":
    sys.exit(main())
