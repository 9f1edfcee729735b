"""A module that does what modules must not: hangs, throws, sends NaN.  For tests only."""

import time

import numpy as np

from walkman.gym.thread import ControlThread


class Module(ControlThread):
    statuses = ["ok"]

    def custom_init(self) -> bool:
        self.status_interface.set_status("ok")
        return True

    def run(self) -> None:
        command = self.command_interface.get_command()
        if command is None:
            return
        if command.name == "hang":
            while True:  # ignores everything, forever
                time.sleep(0.01)
        if command.name == "throw":
            raise RuntimeError("deliberate failure")
        if command.name == "not_a_number":
            q = self.robot.sense_position()
            q[0] = np.nan
            self.robot.move(q)
        if command.name == "short":
            self.robot.move([0.0, 1.0])
        if command.name == "far":
            q = self.robot.sense_position()
            q[self.robot.index["NeckYawj"]] = 5.0  # beyond the 0.61 rad limit
            self.robot.move(q, joints=["NeckYawj"])
            self.status_interface.set_status("ok", float(self.robot.clamped))
