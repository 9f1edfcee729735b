"""drc_door end to end, and two modules on the same joints through the HAL.

Done when the sim door opens past 30 degrees; the HAL refuses the second module's
commands for joints the first holds, and says so on the second's warning port.
"""

import math

from walkman.model.mjcf import PILOT_POSES

DOOR = PILOT_POSES["door"]


def test_the_door_opens_past_30_degrees(task_at):
    door = task_at("door", "drc_door")
    door.send("command", "open")
    door.pilot.wait_warning("'open' is not accepted in state idle")
    door.command(DOOR, "ready")
    for command, state in (("reach", "reached"), ("approach", "approached"),
                           ("grasp", "grasped"), ("turn", "turned"), ("open", "opened"),
                           ("ungrasp", "ungrasped"), ("move_away", "moved_away"),
                           ("home", "idle")):
        door.command(command, state)
    assert math.degrees(door.scene.prop("door")) > 30


def test_the_hal_refuses_a_second_module_on_held_joints(task_at):
    valve = task_at("door", "drc_valve")
    door = task_at("door", "drc_door")
    door.pilot.wait_warning("may not command")
    assert any("held by /drc_valve" in text for text in door.pilot.warnings)
    valve.send("switch", "pause")
    valve.pilot.wait_state("paused", 10)
    door.command(DOOR, "ready")
    door.command("reach", "reached")  # the valve module's joints are free again
