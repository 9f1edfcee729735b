"""walking: ``go_straight D``, ``turn A``, ``step_side D`` with a level pelvis.

Theory of operation
-------------------
The gait is :class:`walkman.control.gait.Gait`: the stance foot holds the floor
and slides back under the pelvis while the swing foot lifts and lands ahead;
every tick each foot's pose (sole point, flat, yawed) is solved by IK over its
own leg's six joints, and the waist is held upright.  On start the module
first bends the knees (the soles come ``CROUCH`` closer to the pelvis): with
straight legs a foot half a stride ahead is out of reach.  Balance is the support
harness's job (``walkman-hal --harness trolley``: the trolley keeps the pelvis
level and carries part of the weight, the feet carry the rest and move the
robot by friction) -- this is a stepping controller, not a balance controller.

The pilot's ``pause`` is safe: the runner keeps the module going until the
current step ends and both feet are down (:meth:`Module.ready_to_pause`);
``resume`` plays the rest of the walk.  While paused the module is silent, so
the HAL lets another module use its joints (the paper's door sequence).  The
status carries the distance walked so far (odometry of the planned steps:
x, y in metres, yaw in radians).
"""

from __future__ import annotations

import math
from typing import List

import numpy as np

from walkman.control.gait import Gait, foot_rotation
from walkman.control.trajectory import quintic
from walkman.modules.task import TaskModule, task_statuses

LEGS = {"left": ["LHipLat", "LHipYaw", "LHipSag", "LKneeSag", "LAnkSag", "LAnkLat"],
        "right": ["RHipLat", "RHipYaw", "RHipSag", "RKneeSag", "RAnkSag", "RAnkLat"]}
WAIST = ["WaistLat", "WaistSag", "WaistYaw"]
FRAMES = {"left": "l_foot", "right": "r_foot"}
SOLE = np.array([0.03, 0.0, -0.10])   # the middle of the sole, in the foot frame
PRESS = 0.005                          # m the stance foot is held into the floor
CROUCH = 0.06                          # m the pelvis sinks at start: knees bent, steps reachable
CROUCH_TIME = 1.5                      # s
TICK_IK_ITERATIONS = 20

TABLE = {
    "idle": {"go_straight": "walking", "turn": "turning", "step_side": "side_stepping"},
    "walking": {"action_done": "idle"},
    "turning": {"action_done": "idle"},
    "side_stepping": {"action_done": "idle"},
}


class Module(TaskModule):
    statuses = task_statuses(TABLE)
    table = TABLE
    arguments = {"go_straight": (1, 1, "DISTANCE m"), "turn": (1, 1, "ANGLE rad"),
                 "step_side": (1, 1, "DISTANCE m, left positive")}
    # Rotating on the spot nearly toppled Walk-Man at the DRC: every step counts down.
    dangerous = frozenset({"go_straight", "turn", "step_side"})
    joints = LEGS["left"] + LEGS["right"] + WAIST

    def setup(self) -> None:
        q = self.robot.sense_position()
        soles = {side: self.sole(q, side) for side in LEGS}
        standing = float(np.mean([p[2] for p in soles.values()])) - PRESS
        self.gait = Gait(half_width=float(np.mean([abs(p[1]) for p in soles.values()])),
                         forward=float(np.mean([p[0] for p in soles.values()])), ground=standing)
        self.crouch = (standing, standing + CROUCH, self.now())
        self.leg_index = {side: self.ik.joints_of(joints) for side, joints in LEGS.items()}
        waist = [self.robot.index[name] for name in WAIST]
        self.reference[waist] = 0.0  # upright

    def sole(self, q: np.ndarray, side: str) -> np.ndarray:
        position, rotation = self.kinematics.pose(q, FRAMES[side])
        return position + rotation @ SOLE

    def status_data(self) -> List[float]:
        return [round(float(v), 3) for v in self.gait.travelled]

    def _walk(self, dx: float, dy: float, dyaw: float) -> None:
        self.gait.plan(dx, dy, dyaw, self.now())

    def _start_go_straight(self, distance: float) -> None:
        if not 0.01 <= abs(distance) <= 5.0:
            raise ValueError(f"go_straight takes 0.01..5 m (negative: backwards), got {distance}")
        self._walk(distance, 0.0, 0.0)

    def _start_turn(self, angle: float) -> None:
        if not 0.01 <= abs(angle) <= math.pi:
            raise ValueError(f"turn takes 0.01..pi rad (positive: left), got {angle}")
        self._walk(0.0, 0.0, angle)

    def _start_step_side(self, distance: float) -> None:
        if not 0.01 <= abs(distance) <= 1.0:
            raise ValueError(f"step_side takes 0.01..1 m (positive: left), got {distance}")
        self._walk(0.0, distance, 0.0)

    def track(self) -> None:
        now = self.now()
        gait = self.gait
        start, end, t0 = self.crouch
        gait.ground = start + (end - start) * quintic((now - t0) / CROUCH_TIME)
        if self.pause_requested and gait.can_pause(now):
            gait.hold(now)
        ended = gait.update(now)
        for side, index in self.leg_index.items():
            (x, y, yaw), z = gait.foot(side, now)
            result = self.ik.solve(FRAMES[side], np.array([x, y, z]), foot_rotation(yaw),
                                   self.reference, LEGS[side], offset=SOLE, restarts=0,
                                   max_iterations=TICK_IK_ITERATIONS)
            self.reference[index] = result.q[index]
        if ended is not None:
            if gait.walking:
                self.report()  # odometry, once per step
            else:
                self.event("action_done")

    def ready_to_pause(self) -> bool:
        return not self.gait.walking or self.gait.held

    def custom_pause(self) -> bool:
        return True  # both feet are down: keep the reference as it is

    def custom_resume(self) -> bool:
        self.gait.resume(self.now())
        return True
