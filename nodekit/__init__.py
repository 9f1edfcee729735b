"""What every node of ours shares: the bridge, the ROS nodes and the Pilot Interface.

* :mod:`nodekit.ros_node` -- rospy's node, kept registered across roscore restarts;
* :mod:`nodekit.connections` -- YARP connections made and remade by themselves;
* :mod:`nodekit.logs` -- readable log lines on stderr, whatever rospy does to the root logger;
* :mod:`nodekit.link_watch` -- a bridge's status reduced to "is the link up" (the pilot
  gateway's ``/bridge/link``, a robot module's link-loss policy);
* :mod:`nodekit.msgs` -- the ``walkman_msgs`` ROS package's Python code, generated with genpy.
"""
