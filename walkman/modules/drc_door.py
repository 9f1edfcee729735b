"""drc_door: open a latched door by its lever handle with the left hand (DRC door task).

Theory of operation
-------------------
The pilot says where the handle is (``doordatasent X Y Z ROLL PITCH YAW
HANDLE_LENGTH DOOR_WIDTH``: the lever's pivot in the pelvis frame and the
door's orientation -- local x is the door's normal pointing away from the
robot, the lever lies along local +y -- the distance from the pivot to where
the hand grips it, and the signed distance from the pivot to the hinge along
y), then steps through the task:

``reach`` (in front of the lever), ``approach``, ``grasp``, ``turn [A]`` (the
lever down by A rad, default 0.9: the latch lets go), ``open [A]`` (the hand
pushes the door about its hinge by A rad, default 0.7, still holding the
handle; repeatable), ``ungrasp`` (a turned lever is eased back up in the
grip first, then the hand opens), ``move_away`` (straight back from where the
hand is), ``home``.

Same building blocks as the other tasks (:mod:`walkman.modules.task`): the
table below, quintic Cartesian lines and arcs, per-tick IK over the left arm
and the waist.  Every target is checked reachable before the state changes.
"""

from __future__ import annotations

import math
from typing import List

import numpy as np
import pinocchio as pin

from walkman.gym.link_loss import LinkLoss
from walkman.modules.drc_valve import rpy_matrix
from walkman.modules.task import GraspTask, grasp_table, task_statuses

APPROACH_GAP, REACH_GAP, AWAY = 0.04, 0.15, 0.15
TURN_SPEED, OPEN_SPEED = 0.6, 0.4

TABLE = grasp_table("doordatasent", {
    "grasped": {"turn": "turning", "ungrasp": "ungrasping"},
    "turning": {"action_done": "turned"},
    "turned": {"open": "opening", "ungrasp": "ungrasping"},
    "opening": {"action_done": "opened"},
    "opened": {"open": "opening", "ungrasp": "ungrasping"},
})


#: The whole task as a pilot steps it once the pose is sent: each command and the state it
#: ends in (the benchmarks and the README's walk-through follow it).
TASK_STEPS = (("reach", "reached"), ("approach", "approached"), ("grasp", "grasped"),
              ("turn", "turned"), ("open", "opened"), ("ungrasp", "ungrasped"),
              ("move_away", "moved_away"), ("home", "idle"))


class Module(GraspTask):
    statuses = task_statuses(TABLE)
    status_format = {"*": "door opened {0:.2f} rad"}
    table = TABLE
    arguments = {"doordatasent": (8, 8, "X Y Z ROLL PITCH YAW HANDLE_LENGTH DOOR_WIDTH"),
                 "turn": (0, 1, "ANGLE rad"), "open": (0, 1, "ANGLE rad")}
    dangerous = frozenset({"open"})
    # As drc_valve: each motion ends by itself, settled; paused halfway the hand would hold
    # a half-turned lever or a door pushing back.  As at the DRC.
    link_loss = LinkLoss.CONTINUE

    def status_data(self) -> List[float]:
        return [] if self.target is None else [float(self.target["opened"])]

    def _start_doordatasent(self, x, y, z, roll, pitch, yaw, handle_length, door_width) -> None:
        if not 0.03 <= handle_length <= 0.3:
            raise ValueError(f"handle length {handle_length} m is not a lever's (0.03..0.3)")
        if not 0.3 <= abs(door_width) <= 1.5:
            raise ValueError(f"door width {door_width} m is not a door's (0.3..1.5, signed)")
        rotation = rpy_matrix(roll, pitch, yaw)
        pivot, normal, along = np.array([x, y, z]), rotation[:, 0], rotation[:, 1]
        grip = pivot + handle_length * along
        self.aim({"pivot": pivot, "normal": normal, "grip": grip,
                  "hinge": pivot + door_width * along, "axis": rotation[:, 2],
                  "side": math.copysign(1.0, door_width), "opened": 0.0,
                  "reach": grip - REACH_GAP * normal, "approach": grip - APPROACH_GAP * normal},
                 "handle")

    def _start_turn(self, angle: float = 0.9) -> None:
        if not 0.1 <= angle <= 1.2:
            raise ValueError(f"turn the handle by 0.1..1.2 rad, got {angle}")
        # Down: about the door's normal, the lever's free end goes towards -z.
        self.arc(self.hand, self.target["pivot"], self.target["normal"], -angle, TURN_SPEED)
        self.target["turned"] = angle

    def _start_open(self, angle: float = 0.7) -> None:
        if not 0.05 <= angle <= 1.2:
            raise ValueError(f"open by 0.05..1.2 rad at a time, got {angle}")
        door, signed = self.target, self.target["side"] * angle
        position, _ = self.pose(self.hand)
        hinge = door["hinge"] + door["axis"] * float(door["axis"] @ (position - door["hinge"]))
        # Check the end of the push before moving: a door opened too far is out of reach.
        end = self.swung(position, signed)
        self.reachable(self.hand, end, what="door's opening arc end")
        self.arc(self.hand, hinge, door["axis"], signed, OPEN_SPEED)
        door["opened"] += angle

    def _start_ungrasp(self) -> None:
        """Let the lever back up in the grip before opening the hand: its spring pushes the
        hand up (8 N*m at 1 rad: ~90 N at the grip), and let go at once it snaps up and takes
        that push off a free-standing robot's front, tipping it onto its toes."""
        door = self.target
        if not door.get("turned"):
            super()._start_ungrasp()
            return
        opened = door["side"] * door["opened"]
        pivot = self.swung(door["pivot"], opened)          # where the door took the lever
        normal = pin.exp3(door["axis"] * opened) @ door["normal"]
        self.arc(self.hand, pivot, normal, door["turned"], TURN_SPEED)
        door["turned"] = 0.0
        self.then(super()._start_ungrasp)

    def swung(self, point: np.ndarray, angle: float) -> np.ndarray:
        """``point`` carried by the door turning ``angle`` rad (signed) about its hinge."""
        door = self.target
        return pin.exp3(door["axis"] * angle) @ (point - door["hinge"]) + door["hinge"]

    def _start_move_away(self) -> None:
        position, _ = self.pose(self.hand)
        goal = position - AWAY * self.target["normal"]
        self.reachable(self.hand, goal, what="point away from the door")
        self.line_to(self.hand, goal, self.speed)

