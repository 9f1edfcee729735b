"""drc_wall end to end: the HAL at the wall station, the module as a process, yarp-lite write.

Done when the HAL -- the simulated world -- says the circle is cut out of the drywall, and
the drill stands on its table again after the hand let it go (read from the world port).
"""

import math

import pytest

from system.processes import wait_until
from walkman.model.mjcf import DRILL_GRIP, PILOT_POSES, STATIONS
from walkman.modules.drc_wall import TASK_STEPS
from yarp_lite.bottle import Bottle
from yarp_lite.rpc import RpcClient


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


def hal_rpc(*words) -> str:
    """A request on the HAL's rpc port, as a user does with ``yarp rpc /walkman/rpc:i``."""
    client = RpcClient("/test/stations")
    try:
        assert client.connect("/walkman/rpc:i")
        return client.call(Bottle(list(words)), timeout=10).to_text()
    finally:
        client.close()


def test_the_robot_goes_to_the_wall_station_and_not_away_with_the_drill(task_at):
    """One session for every task: ``[set] station`` moves the simulated robot; a hand
    holding a part keeps it there (the part would go with it)."""
    wall = task_at("valve", "drc_wall")
    assert "station must be one of valve, car" in hal_rpc("set", "station", "moon")
    assert hal_rpc("set", "station", "wall") == "[ok]"
    x, y, _ = STATIONS["wall"]
    wait_until(lambda: math.dist(wall.scene.base()[:2], (x, y)) < 0.02, 20, message="at the wall")
    wall.hal.wait_for(r"HAL: the robot is at station wall", 10)
    wall.command(PILOT_POSES["wall"], "ready")
    for command, state in TASK_STEPS[:3]:                 # the drill in the hand
        wall.command(command, state, timeout=60)
    assert "a hand holds l_drill: let go first" in hal_rpc("set", "station", "valve")
    assert math.dist(wall.scene.base()[:2], (x, y)) < 0.02
