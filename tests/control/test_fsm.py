"""Table-driven state machines: the original drc_drive machine, refusals that say why."""

import pytest

from walkman.control.fsm import DRIVE_TABLE, StateMachine


def test_the_drive_machine_from_idle_to_driving_and_back():
    fsm = StateMachine(DRIVE_TABLE, "idle", "drc_drive")
    for event in ("steeringwheeldatasent", "reach", "action_done", "approach", "action_done",
                  "grasp", "hand_done", "drive", "turn_left", "action_done", "accelerate",
                  "action_done", "ungrasp", "hand_done", "move_away_hand", "action_done"):
        step = fsm.fire(event)
        assert step.accepted, step.reason
    assert fsm.state == "moved_away_hand"
    assert [s.after for s in fsm.history][7:9] == ["drive", "turning_left"]


@pytest.mark.parametrize("state,event", [("idle", "reach"), ("drive", "grasp"),
                                         ("reaching", "reach"), ("grasped", "turn_left")])
def test_an_event_the_state_does_not_accept_changes_nothing_and_says_why(state, event):
    fsm = StateMachine(DRIVE_TABLE, state, "drc_drive")
    step = fsm.fire(event)
    assert not step.accepted and fsm.state == state
    assert f"'{event}' is not accepted in state {state}" in step.reason


def test_move_away_hand_from_every_state_the_original_allows():
    for state in ("ready", "reached", "approached", "ungrasped", "moved_away_hand"):
        assert StateMachine(DRIVE_TABLE, state).fire("move_away_hand").after == "moving_away_hand"


def test_tables_with_dangling_states_are_refused():
    with pytest.raises(ValueError, match=r"states \['nowhere'\] are reached"):
        StateMachine({"a": {"go": "nowhere"}}, "a")
    with pytest.raises(ValueError, match="initial state 'b'"):
        StateMachine({"a": {}}, "b")
