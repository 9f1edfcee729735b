"""Two GYM modules for the link-loss policy's process test (tests/bridge/test_link_loss_policy.py).

Run as ``walkman-module link_loss_modules:Holder --name /holder`` (and ``:Ticker``)
with this folder on PYTHONPATH.
"""

from __future__ import annotations

from walkman.gym.link_loss import LinkLoss
from walkman.gym.thread import ControlThread, GenericThread
from walkman.modules.task import LEFT_ARM


class Holder(ControlThread):
    """Holds the left arm where it found it: a chain that gravity pulls down, so a HAL that
    let go of it (zero torque) would show at once in its joints.  Pauses 2 s into a cut."""

    statuses = ["holding"]
    joints = LEFT_ARM
    link_loss = LinkLoss.pause(after=2.0)

    def custom_init(self) -> bool:
        self.posture = self.robot.sense_position()
        self.status_interface.set_status("holding")
        return True

    def run(self) -> None:
        self.robot.move(self.posture, joints=self.joints)


class Ticker(GenericThread):
    """Says how many whole seconds it has been running: the link-loss policy left at its
    default (``continue``), it goes on counting through a cut."""

    statuses = ["ticking"]

    def custom_init(self) -> bool:
        self.started = self.now()
        return True

    def run(self) -> None:
        self.status_interface.set_status("ticking", int(self.now() - self.started))
