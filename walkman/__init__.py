"""Walk-Man: the Generic YARP Module, the hardware abstraction layer, and the robot."""
