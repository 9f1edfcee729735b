"""A task module on the simulated robot and its preview shadow, given the same commands
(tests/walkman/test_preview.py, tests/pilot/test_preview_gate.py)."""

from typing import Optional

import numpy as np

from walkman.gym.offline import OfflineWorld
from walkman.gym.preview import Shadow
from walkman.hal.sim import SimBackend


class Followed:
    """A module on the simulated robot and its shadow, given the same commands."""

    def __init__(self, station: str, module_class, name: str,
                 world: Optional[OfflineWorld] = None) -> None:
        """At ``station`` in the harness, or in ``world`` (a robot standing as it is there)."""
        self.world = world or OfflineWorld(SimBackend(station=station))
        self.module = self.world.add(module_class, name)
        assert self.module.switch("start")
        self.world.step(0.05)
        self.shadow = Shadow(module_class, name)

    @property
    def posture(self) -> np.ndarray:
        return self.world.backend.positions()

    def do(self, command: str, state: str) -> None:
        before, posture = self.module.thread.fsm.state, self.posture
        self.module.do(command, state, 40)
        self.shadow.follow(command, before, posture)

    def preview(self, command: str):
        return self.shadow.preview(command, self.module.thread.fsm.state, self.posture)
