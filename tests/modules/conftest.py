"""Task modules as processes: the HAL (MuJoCo) at a station, the module, a pilot, the scene."""

import math

import mujoco
import pytest

from tests.walkman.test_gym_hal import Pilot, start_hal, start_module
from walkman.gym.runner import load_module_class
from walkman.hal import protocol
from walkman.model import SCENE_PATH
from yarp_lite.buffered_port import BufferedPort
from yarp_lite.nameclient import NameClient


class World:
    """The simulator's scene state, as the HAL publishes it (``/walkman/sim/world:o``)."""

    def __init__(self) -> None:
        self.model = mujoco.MjModel.from_xml_path(str(SCENE_PATH))
        self.port = BufferedPort("/test/world:i")
        NameClient().subscribe(protocol.world_port_name("walkman"), self.port.name)
        assert self.port.wait_for_inputs(1, 20)

    def prop(self, joint: str) -> float:
        """A scene joint's position: ``valve``, ``steering``, ``throttle``, ``door``..."""
        bottle = self.port.read(timeout=5)
        values = protocol.decode_world(bottle, self.model.nq)[1]
        return values[self.model.joint(joint).qposadr[0]]

    def base(self) -> list:
        """The pelvis in the world: x, y, z, yaw (ground truth)."""
        bottle = self.port.read(timeout=5)
        values = protocol.decode_world(bottle, self.model.nq)[1]
        adr = self.model.joint("base").qposadr[0]
        x, y, z, w, _, _, qz = values[adr:adr + 7]
        return [x, y, z, 2.0 * math.atan2(qz, w)]

    def close(self) -> None:
        self.port.close()


class Task:
    """A started task module, piloted the way a user does: ``yarp-lite write``."""

    def __init__(self, world, lite, name: str, scene: World) -> None:
        self.name, self.scene = name, scene
        self.pilot = Pilot(world, name, load_module_class(name).statuses)
        self.send = lambda port, line: self.pilot.send(lite, port, line)

    def command(self, line: str, state: str, timeout: float = 40.0) -> None:
        self.send("command", line)
        self.pilot.wait_state(state, timeout)

    def close(self) -> None:
        self.pilot.close()


@pytest.fixture
def task_at(lite_world, lite):
    """``task_at(station, module)``: HAL at a station of the scene, the module started."""
    made = []

    def start(station: str, name: str, *hal_options: str) -> Task:
        if not made:
            start_hal(lite_world, "sim", "--station", station, *hal_options)
            made.append(World())
        start_module(lite_world, name).wait_for("ready for the pilot", timeout=60)
        task = Task(lite_world, lite, name, made[0])
        made.append(task)
        task.send("switch", "start")
        task.pilot.wait_state("idle", 30)
        return task

    yield start
    for thing in made:
        thing.close()

