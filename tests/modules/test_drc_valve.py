"""drc_valve end to end: HAL (MuJoCo) and the module as processes, piloted with yarp-lite write.

Done when the sim valve turns by the commanded angle within 10 %.
"""

import math

import mujoco
import pytest

from tests.walkman.test_gym_hal import Pilot, start_hal, start_module
from harness import wait_until
from walkman.hal import protocol
from walkman.model import SCENE_PATH
from walkman.modules.drc_valve import Module
from yarp_lite.buffered_port import BufferedPort
from yarp_lite.nameclient import NameClient

VALVE = "valvedatasent 0.66 0.25 0.08 0 0 0 0.15"  # where models/walkman_drc.xml puts it


class World:
    """The simulator's scene state, as the HAL publishes it."""

    def __init__(self) -> None:
        model = mujoco.MjModel.from_xml_path(str(SCENE_PATH))
        self.size = model.nq
        self.valve = model.joint("valve").qposadr[0]
        self.port = BufferedPort("/test/world:i")
        NameClient().subscribe(protocol.world_port_name("walkman"), self.port.name)
        assert self.port.wait_for_inputs(1, 20)

    def valve_angle(self) -> float:
        bottle = self.port.read(timeout=5)
        return protocol.decode_world(bottle, self.size)[1][self.valve]

    def close(self) -> None:
        self.port.close()


@pytest.fixture
def valve_task(lite_world, lite):
    start_hal(lite_world, "sim")
    module = start_module(lite_world, "drc_valve")
    module.wait_for("ready for the pilot", timeout=60)
    pilot = Pilot(lite_world, "drc_valve", Module.statuses)
    world = World()
    send = lambda port, line: pilot.send(lite, port, line)  # noqa: E731
    send("switch", "start")
    pilot.wait_state("idle", 30)
    yield pilot, world, send
    world.close()
    pilot.close()


def test_the_valve_turns_by_the_commanded_angle(valve_task):
    pilot, world, send = valve_task
    send("command", VALVE)
    pilot.wait_state("ready")
    for command, state in (("reach", "reached"), ("approach", "approached"),
                           ("grasp", "grasped")):
        send("command", command)
        pilot.wait_state(state, 40)
    before = world.valve_angle()
    send("command", "turn 1.5708")
    wait_until(lambda: pilot.state() == "turning", 10, message="turning")
    pilot.wait_state("grasped", 40)
    turned = world.valve_angle() - before
    assert turned == pytest.approx(math.pi / 2, rel=0.10), turned
    for command, state in (("ungrasp", "ungrasped"), ("move_away", "moved_away"),
                           ("home", "idle")):
        send("command", command)
        pilot.wait_state(state, 40)
    # Released: the valve stays where it was turned.
    assert world.valve_angle() - before == pytest.approx(turned, abs=0.1)


def test_illegal_commands_and_bad_poses_are_refused_and_nothing_moves(valve_task):
    pilot, world, send = valve_task
    send("command", "grasp")
    pilot.wait_warning("'grasp' is not accepted in state idle")
    send("command", "action_done")  # the module's own event, not the pilot's
    pilot.wait_warning("unknown command 'action_done'")
    send("command", "valvedatasent 0.66 0.25")
    pilot.wait_warning("takes 7 numbers (X Y Z ROLL PITCH YAW RADIUS), got 2")
    send("command", "valvedatasent 2.5 0.25 0.08 0 0 0 0.15")
    pilot.wait_warning("cannot reach the valve's reach point")
    assert pilot.state() in ("refused", "idle")
    send("command", VALVE)
    pilot.wait_state("ready")
    send("command", "turn 1")
    pilot.wait_warning("'turn' is not accepted in state ready")
    assert pilot.state() == "ready"
