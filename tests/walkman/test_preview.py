"""The pilot PC's preview: a shadow of the task module says where a command takes the robot.

The robot here is the simulated one (walkman.gym.offline); the shadow follows the commands
at the postures they were sent at, and its previews are compared with where the simulated
robot's hand really ends.
"""

import math
import numpy as np
import pytest

from tests.walkman.followed import Followed
from walkman.control.kinematics import Kinematics
from walkman.courses import seen_from_the_crouched_pelvis, walker
from walkman.gym.preview import Shadow
from walkman.model.mjcf import PILOT_POSES
from walkman.modules import drc_door, drc_valve, drc_wall
from walkman.modules.task import GRIP

#: The robot on simulated time in this process: no real-time thread (tests/robot_slots.py).
pytestmark = pytest.mark.offline

KINEMATICS = Kinematics()


def grip(q) -> np.ndarray:
    return KINEMATICS.point(q, "l_hand", GRIP)


@pytest.fixture(scope="module")
def valve():
    followed = Followed("valve", drc_valve.Module, "drc_valve")
    for command, state in ((PILOT_POSES["valve"], "ready"), ("reach", "reached"),
                           ("approach", "approached"), ("grasp", "grasped")):
        followed.do(command, state)
    return followed


def test_a_turn_previewed_ends_where_the_hand_really_ends(valve):
    preview = valve.preview("turn 1.5708")
    assert not preview.refused and preview.moves, preview.refusal
    valve.do("turn 1.5708", "grasped")
    assert np.linalg.norm(grip(preview.posture) - grip(valve.posture)) < 0.015


def test_the_door_s_turn_and_open_are_previewed_for_a_robot_crouched_there_unsupported():
    """The harness off, walking paused balancing, the pelvis 9 cm lower than the harness
    holds it: from the measured posture, the first points of the turn fall in a local
    minimum of the tracking IK, 1.5-1.7 cm off (the module's own reference posture gives the
    same), which the chained points carried on -- the
    preview refused turn and open that the module's loop makes (the door opens 53 degrees).
    A point that misses is solved again with restarts before it is called out of reach."""
    world, walking = walker("door")
    assert walking.switch("pause")
    world.step(0.5)
    door = Followed("door", drc_door.Module, "drc_door", world=world)
    x, y, z, _ = world.backend.plant.base_pose()
    pose = " ".join(f"{v:.3f}" for v in seen_from_the_crouched_pelvis("door", x, y, z))
    for command, state in ((f"doordatasent {pose}", "ready"), ("reach", "reached"),
                           ("approach", "approached"), ("grasp", "grasped")):
        door.do(command, state)
    for command, state in (("turn", "turned"), ("open", "opened")):
        preview = door.preview(command)
        assert not preview.refused, preview.refusal
        door.do(command, state)
        assert np.linalg.norm(grip(preview.posture) - grip(door.posture)) < 0.03, command


def test_a_turn_through_where_the_arm_cannot_go_is_refused_and_says_where(valve):
    """Three quarters of a turn: the hand would pass the bottom of the rim, out of the arm's
    reach with the grasp's orientation (on the robot such a turn stalls there, 'still
    trying')."""
    preview = valve.preview("turn 4.7")
    assert preview.refused
    assert "cannot reach" in preview.refusal and "% of the way" in preview.refusal


def test_the_module_s_own_refusals_come_back_from_the_preview(valve):
    assert valve.preview("home").refusal.endswith(
        "'home' is not accepted in state grasped (accepted: turn, ungrasp)")
    assert "at most 2 pi" in valve.preview("turn 10").refusal


def test_a_preview_changes_nothing_for_the_next_one(valve):
    noted = (valve.shadow.thread.fsm.state, dict(valve.shadow.thread.target))
    first = valve.preview("turn 0.5")
    assert valve.preview("turn 4.7").refused      # given up on the way
    valve.preview("ungrasp")
    again = valve.preview("turn 0.5")
    assert np.allclose(first.posture, again.posture)
    assert valve.shadow.thread.fsm.state == noted[0]
    assert valve.shadow.thread.target.keys() == noted[1].keys()


