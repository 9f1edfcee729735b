"""The PI's preview gate: a dangerous command the pilot PC's preview refuses never leaves."""

import pytest

from pilot.preview import COUNTDOWN_SILENCE, PreviewGate
from tests.walkman.followed import Followed
from walkman.model.description import walkman
from walkman.model.mjcf import PILOT_POSES
from walkman.modules import drc_valve


@pytest.fixture(scope="module")
def grasped():
    """The simulated robot with its hand on the valve, and the commands that got it there."""
    robot = Followed("valve", drc_valve.Module, "drc_valve")
    sent = [(PILOT_POSES["valve"], "ready"), ("reach", "reached"), ("approach", "approached"),
            ("grasp", "grasped")]
    steps = []
    for command, state in sent:
        steps.append((command, robot.module.thread.fsm.state, robot.posture))
        robot.do(command, state)
    return robot, steps


def gate_at(grasped):
    """A gate that followed the task's commands as the PI sent them."""
    robot, steps = grasped
    shown, said, states = [], [], {"drc_valve": None}
    gate = PreviewGate(states.get, lambda module, q: shown.append((module, q)), said.append)
    names = robot.world.backend.joint_names
    for command, state, posture in steps:
        states["drc_valve"] = state
        gate.on_joints(names, posture)
        name, *numbers = command.split()
        assert gate.command("drc_valve", name, [float(n) for n in numbers], False,
                            lambda: "") == ""
    states["drc_valve"] = "grasped"
    gate.on_joints(names, robot.posture)
    return gate, shown, said


def test_a_turn_the_arm_cannot_make_is_not_sent(grasped):
    gate, shown, said = gate_at(grasped)
    sent = []
    problem = gate.command("drc_valve", "turn", [4.7], True, lambda: sent.append(1) or "")
    assert sent == [] and shown == []
    assert problem.startswith("not sent: this PC's preview says drc_valve: the l_hand cannot "
                              "reach") and "% of the way" in problem
    assert said[-1].startswith("preview of drc_valve turn: refused")


def test_a_turn_it_can_make_shows_its_ghost_then_goes_and_a_second_click_cancels(grasped):
    gate, shown, said = gate_at(grasped)
    sent = []
    assert gate.command("drc_valve", "turn", [1.5708], True, lambda: sent.append(1) or "") == ""
    assert sent == [1] and len(shown) == 1 and gate.last_ms is not None
    assert "the ghost shows where it goes" in said[-1]
    # the second click while it counts down is the cancel: straight out, no new preview
    assert gate.command("drc_valve", "turn", [1.5708], True, lambda: sent.append(2) or "") == ""
    assert sent == [1, 2] and len(shown) == 1
    gate.countdown_over("drc_valve")
    gate.command("drc_valve", "turn", [1.5708], True, lambda: "")
    assert len(shown) == 2


def test_a_countdown_whose_end_never_came_is_over_after_its_silence(grasped):
    """The link dropped the gateway's 'sent': the next click is a new command, previewed."""
    gate, shown, said = gate_at(grasped)
    now = [100.0]
    gate.clock = lambda: now[0]
    assert gate.command("drc_valve", "turn", [1.5708], True, lambda: "") == ""
    assert gate.counting("drc_valve") and len(shown) == 1
    now[0] += 2.0
    gate.countdown_left("drc_valve", 2.5)       # the gateway: 2.5 s to go
    now[0] += 2.5 + COUNTDOWN_SILENCE - 0.1
    assert gate.counting("drc_valve")            # still believed: within its end and silence
    now[0] += 0.2                                # ... and then no word for too long
    assert not gate.counting("drc_valve")
    gate.command("drc_valve", "turn", [1.5708], True, lambda: "")
    assert len(shown) == 2                       # previewed: not taken for a cancel


def test_before_any_joint_state_the_pose_is_followed_from_home_and_others_pass_on():
    """A pilot quicker than the first joint state: the pose still reaches the shadow (from
    the home posture the robot starts in), so later previews have it; a module without a
    shadow (not a task) gets its commands as they are."""
    states = {"drc_valve": "idle", "temperature": "monitoring"}
    gate = PreviewGate(states.get, lambda *a: pytest.fail("no ghost"), print)
    name, *numbers = PILOT_POSES["valve"].split()
    assert gate.command("drc_valve", name, [float(n) for n in numbers], False,
                        lambda: "") == ""
    shadow = gate._shadows["drc_valve"]
    assert gate.posture is None and shadow.in_step and shadow.thread.target is not None
    gate.on_joints(["not", "the", "robot"], [0.0, 0.0, 0.0])     # ignored: not the model
    assert gate.posture is None
    names = walkman().joint_names
    gate.on_joints(names, [])                     # ignored: names without positions (ROS allows)
    assert gate.posture is None
    gate.on_joints(names, [0.0] * len(names))
    assert gate.posture is not None
    assert gate.command("temperature", "set_limit", [70.0], True, lambda: "out") == "out"


def test_a_gate_whose_shadow_is_out_of_step_sends_without_a_preview_and_says_so(grasped):
    """A PI restarted mid-task (the valve's pose sent by the one before it): its commands go
    out as they always did, no ghost, no refusal, and the pilot is told why."""
    robot, _ = grasped
    shown, said = [], []
    gate = PreviewGate(lambda module: "reached", lambda module, q: shown.append(q), said.append)
    gate.on_joints(robot.world.backend.joint_names, robot.posture)
    sent = []
    assert gate.command("drc_valve", "approach", [], False, lambda: sent.append(1) or "") == ""
    assert gate.command("drc_valve", "turn", [1.5708], True, lambda: sent.append(2) or "") == ""
    assert sent == [1, 2] and shown == []
    assert said[-1].startswith("no preview of drc_valve turn: this PC has not seen the task's "
                               "pose")
