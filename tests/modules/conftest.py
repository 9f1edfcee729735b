"""Task modules as processes: the HAL (MuJoCo) at a station, the module, a pilot, the scene."""

import pytest

from tests.modules.scene import World
from tests.walkman.test_gym_hal import Pilot, start_hal, start_module
from walkman.gym.runner import load_module_class


class Task:
    """A started task module, piloted the way a user does: ``yarp-lite write``."""

    def __init__(self, world, lite, name: str, scene: World, hal) -> None:
        self.name, self.scene, self.hal = name, scene, hal
        self.pilot = Pilot(world, name, load_module_class(name).statuses)
        self.send = lambda port, line: self.pilot.send(lite, port, line)

    def command(self, line: str, state: str, timeout: float = 40.0) -> None:
        self.send("command", line)
        self.pilot.wait_state(state, timeout)

    def close(self) -> None:
        self.pilot.close()


@pytest.fixture
def task_at(lite_world, lite):
    """``task_at(station, module)``: HAL at a station of the scene, the module started
    (``task.hal`` is the HAL's process: its log says what the simulated world did)."""
    made = []
    hals = []

    def start(station: str, name: str, *hal_options: str) -> Task:
        if not made:
            hals.append(start_hal(lite_world, "sim", "--station", station, *hal_options))
            made.append(World())
        start_module(lite_world, name).wait_for("ready for the pilot", timeout=60)
        task = Task(lite_world, lite, name, made[0], hals[0])
        made.append(task)
        task.send("switch", "start")
        task.pilot.wait_state("idle", 30)
        return task

    yield start
    for thing in made:
        thing.close()

