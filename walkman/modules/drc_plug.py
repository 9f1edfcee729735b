"""drc_plug: the DRC's surprise task -- pull a plug from one socket, push it into another.

Theory of operation
-------------------
The pilot tells where the plug's handle is and where the other socket lies
(``plugdatasent X Y Z ROLL PITCH YAW DX DY``: the handle's centre and the
plug's orientation in the pelvis frame, then the second socket's offset from
the first, level with it), then steps through the task with the left hand,
as for the valve: ``reach``, ``approach``, ``grasp``; ``pull`` (straight up,
the plug out of its socket), ``move_to_socket`` (level, over the other
socket), ``insert`` (straight down into it), ``ungrasp``, ``move_away``
(back along the approach axis), ``home``.

The state machine is the valve's (:func:`walkman.modules.task.grasp_table`)
with the plug's rows; a command the state does not accept is refused with a
warning.  Every motion is a straight Cartesian line (quintic law, IK over the
left arm and the waist, orientation held), checked reachable before the task
accepts the plug's pose: a socket the hand cannot reach is refused at
``plugdatasent`` with the distance it misses by.  ``insert`` takes the hand
down to where it held the plug standing (noted at the first ``pull``), moved
over the other socket: the grasp fixed the plug to the hand, so it seats as
deep as it stood, whatever the hand's small miss at the grasp.
"""

from __future__ import annotations

from typing import List

import numpy as np

from walkman.gym.link_loss import LinkLoss
from walkman.modules.drc_valve import rpy_matrix
from walkman.modules.task import GraspTask, grasp_table, task_statuses

APPROACH_GAP = 0.045     # m behind the handle when approached (the hand grasps within 8 cm)
REACH_GAP = 0.165        # m behind the handle when reached
PULL = 0.10              # m the plug rises: its 8 cm body clears the 6 cm socket
MAX_OFFSET = 0.5         # m: the other socket is beside the first

TABLE = grasp_table("plugdatasent", {
    "grasped": {"pull": "pulling", "ungrasp": "ungrasping"},
    "pulling": {"action_done": "pulled"},
    "pulled": {"move_to_socket": "moving_to_socket", "insert_back": "inserting"},
    "moving_to_socket": {"action_done": "over_socket"},
    "over_socket": {"insert": "inserting"},
    "inserting": {"action_done": "inserted"},
    "inserted": {"ungrasp": "ungrasping", "pull": "pulling"},
})


#: The whole task as a pilot steps it once the pose is sent: each command and the state it
#: ends in (the benchmarks and the README's walk-through follow it).
TASK_STEPS = (("reach", "reached"), ("approach", "approached"), ("grasp", "grasped"),
              ("pull", "pulled"), ("move_to_socket", "over_socket"), ("insert", "inserted"),
              ("ungrasp", "ungrasped"), ("move_away", "moved_away"), ("home", "idle"))


class Module(GraspTask):
    statuses = task_statuses(TABLE)
    status_format = {"*": "plug handle at ({0:.2f}, {1:.2f}, {2:.2f}) m"}
    table = TABLE
    arguments = {"plugdatasent": (8, 8, "X Y Z ROLL PITCH YAW DX DY")}
    dangerous = frozenset({"insert"})
    # Every motion ends by itself with the hand still; a pause would hold the plug in the air.
    link_loss = LinkLoss.CONTINUE

    def status_data(self) -> List[float]:
        return [] if self.target is None else [float(v) for v in self.target["handle"]]

    def _start_plugdatasent(self, x, y, z, roll, pitch, yaw, dx, dy) -> None:
        if np.hypot(dx, dy) > MAX_OFFSET or np.hypot(dx, dy) < 0.05:
            raise ValueError(f"the other socket is 0.05..{MAX_OFFSET} m from the first, got "
                             f"({dx:g}, {dy:g})")
        rotation = rpy_matrix(roll, pitch, yaw)
        handle = np.array([x, y, z])
        forward = rotation[:, 0]               # the hand comes along the plug's x axis
        up, over = np.array([0.0, 0.0, PULL]), np.array([dx, dy, 0.0])
        target = {"handle": handle, "forward": forward, "grip": handle,
                  "approach": handle - APPROACH_GAP * forward,
                  "reach": handle - REACH_GAP * forward,
                  "pulled": handle + up, "over": handle + up + over, "seated": handle + over,
                  "seated_reach": handle + over - REACH_GAP * forward}
        for point in ("pulled", "over", "seated", "seated_reach"):
            self.reachable(self.hand, target[point], what=f"plug's {point.replace('_', ' ')} point")
        self.aim(target, "plug")

    def _start_pull(self) -> None:
        """Straight up from where the hand holds the plug (in either socket).  The first
        pull notes where the hand held it standing: the grasp fixed the plug to the hand
        there, so the hand at that height over a socket seats the plug exactly as deep."""
        position, _ = self.pose(self.hand)
        self.target.setdefault("held", position)
        self.line_to(self.hand, position + np.array([0.0, 0.0, PULL]), self.speed)

    def _start_move_to_socket(self) -> None:
        self.line_to(self.hand, self.target["over"], self.speed)

    def _start_insert(self) -> None:
        over = self.target["seated"] - self.target["handle"]
        self.line_to(self.hand, self.target["held"] + over, self.speed / 2)

    def _start_insert_back(self) -> None:
        self.line_to(self.hand, self.target["held"], self.speed / 2)

    def _start_move_away(self) -> None:
        # Back along the approach axis from wherever the plug was left, then nothing else:
        # ``home`` takes the arm down.
        self.back_away(REACH_GAP)
