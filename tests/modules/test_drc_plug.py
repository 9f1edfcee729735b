"""drc_plug end to end: the HAL at the plug table, the module as a process, yarp-lite write.

Done when the plug, pulled from socket a and pushed into socket b, stands in socket b
after the hand let it go -- read from the simulator's world, not from the module.
"""

import math

import pytest

from walkman.model.mjcf import PILOT_POSES, PLUG_SOCKETS, plug_in_socket


def test_the_plug_goes_from_one_socket_into_the_other(task_at):
    plug = task_at("plug", "drc_plug")
    start = plug.scene.body_position("plug")
    assert start[:2] == pytest.approx(PLUG_SOCKETS["a"], abs=0.005)
    plug.command(PILOT_POSES["plug"], "ready")
    for command, state in (("reach", "reached"), ("approach", "approached"),
                           ("grasp", "grasped"), ("pull", "pulled")):
        plug.command(command, state)
    lifted = plug.scene.body_position("plug")
    assert lifted[2] > start[2] + 0.07, "the plug came out of socket a with the hand"
    for command, state in (("move_to_socket", "over_socket"), ("insert", "inserted"),
                           ("ungrasp", "ungrasped"), ("move_away", "moved_away")):
        plug.command(command, state)
    placed = plug.scene.body_position("plug")
    assert plug_in_socket(placed, "b"), f"not standing in socket b: {placed}"
    assert plug.scene.upright("plug") > math.cos(math.radians(10))


def test_a_socket_the_hand_cannot_reach_is_refused_before_anything_moves(task_at):
    plug = task_at("plug", "drc_plug")
    plug.send("command", "plugdatasent 0.62 0.30 -0.045 0 0 0 0.45 0")   # 1.07 m ahead
    plug.pilot.wait_warning("cannot reach the plug's over point", 30)
    plug.pilot.wait_state("refused", 10)
    plug.send("command", "reach")                        # nothing was aimed at
    plug.pilot.wait_warning("reach", 30)
    assert plug.scene.body_position("plug")[:2] == pytest.approx(PLUG_SOCKETS["a"], abs=0.005)
