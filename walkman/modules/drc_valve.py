"""drc_valve: turn a valve with the left hand (the DRC valve task).

Theory of operation
-------------------
The pilot first tells where the valve is (``valvedatasent X Y Z ROLL PITCH
YAW RADIUS``: the wheel's centre in the pelvis frame, its orientation -- the
wheel turns about its local x axis -- and its radius), then steps through the
task: ``reach`` (the hand's grip point goes in front of the rim's top),
``approach`` (close to the rim), ``grasp`` (the hand closes), ``turn [ANGLE]``
(the hand follows the rim about the wheel's axis, ANGLE rad, default pi/2;
repeatable), ``ungrasp``, ``move_away``, ``home``.

Each step is a transition of a table-driven state machine
(:mod:`walkman.control.fsm`); a command the current state does not accept is
refused with a warning and changes nothing.  Motions are Cartesian
trajectories with the quintic law (:mod:`walkman.control.trajectory`) solved
every tick by damped-least-squares IK (:mod:`walkman.control.ik`) over the left
arm and the waist -- the valve is beyond the arm's reach alone.  While turning,
the hand's orientation turns with the rim (the grasp holds both).  A motion is
``action_done`` when its trajectory has ended and the sensed grip point is
within 1 cm of its goal (FACTS.md); the hand is ``hand_done`` when its joint
has closed (or opened).  A valve pose the hand cannot reach is refused at
``valvedatasent`` with the distance it misses by.
"""

from __future__ import annotations

import math
from typing import List, Optional

import numpy as np
import pinocchio as pin

from walkman.modules.task import HAND_CLOSED, HAND_OPEN, Effector, TaskModule, task_statuses

ARM = ["LShSag", "LShLat", "LShYaw", "LElbj", "LForearmPlate", "LWrj1", "LWrj2"]
WAIST = ["WaistLat", "WaistSag", "WaistYaw"]
HAND = "l_handj"
GRIP = np.array([0.0, 0.0, -0.1])     # the grip point in the hand frame (models: l_hand_grip)
APPROACH_GAP = 0.045                  # m in front of the rim when approached (grasp within 6 cm)
REACH_GAP = 0.165                     # m in front of the rim when reached
SPEED = 0.15                          # m/s, peak Cartesian speed
TURN_SPEED = 0.6                      # rad/s, peak wheel speed

TABLE = {
    "idle": {"valvedatasent": "ready"},
    "ready": {"valvedatasent": "ready", "reach": "reaching", "home": "homing"},
    "reaching": {"action_done": "reached"},
    "reached": {"approach": "approaching", "move_away": "moving_away", "home": "homing"},
    "approaching": {"action_done": "approached"},
    "approached": {"grasp": "grasping", "move_away": "moving_away"},
    "grasping": {"hand_done": "grasped"},
    "grasped": {"turn": "turning", "ungrasp": "ungrasping"},
    "turning": {"action_done": "grasped"},
    "ungrasping": {"hand_done": "ungrasped"},
    "ungrasped": {"move_away": "moving_away", "grasp": "grasping"},
    "moving_away": {"action_done": "moved_away"},
    "moved_away": {"home": "homing", "valvedatasent": "ready", "reach": "reaching"},
    "homing": {"action_done": "idle"},
}


def rpy_matrix(roll: float, pitch: float, yaw: float) -> np.ndarray:
    return pin.rpy.rpyToMatrix(roll, pitch, yaw)


class Module(TaskModule):
    statuses = task_statuses(TABLE)
    table = TABLE
    arguments = {"valvedatasent": (7, 7, "X Y Z ROLL PITCH YAW RADIUS"),
                 "turn": (0, 1, "ANGLE rad")}
    joints = ARM + WAIST + [HAND]

    def setup(self) -> None:
        self.hand = Effector("l_hand", GRIP, ARM + WAIST)
        self.valve: Optional[dict] = None

    def status_data(self) -> List[float]:
        return [] if self.valve is None else [float(v) for v in self.valve["center"]]

    def _start_valvedatasent(self, x, y, z, roll, pitch, yaw, radius) -> None:
        if not 0.05 <= radius <= 0.5:
            raise ValueError(f"radius {radius} m is not a valve's (0.05..0.5)")
        rotation = rpy_matrix(roll, pitch, yaw)
        center = np.array([x, y, z])
        axis = rotation[:, 0]
        grip = center + radius * rotation[:, 2]
        valve = {"center": center, "axis": axis, "grip": grip, "radius": radius,
                 "approach": grip - APPROACH_GAP * axis, "reach": grip - REACH_GAP * axis}
        for point in ("reach", "approach"):
            self.reachable(self.hand, valve[point], what=f"valve's {point} point")
        self.valve = valve

    def _start_reach(self) -> None:
        self.line_to(self.hand, self.valve["reach"], SPEED)

    def _start_approach(self) -> None:
        self.line_to(self.hand, self.valve["approach"], SPEED)

    def _start_move_away(self) -> None:
        # Back to the reach point: checked reachable at valvedatasent, clear of the wheel.
        self.line_to(self.hand, self.valve["reach"], SPEED)

    def _start_grasp(self) -> None:
        self.set_hand(HAND, HAND_CLOSED)

    def _start_ungrasp(self) -> None:
        self.set_hand(HAND, HAND_OPEN)

    def _start_turn(self, angle: float = math.pi / 2) -> None:
        if abs(angle) > 2 * math.pi:
            raise ValueError(f"turn by at most 2 pi rad, got {angle}")
        self.arc(self.hand, self.valve["center"], self.valve["axis"], angle, TURN_SPEED)

    def _start_home(self) -> None:
        self.home(ARM + WAIST)
