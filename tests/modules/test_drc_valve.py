"""drc_valve end to end: HAL (MuJoCo) and the module as processes, piloted with yarp-lite write.

Done when the sim valve turns by the commanded angle within 10 %.
"""

import math

import pytest

from harness import wait_until
from walkman.model.mjcf import PILOT_POSES

VALVE = PILOT_POSES["valve"]


def test_the_valve_turns_by_the_commanded_angle(task_at):
    valve = task_at("valve", "drc_valve")
    valve.command(VALVE, "ready")
    for command, state in (("reach", "reached"), ("approach", "approached"),
                           ("grasp", "grasped")):
        valve.command(command, state)
    before = valve.scene.prop("valve")
    valve.send("command", "turn 1.5708")
    wait_until(lambda: valve.pilot.state() == "turning", 10, message="turning")
    valve.pilot.wait_state("grasped", 40)
    turned = valve.scene.prop("valve") - before
    assert turned == pytest.approx(math.pi / 2, rel=0.10), turned
    for command, state in (("ungrasp", "ungrasped"), ("move_away", "moved_away"),
                           ("home", "idle")):
        valve.command(command, state)
    # Released: the valve stays where it was turned (a hand backing off free to turn
    # dragged it back by 0.07-0.13 rad).
    assert valve.scene.prop("valve") - before == pytest.approx(turned, abs=0.03)


def test_illegal_commands_and_bad_poses_are_refused_and_nothing_moves(task_at):
    valve = task_at("valve", "drc_valve")
    pilot = valve.pilot
    valve.send("command", "grasp")
    pilot.wait_warning("'grasp' is not accepted in state idle")
    valve.send("command", "action_done")  # the module's own event, not the pilot's
    pilot.wait_warning("unknown command 'action_done'")
    valve.send("command", "valvedatasent 0.66 0.25")
    pilot.wait_warning("takes 7 numbers (X Y Z ROLL PITCH YAW RADIUS), got 2")
    valve.send("command", "valvedatasent 2.5 0.25 0.08 0 0 0 0.15")
    pilot.wait_warning("cannot reach the valve's reach point")
    assert pilot.state() in ("refused", "idle")
    valve.command(VALVE, "ready")
    valve.send("command", "turn 1")
    pilot.wait_warning("'turn' is not accepted in state ready")
    assert pilot.state() == "ready"
