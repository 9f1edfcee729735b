"""Where the bridge meets the middlewares: YARP ports (:mod:`.yarp`) and ROS topics (:mod:`.ros`).

A *sink* takes messages from local programs and hands them to a channel; a
*source* gives what a channel received to local programs, under the original
names, so neither side can tell a bridge is in between.
"""
