"""The Pilot Interface (PI): the paper's operator GUI (section 2.7), Qt + librviz.

Qt-free layers first, so they are tested without a display:

* :mod:`pilot.catalogue` -- what each module offers a pilot (commands, their
  numbers, which are legal in which state, which count down);
* :mod:`pilot.layouts` -- named window layouts from a file;
* :mod:`pilot.link` -- the PI's ROS node: the gateway's topics, the robot's
  state, perception and the bridge's status, as plain callbacks;

then the widgets (:mod:`pilot.widgets`) and the window (:mod:`pilot.app`,
the ``walkman-pilot`` program).
"""
