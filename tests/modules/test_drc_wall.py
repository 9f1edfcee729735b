"""drc_wall end to end: the HAL at the wall station, the module as a process, yarp-lite write.

Done when the HAL -- the simulated world -- says the circle is cut out of the drywall, and
the drill stands on its table again after the hand let it go (read from the world port).
"""

import math

import pytest

from walkman.model.mjcf import DRILL_GRIP, PILOT_POSES
from walkman.modules.drc_wall import TASK_STEPS

def test_the_drill_cuts_the_circle_and_is_put_back(task_at):
    wall = task_at("wall", "drc_wall")
    wall.command(PILOT_POSES["wall"], "ready")
    for command, state in TASK_STEPS[:-1]:
        wall.command(command, state, timeout=60)
        if command == "switch_on":
            wall.hal.wait_for("drill on$", timeout=10)
        if command == "cut":
            cut = wall.hal.wait_for(r"drywall: the circle is cut out \(360 degrees, largest "
                                    r"miss ([\d.]+) cm\)", timeout=10)
            assert float(cut.group(1)) < 1.5, cut.group(0)
    wall.hal.wait_for("drill off$", timeout=10)
    assert wall.scene.body_position("drill") == pytest.approx(DRILL_GRIP, abs=0.01)
    assert wall.scene.upright("drill") > math.cos(math.radians(5))


def test_a_push_into_the_wall_before_the_drill_runs_is_refused(task_at):
    wall = task_at("wall", "drc_wall")
    wall.command(PILOT_POSES["wall"], "ready")
    for command, state in TASK_STEPS[:4]:
        wall.command(command, state, timeout=60)
    wall.send("command", "to_wall")                  # the drill is off: not from 'lifted'
    wall.pilot.wait_warning("to_wall", 30)
    wall.send("command", "push_in")
    wall.pilot.wait_warning("push_in", 30)
    wall.command("put_down", "on_table", timeout=60)
    assert wall.scene.body_position("drill") == pytest.approx(DRILL_GRIP, abs=0.01)
