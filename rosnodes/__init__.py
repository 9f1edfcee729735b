"""ROS nodes of the pilot and perception layer (paper section 2.7).

* :mod:`gateway` -- ``walkman-pilot-gateway``: every GYM module's switch,
  command, status and warning as ROS topics and services on the pilot roscore;
  dangerous commands wait a countdown (:mod:`timed`).
* :mod:`perception` -- ``walkman-perception``: the simulated head camera (RGB,
  depth, point cloud) on the robot roscore.
* :mod:`joint_state` -- ``walkman-joint-state``: ``sensor_msgs/JointState`` and TF
  from the HAL's ports, on either side of the bridge.
* ``walkman_msgs/`` -- our ROS messages and services (:mod:`nodekit.msgs` generates their
  Python code: the bridge and the Pilot Interface need them too).
"""
