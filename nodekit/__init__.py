"""What every node of ours shares: the bridge, the ROS nodes and the Pilot Interface.

* :mod:`nodekit.ros_node` -- rospy's node, kept registered across roscore restarts;
* :mod:`nodekit.connections` -- YARP connections made and remade by themselves;
* :mod:`nodekit.logs` -- readable log lines on stderr, whatever rospy does to the root logger.
"""
