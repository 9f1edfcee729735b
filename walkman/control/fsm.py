"""Table-driven finite state machines for task modules (paper section 2.5).

A task is a table ``state -> {event -> next state}``.  Events are the pilot's
commands (``reach``, ``grasp`` ...) and the module's internal events
(``action_done`` when a trajectory reached its target, ``hand_done`` when the
hand closed or opened).  An event the current state does not accept leaves the
state unchanged and is reported -- the pilot sees why in the warning, the robot
keeps doing what it did.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Dict, List, Mapping, Optional

Table = Mapping[str, Mapping[str, str]]


@dataclass(frozen=True)
class Step:
    before: str
    event: str
    after: str
    accepted: bool
    reason: str = ""


class StateMachine:
    def __init__(self, table: Table, initial: str, name: str = "fsm") -> None:
        targets = {after for moves in table.values() for after in moves.values()}
        unknown = sorted(targets - set(table))
        if unknown:
            raise ValueError(f"{name}: states {unknown} are reached but have no row in the table")
        if initial not in table:
            raise ValueError(f"{name}: initial state {initial!r} is not in the table")
        self.name = name
        self.table: Dict[str, Dict[str, str]] = {k: dict(v) for k, v in table.items()}
        self.initial = initial
        self.state = initial
        self.history: List[Step] = []

    @property
    def statuses(self) -> List[str]:
        """Every state, in table order: the module's status list."""
        return list(self.table)

    def accepts(self, event: str) -> bool:
        return event in self.table[self.state]

    def fire(self, event: str) -> Step:
        """Apply ``event``; a refused one leaves the state and says why."""
        before = self.state
        after: Optional[str] = self.table[before].get(event)
        if after is None:
            allowed = ", ".join(sorted(self.table[before])) or "nothing"
            step = Step(before, event, before, False,
                        f"{self.name}: '{event}' is not accepted in state {before} "
                        f"(accepted: {allowed})")
        else:
            self.state = after
            step = Step(before, event, after, True)
        self.history.append(step)
        return step

    def reset(self) -> None:
        self.state = self.initial


def _drive_table() -> Dict[str, Dict[str, str]]:
    """The original drc_drive machine (FACTS.md)."""
    table: Dict[str, Dict[str, str]] = {
        "idle": {"steeringwheeldatasent": "ready"},
        "ready": {"reach": "reaching"},
        "reaching": {"action_done": "reached"},
        "reached": {"approach": "approaching"},
        "approaching": {"action_done": "approached"},
        "approached": {"grasp": "grasping"},
        "grasping": {"hand_done": "grasped"},
        "grasped": {"drive": "drive"},
        "drive": {"turn_left": "turning_left", "turn_right": "turning_right",
                  "accelerate": "accelerating", "rotate_foot": "rotating_foot",
                  "ungrasp": "ungrasping", "move_away_foot": "moving_away_foot"},
        "turning_left": {"action_done": "drive"},
        "turning_right": {"action_done": "drive"},
        "accelerating": {"action_done": "drive"},
        "rotating_foot": {"action_done": "drive"},
        "moving_away_foot": {"action_done": "drive"},
        "ungrasping": {"hand_done": "ungrasped"},
        "ungrasped": {},
        "moving_away_hand": {"action_done": "moved_away_hand"},
        "moved_away_hand": {},
    }
    for state in ("ready", "reached", "approached", "ungrasped", "moved_away_hand"):
        table[state]["move_away_hand"] = "moving_away_hand"
    return table


DRIVE_TABLE = _drive_table()
