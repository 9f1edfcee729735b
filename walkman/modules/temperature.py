"""temperature: board temperatures to the pilot, seven joints a second, and warnings.

Table 1 of the paper budgets the temperatures at seven 16-bit values per
second.  Every second this module puts the next seven joints (round robin
over all 33) in its status, as ``index temperature_in_0.1_C`` pairs, and
warns once when a joint goes above ``warning_threshold`` (again only after
it cooled 2 C below it).
"""

from __future__ import annotations

from functools import lru_cache
from typing import List, Sequence

import numpy as np

from walkman.gym.link_loss import LinkLoss
from walkman.gym.thread import ControlThread
from walkman.model.description import walkman

PER_SECOND = 7
HYSTERESIS = 2.0


@lru_cache(maxsize=1)
def joint_names() -> List[str]:
    """The robot's joints in the HAL's order: what a status's joint index counts."""
    return walkman().joint_names


class Module(ControlThread):
    statuses = ["monitoring", "hot"]

    @classmethod
    def describe_status(cls, state: str, values: Sequence[float]) -> str:
        """``(joint index, tenths of a degree)`` pairs as ``LKneej 30.0 C``."""
        names = joint_names()
        pairs = list(zip(values[0::2], values[1::2]))
        if len(values) % 2 or any(not 0 <= index < len(names) or index != int(index)
                                  for index, _ in pairs):
            return super().describe_status(state, values)
        return ", ".join(f"{names[int(index)]} {tenths / 10:.1f} C" for index, tenths in pairs)
    # It only watches: its warnings wait in the robot bridge's queue for the pilot.
    link_loss = LinkLoss.CONTINUE

    def custom_init(self) -> bool:
        self.threshold = float(self.config.get("warning_threshold", 60.0))
        self.cursor = 0
        self.hot = np.zeros(len(self.robot.joint_names), dtype=bool)
        return True

    def run(self) -> None:
        temperatures = self.robot.sense_temperature()
        names = self.robot.joint_names
        for index in np.flatnonzero((temperatures > self.threshold) & ~self.hot):
            self.hot[index] = True
            self.warning_interface.warn(f"temperature: {names[index]} at "
                                        f"{temperatures[index]:.1f} C (limit {self.threshold:g} C)")
        self.hot &= temperatures > self.threshold - HYSTERESIS
        batch = [(self.cursor + k) % len(names) for k in range(PER_SECOND)]
        self.cursor = (self.cursor + PER_SECOND) % len(names)
        data = []
        for index in batch:
            data += [int(index), int(round(temperatures[index] * 10))]
        self.status_interface.set_status("hot" if self.hot.any() else "monitoring", *data)
