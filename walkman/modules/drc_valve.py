"""drc_valve: turn a valve with the left hand (the DRC valve task).

Theory of operation
-------------------
The pilot first tells where the valve is (``valvedatasent X Y Z ROLL PITCH
YAW RADIUS``: the wheel's centre in the pelvis frame, its orientation -- the
wheel turns about its local x axis -- and its radius), then steps through the
task: ``reach`` (the hand's grip point goes in front of the rim's top),
``approach`` (close to the rim), ``grasp`` (the hand closes), ``turn [ANGLE]``
(the hand follows the rim about the wheel's axis, ANGLE rad, default pi/2;
repeatable), ``ungrasp``, ``move_away`` (straight back off the rim along the
wheel's axis, then to the reach point), ``home``.

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
from typing import List

import numpy as np
import pinocchio as pin

from walkman.gym.link_loss import LinkLoss
from walkman.modules.task import GraspTask, grasp_table, task_statuses

APPROACH_GAP = 0.045                  # m in front of the rim when approached (the hand grasps within 8 cm)
REACH_GAP = 0.165                     # m in front of the rim when reached
TURN_SPEED = 0.6                      # rad/s, peak wheel speed
BACK_OFF_MIN = 0.01                   # m: a shorter back-off along the axis is skipped

TABLE = grasp_table("valvedatasent", {
    "grasped": {"turn": "turning", "ungrasp": "ungrasping"},
    "turning": {"action_done": "grasped"},
})


def rpy_matrix(roll: float, pitch: float, yaw: float) -> np.ndarray:
    return pin.rpy.rpyToMatrix(roll, pitch, yaw)


#: The whole task as a pilot steps it once the pose is sent: each command and the state it
#: ends in (the benchmarks and the README's walk-through follow it).
TASK_STEPS = (("reach", "reached"), ("approach", "approached"), ("grasp", "grasped"),
              ("turn 1.5708", "grasped"), ("ungrasp", "ungrasped"), ("move_away", "moved_away"),
              ("home", "idle"))


class Module(GraspTask):
    statuses = task_statuses(TABLE)
    status_format = {"*": "valve at ({0:.2f}, {1:.2f}, {2:.2f}) m"}
    table = TABLE
    arguments = {"valvedatasent": (7, 7, "X Y Z ROLL PITCH YAW RADIUS"),
                 "turn": (0, 1, "ANGLE rad")}
    dangerous = frozenset({"turn"})
    # The motion the pilot started ends by itself with the hand settled (a turn stops at its
    # angle); paused halfway it would hold the hand on a loaded rim, and a turn resumed is
    # not finished (task.py).  As at the DRC.
    link_loss = LinkLoss.CONTINUE

    def status_data(self) -> List[float]:
        return [] if self.target is None else [float(v) for v in self.target["center"]]

    def _start_valvedatasent(self, x, y, z, roll, pitch, yaw, radius) -> None:
        if not 0.05 <= radius <= 0.5:
            raise ValueError(f"radius {radius} m is not a valve's (0.05..0.5)")
        rotation = rpy_matrix(roll, pitch, yaw)
        center = np.array([x, y, z])
        axis = rotation[:, 0]
        grip = center + radius * rotation[:, 2]
        self.aim({"center": center, "axis": axis, "grip": grip, "radius": radius,
                  "approach": grip - APPROACH_GAP * axis, "reach": grip - REACH_GAP * axis},
                 "valve")

    def _start_move_away(self) -> None:
        # Straight back along the wheel's axis first, to the reach point's depth, the hand
        # keeping its turned orientation: the open fingers are still around the rim, and a
        # hand free to turn (or to go diagonally to the reach point) dragged the wheel back
        # by 0.1 rad.  Then to the reach point (checked reachable at valvedatasent).
        axis, reach = self.target["axis"], self.target["reach"]
        position, rotation = self.pose(self.hand)
        back = float(np.dot(reach - position, axis))
        if back < -BACK_OFF_MIN:  # in front of the reach point's depth (reached: already there)
            clear = position + back * axis
            self.reachable(self.hand, clear, rotation, what="point back off the wheel")
            self.line_to(self.hand, clear, self.speed, rotation)
            self.then(lambda: self.line_to(self.hand, reach, self.speed))
        else:
            self.line_to(self.hand, reach, self.speed)

    def _start_turn(self, angle: float = math.pi / 2) -> None:
        if abs(angle) > 2 * math.pi:
            raise ValueError(f"turn by at most 2 pi rad, got {angle}")
        self.arc(self.hand, self.target["center"], self.target["axis"], angle, TURN_SPEED)
