"""A module that senses and moves every tick (the neck follows a slow sine): the GYM benchmark load."""

import math
import time

from walkman.gym.thread import ControlThread


class Module(ControlThread):
    statuses = ["running"]

    def custom_init(self) -> bool:
        self.start = time.monotonic()
        self.index = self.robot.index["NeckYawj"]
        return True

    def run(self) -> None:
        q = self.robot.sense_position()
        q[self.index] = 0.3 * math.sin(time.monotonic() - self.start)
        self.robot.move(q, joints=["NeckYawj"])
