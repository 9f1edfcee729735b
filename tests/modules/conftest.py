"""Task modules as processes: the HAL (MuJoCo) at a station, the module, a pilot, the scene."""

import pytest

from tests.modules.scene import World
from tests.walkman.test_gym_hal import Pilot, start_hal, start_module
from walkman.gym.runner import load_module_class
from yarp_lite.bottle import Vocab
from yarp_lite.rpc import RpcClient


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


#: The HAL's and each module's options in a test marked ``lockstep``: the robot as fast as the
#: machine goes, started paused until the first module has joined its clock.
LOCKSTEP_HAL = ("--clock", "--rtf", "max", "--paused")
LOCKSTEP_MODULE = ("--lockstep",)


@pytest.fixture
def task_at(lite_world, lite, request):
    """``task_at(station, module)``: HAL at a station of the scene, the module started
    (``task.hal`` is the HAL's process: its log says what the simulated world did).  In a
    test marked ``lockstep`` the robot runs on the lockstep clock at ``--rtf max`` and every
    module joins it (walkman/gym/lockstep.py): the test no longer needs the machine alone."""
    made = []
    hals = []
    lockstep = request.node.get_closest_marker("lockstep") is not None

    def start(station: str, name: str, *hal_options: str) -> Task:
        if not made:
            hals.append(start_hal(lite_world, "sim", "--station", station, *hal_options,
                                  *(LOCKSTEP_HAL if lockstep else ())))
            made.append(World())
        start_module(lite_world, name, *(LOCKSTEP_MODULE if lockstep else ())).wait_for(
            "ready for the pilot", timeout=60)
        task = Task(lite_world, lite, name, made[0], hals[0])
        made.append(task)
        task.send("switch", "start")
        if lockstep and len(made) == 2:    # the first module: the robot waited for it
            hals[0].wait_for(f"lockstep: /{name} joined", timeout=60)
            clock = RpcClient(target="/clock/rpc")
            try:
                assert clock.call(["continueSimulation"]) == [Vocab("done")]
            finally:
                clock.close()
        task.pilot.wait_state("idle", 30)
        return task

    yield start
    for thing in made:
        thing.close()

