"""A GYM module that writes down every command it executes.  For the bridge tests.

Run as ``walkman-module counting_module:Module --name counter`` with this
folder on PYTHONPATH and ``COUNTER_LOG`` naming the file to append to.
"""

import os

from walkman.gym.thread import GenericThread


class Module(GenericThread):
    statuses = ["idle", "counting"]
    #: A witness of exactly-once delivery: commands held through long outages must still run
    #: (validity itself is tested with modules that keep the default).
    command_validity = 3600.0

    def custom_init(self) -> bool:
        self.log = open(os.environ["COUNTER_LOG"], "a", buffering=1)
        self.status_interface.set_status("idle")
        return True

    def run(self) -> None:
        command = self.command_interface.get_command()
        if command is None:
            return
        self.log.write(f"executed {command.name} {command.seq}\n")
        self.log.flush()
        os.fsync(self.log.fileno())
        self.status_interface.set_status("counting", command.seq)