def test_the_drill_s_cut_is_previewed_from_where_the_grasp_held_it():
    """The tip's offset in the hand is noted at the first motion after the grasp: the
    shadow notes it from the posture of that command, as the module does."""
    wall = Followed("wall", drc_wall.Module, "drc_wall")
    wall.do(PILOT_POSES["wall"], "ready")
    for command, state in drc_wall.TASK_STEPS[:7]:       # up to drilled_in
        preview = wall.preview(command)
        assert not preview.refused, (command, preview.refusal)
        wall.do(command, state)
        assert np.linalg.norm(grip(preview.posture) - grip(wall.posture)) < 0.015, command
    cut = wall.preview("cut")
    assert not cut.refused and cut.seconds < 0.5
    # once round and OVERLAP on: the hand (its orientation held) ends a chord of that away
    radius = float(PILOT_POSES["wall"].split()[-1])
    chord = 2 * radius * math.sin(drc_wall.OVERLAP / 2)
    assert abs(np.linalg.norm(grip(cut.posture) - grip(wall.posture)) - chord) < 0.005


def test_a_shadow_that_never_saw_the_pose_is_out_of_step_not_wrong_and_not_crashed():
    """A PI restarted mid-task: its shadow meets ``approach`` in ``reached`` without the
    valve's pose.  Its previews are unknown (no ghost, no refusal) until a pose comes."""
    robot = Followed("valve", drc_valve.Module, "drc_valve")
    robot.module.do(PILOT_POSES["valve"], "ready", 40)
    robot.module.do("reach", "reached", 40)
    late = Shadow(drc_valve.Module, "drc_valve")            # started after those two
    late.follow("approach", "reached", robot.posture)
    assert not late.in_step
    preview = late.preview("turn 1.5708", "grasped", robot.posture)
    assert not preview.known and not preview.refused and preview.posture is None
    assert "has not seen the task's pose" in preview.refusal
    late.follow(PILOT_POSES["valve"], "moved_away", robot.posture)   # the pose again
    assert late.in_step


def test_a_walk_s_shadow_refuses_what_the_module_refuses_and_nothing_more():
    """walking on the rough ground: a walk the shadow followed is over for it (the next one
    is not 'already walking'); a step too high is refused on the pilot PC with the module's
    own words; footsteps measured from the soles (pelvis frame) are judged as the module
    judges them, though the shadow never walked (issue 32)."""
    from walkman.courses import footsteps, soles_in_pelvis_frame, walk_through, walker
    from walkman.modules import walking

    world, module = walker("terrain")
    shadow = Shadow(walking.Module, "walking")

    def do(command: str) -> None:
        before, posture = module.thread.fsm.state, world.backend.positions()
        walk_through(world, module, command)
        shadow.follow(command, before, posture)

    def preview(command: str):
        return shadow.preview(command, module.thread.fsm.state, world.backend.positions())

    do("go_straight 0.12")
    step_up = preview("step_up 0.05")
    assert not step_up.refused and not step_up.moves, step_up.refusal   # no ghost for a walk
    too_high = preview("step_up 0.12")
    assert too_high.refused and too_high.refusal.endswith(
        "step_up refused: step 1 of 2 (left foot) cannot be made: 0.12 m above the other foot "
        "(at most 0.08)")
    do("step_up 0.05")
    left, right = soles_in_pelvis_frame(world.backend)

    level = footsteps(left + (0.15, 0, 0, 0, 0, 0), right + (0.15, 0, 0, 0, 0, 0))
    high = footsteps(left + (0.15, 0, 0.10, 0, 0, 0), right + (0.15, 0, 0, 0, 0, 0))
    assert not preview(level).refused, preview(level).refusal
    assert preview(high).refused and "0.10 m above the other foot" in preview(high).refusal
    module.command(high)                 # the module on the robot says the same
    world.step(0.2)
    assert module.state == "idle" and "0.10 m above the other foot" in module.warnings[-1]
    do(level)
