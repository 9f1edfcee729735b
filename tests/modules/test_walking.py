"""walking: each command moves the robot's base at least 80 % of what was asked, on the
support harness's trolley (named in the README); pause finishes the step with both feet
down; and the paper's door sequence (walking paused, door module runs, walking resumed)."""

import math

import numpy as np
import pytest

from harness import wait_until
from walkman.gym.offline import OfflineWorld
from walkman.hal.sim import SimBackend
from walkman.modules import walking

HANDLE_PIVOT = np.array([0.84, 2.26, 1.15])  # world; models/walkman_drc.xml


def walker(station: str = "yard"):
    backend = SimBackend(station=station, harness="trolley")
    world = OfflineWorld(backend)
    world.step(0.5)
    module = world.add(walking.Module, "walking")
    module.switch("start")
    world.step(walking.CROUCH_TIME + 0.1)
    return world, module


def upright(backend) -> bool:
    roll, pitch, _ = backend.imu().rpy
    return abs(roll) < 0.1 and abs(pitch) < 0.1 and backend.plant.base_pose()[2] > 0.95


@pytest.mark.parametrize("command, axis, amount", [
    ("go_straight 1.0", 0, 1.0), ("go_straight -0.5", 0, -0.5), ("turn 0.8", 3, 0.8),
    ("turn -1.5", 3, -1.5), ("step_side 0.3", 1, 0.3), ("step_side -0.3", 1, -0.3)])
def test_the_base_moves_at_least_80_percent_without_falling(command, axis, amount):
    world, module = walker()
    before = np.array(world.backend.plant.base_pose())
    lowest = math.inf
    module.command(command)
    while module.state != "idle" or world.time < 3.0:
        world.step(0.1)
        assert upright(world.backend), world.backend.plant.base_pose()
        lowest = min(lowest, world.backend.plant.base_pose()[2])
        assert world.time < 60
    moved = np.array(world.backend.plant.base_pose()) - before
    assert 0.8 <= moved[axis] / amount <= 1.3, moved
    assert module.interfaces.data[{0: 0, 1: 1, 3: 2}[axis]] == pytest.approx(amount)


def test_pause_finishes_the_step_with_both_feet_down_and_resume_walks_the_rest():
    world, module = walker()
    backend = world.backend
    before = backend.plant.base_pose()[0]
    module.command("go_straight 1.0")
    world.step(1.0)  # in the first step's single support: a foot is up
    assert min(abs(backend.ft("l_leg_ft")[2]), abs(backend.ft("r_leg_ft")[2])) < 60
    assert not module.thread.ready_to_pause()
    module.switch("pause")
    assert module.state == "paused"
    world.step(0.5)
    for sensor in ("l_leg_ft", "r_leg_ft"):
        assert backend.ft(sensor)[2] < -100, sensor  # both feet carry weight
    here = backend.plant.base_pose()[0]
    world.step(3.0)
    assert abs(backend.plant.base_pose()[0] - here) < 0.03  # stays while paused
    module.switch("resume")
    world.run_until(lambda: module.state == "idle", 30, "the rest of the walk")
    assert backend.plant.base_pose()[0] - before >= 0.8


def test_bad_walks_are_refused_and_the_robot_holds():
    world, module = walker()
    before = world.backend.positions()
    for command, warning in (("go_straight 9", "go_straight takes 0.01..5 m"),
                             ("turn", "takes 1 numbers (ANGLE rad), got 0"),
                             ("step_side left", "'left' is not a finite number"),
                             ("jump 1", "unknown command 'jump'")):
        module.command(command)
        world.step(0.2)
        assert warning in module.warnings[-1], module.warnings
    assert np.abs(world.backend.positions() - before).max() < 0.01
    module.command("go_straight 0.3")
    world.step(0.2)
    module.command("turn 1")
    world.step(0.1)
    assert "'turn' is not accepted in state walking" in module.warnings[-1]


def pilot_door_pose(base) -> str:
    """What the perception pilot would send: the handle in the pelvis frame."""
    x, y, z, yaw = base
    rel = HANDLE_PIVOT - [x, y, z]
    c, s = math.cos(yaw), math.sin(yaw)
    return (f"doordatasent {c * rel[0] + s * rel[1]:.3f} {-s * rel[0] + c * rel[1]:.3f} "
            f"{rel[2]:.3f} 0 0 {-yaw:.3f} 0.09 0.6")


def test_the_door_sequence_as_processes(task_at):
    """Paper, section 3.3: walking paused and resumed around the door module."""
    walk = task_at("door_far", "walking", "--harness", "trolley")
    door = task_at("door_far", "drc_door")
    scene = walk.scene
    start = scene.base()
    walk.send("command", "go_straight 0.5")
    wait_until(lambda: walk.pilot.state() == "walking", 10, message="walking")
    walk.send("switch", "pause")
    walk.pilot.wait_state("paused", 10)
    walk.send("switch", "resume")
    walk.pilot.wait_state("idle", 40)
    assert scene.base()[0] - start[0] >= 0.4
    door.pilot.wait_warning("held by /walking")  # both running: the waist is walking's
    walk.send("switch", "pause")
    walk.pilot.wait_state("paused", 10)
    door.command(pilot_door_pose(scene.base()), "ready", 10)
    for command, state in (("reach", "reached"), ("approach", "approached"),
                           ("grasp", "grasped"), ("turn", "turned"), ("open", "opened"),
                           ("ungrasp", "ungrasped"), ("move_away", "moved_away"),
                           ("home", "idle")):
        door.command(command, state)
    assert math.degrees(scene.prop("door")) > 30
    door.send("switch", "stop")
    door.pilot.wait_state("stopped", 10)
    walk.send("switch", "resume")
    before = scene.base()[0]
    walk.command("go_straight 0.2", "walking", 10)
    walk.pilot.wait_state("idle", 30)
    assert scene.base()[0] - before >= 0.16
