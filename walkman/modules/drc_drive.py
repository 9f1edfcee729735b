"""drc_drive: steer the wheel with the left hand, press the throttle with the right foot.

Theory of operation
-------------------
The original drive module's state machine (FACTS.md, paper Figure 10), kept
as it was (:data:`walkman.control.fsm.DRIVE_TABLE`).  The pilot first says
where the wheel is (``steeringwheeldatasent X Y Z ROLL PITCH YAW RADIUS
[PX PY PZ]``: the wheel's centre in the pelvis frame, its orientation -- the
wheel turns about its local z axis, which points at the driver -- its radius,
and optionally where the throttle pad is), then ``reach``, ``approach``,
``grasp`` (the left hand takes the rim's left side) and ``drive``.

While driving:

* ``turn_left [A]`` / ``turn_right [A]``: the hand follows the rim about the
  wheel's axis by A rad (default 0.5), counter-clockwise / clockwise as the
  driver sees it; the wheel turns with it;
* ``rotate_foot``: the right foot's sole goes over the throttle pad;
* ``accelerate [T] [AMOUNT]``: the foot presses the pad AMOUNT of its 4-cm travel
  down (0.1..1, default 1: the whole), holds it T seconds (default 1), and lets it
  up -- refused until the foot is on the pedal;
* ``move_away_foot``: the foot back to the floor;
* ``ungrasp``, then ``move_away_hand`` (the arm back to where it started).

The hand moves by IK over the left arm and the waist, the foot by IK over the
right leg with the sole kept flat.  The robot drives seated, as Walk-Man did at
the DRC: the car's seat carries it (no harness, no balance controller) while one
foot is on the pedal, and ``move_away_foot`` puts the leg back where it was when
the module started (seated, not the standing home posture).
"""

from __future__ import annotations

from typing import List

import numpy as np

from walkman.control.fsm import DRIVE_TABLE
from walkman.gym.link_loss import LinkLoss
from walkman.modules.drc_valve import rpy_matrix
from walkman.modules.task import LEFT_ARM, WAIST, Effector, GraspTask, task_statuses

RIGHT_LEG = ["RHipLat", "RHipYaw", "RHipSag", "RKneeSag", "RAnkSag", "RAnkLat"]
SOLE = np.array([0.10, 0.0, -0.10])  # the ball of the right foot, under the sole
#: Where the throttle pad is in the pelvis frame, seated at the car station, unless the
#: pilot says.
PEDAL = np.array([0.69, -0.11, -0.63])
#: The sole on the pedal: toe up as the pad slopes (20 degrees), so the whole sole presses
#: it -- a flat sole met only the pad's raised front edge, and slid off it forward.
PEDAL_SLOPE = 0.349
SOLE_ON_PEDAL = rpy_matrix(0.0, -PEDAL_SLOPE, 0.0)
#: rad the sole turns toe down to press the pedal all the way, as a seated driver does, the
#: heel's side still: with the thigh on the seat and the shank upright the ankle is already
#: as low as it goes, and pushing the whole leg down pressed the thigh into the seat.
PRESS_TILT = 0.30
PEDAL_CLEARANCE = 0.03               # m above the pad when the foot is on the pedal
PRESS_DEPTH = 0.03                   # m the ball of the foot pushes the pad down
APPROACH_GAP, REACH_GAP = 0.04, 0.15
TURN_SPEED, FOOT_SPEED = 0.6, 0.1
#: The states in which the left hand holds the rim (:data:`DRIVE_TABLE`).
HOLDING_THE_WHEEL = frozenset({"grasped", "drive", "turning_left", "turning_right",
                               "accelerating", "rotating_foot", "moving_away_foot"})


#: The whole task as a pilot steps it once the pose is sent: each command and the state it
#: ends in (the benchmarks and the README's walk-through follow it).
TASK_STEPS = (("reach", "reached"), ("approach", "approached"), ("grasp", "grasped"),
              ("drive", "drive"), ("turn_left 0.5", "drive"), ("turn_right 1.0", "drive"),
              ("rotate_foot", "drive"), ("accelerate 1.5", "drive"),
              ("move_away_foot", "drive"), ("ungrasp", "ungrasped"),
              ("move_away_hand", "moved_away_hand"))


class Module(GraspTask):
    statuses = task_statuses(DRIVE_TABLE)
    #: The wheel's centre, the angle the pilot asked in all, and the angle the hand holding
    #: the rim is at now, measured by the robot's own joints (forward kinematics).
    status_format = {"*": "wheel at ({0:.2f}, {1:.2f}, {2:.2f}) m, steered {3:.2f} rad, "
                          "measured {4:.2f} rad"}
    table = DRIVE_TABLE
    arguments = {"steeringwheeldatasent": (7, 10, "X Y Z ROLL PITCH YAW RADIUS [PX PY PZ]"),
                 "turn_left": (0, 1, "ANGLE rad"), "turn_right": (0, 1, "ANGLE rad"),
                 "accelerate": (0, 2, "SECONDS AMOUNT")}
    dangerous = frozenset({"accelerate"})
    joints = GraspTask.joints + RIGHT_LEG
    # Never pause a car's driver: a pause holds the posture of the moment, so a pause during
    # ``accelerate`` would hold the throttle down.  Every motion here ends by itself (the
    # pedal comes up after T s, a turn of the wheel stops at its angle): the car coasts.
    link_loss = LinkLoss.CONTINUE

    def setup(self) -> None:
        super().setup()
        self.foot = Effector("r_foot", SOLE, RIGHT_LEG)
        self.foot_on_pedal = False

    def status_data(self) -> List[float]:
        if self.target is None:
            return []
        return [*map(float, self.target["center"]), float(self.target["steered"]),
                self.measured_steer()]

    def measured_steer(self) -> float:
        """How far the wheel is turned, from where the hand holding its rim is (sensed):
        the angle asked when it began to drive, plus the angle about the wheel's axis
        from where the hand was then to where it is now.  Before it drives, the angle
        asked (there is nothing to measure it by).

        From where the hand *took* the rim, not from the grip the pilot pointed at: the
        hand closes where it is, a few millimetres off the grip (0.04 rad offline; more on
        a loaded PC, fc43 of 2026-11-28), and the wheel turns with the hand from there."""
        wheel = self.target
        held = wheel.get("held_at")
        if self.fsm.state not in HOLDING_THE_WHEEL or held is None:
            return float(wheel["steered"])
        return wheel["steered_when_held"] + self._angle_about_the_wheel(held,
                                                                        self.pose(self.hand)[0])

    def _angle_about_the_wheel(self, start: np.ndarray, now: np.ndarray) -> float:
        wheel = self.target
        axis = wheel["axis"] / np.linalg.norm(wheel["axis"])

        def in_plane(point: np.ndarray) -> np.ndarray:
            offset = point - wheel["center"]
            return offset - axis @ offset * axis

        start, now = in_plane(start), in_plane(now)
        return float(np.arctan2(axis @ np.cross(start, now), start @ now))

    def _start_steeringwheeldatasent(self, x, y, z, roll, pitch, yaw, radius,
                                     *pedal: float) -> None:
        if len(pedal) not in (0, 3):
            raise ValueError(f"the pedal is 3 numbers (PX PY PZ), got {len(pedal)}")
        if not 0.1 <= radius <= 0.3:
            raise ValueError(f"radius {radius} m is not a steering wheel's (0.1..0.3)")
        rotation = rpy_matrix(roll, pitch, yaw)
        center, axis = np.array([x, y, z]), rotation[:, 2]
        grip = center + radius * rotation[:, 1]
        wheel = {"center": center, "axis": axis, "grip": grip,
                 "approach": grip + APPROACH_GAP * axis, "reach": grip + REACH_GAP * axis,
                 "pedal": np.array(pedal) if pedal else PEDAL.copy(), "steered": 0.0}
        above = wheel["pedal"] + [0.0, 0.0, PEDAL_CLEARANCE]
        self.reachable(self.foot, above, SOLE_ON_PEDAL, what="throttle pedal")
        self.aim(wheel, "wheel")

    def _start_drive(self) -> None:
        """Grasped: from now on the pilot steers and accelerates; the wheel turns with the
        hand from where it holds the rim now (:meth:`measured_steer`)."""
        self.target["held_at"], _ = self.pose(self.hand)
        self.target["steered_when_held"] = float(self.target["steered"])

    def _start_turn_left(self, angle: float = 0.5) -> None:
        self._steer(abs(angle))

    def _start_turn_right(self, angle: float = 0.5) -> None:
        self._steer(-abs(angle))

    def _steer(self, angle: float) -> None:
        if not 0.01 <= abs(angle) <= 3.2:
            raise ValueError(f"steer by 0.01..3.2 rad at a time, got {abs(angle)}")
        self.arc(self.hand, self.target["center"], self.target["axis"], angle, TURN_SPEED)
        self.target["steered"] += angle

    def _start_rotate_foot(self) -> None:
        """Up off the floor, then over the pad: straight there, the toe met the pedal's
        edge (the pad is higher than the resting foot)."""
        above = self.target["pedal"] + [0.0, 0.0, PEDAL_CLEARANCE]
        here, _ = self.pose(self.foot)
        self.line_to(self.foot, [here[0], here[1], max(here[2], above[2])], FOOT_SPEED)
        self.then(lambda: self.line_to(self.foot, above, FOOT_SPEED, SOLE_ON_PEDAL))
        self.foot_on_pedal = True

    def _start_accelerate(self, seconds: float = 1.0, amount: float = 1.0) -> None:
        if not self.foot_on_pedal:
            raise ValueError("the foot is not on the pedal (rotate_foot first)")
        if not 0.1 <= seconds <= 10:
            raise ValueError(f"accelerate for 0.1..10 s, got {seconds}")
        if not 0.1 <= amount <= 1.0:
            raise ValueError(f"press the throttle 0.1..1 of its travel, got {amount}")
        above = self.target["pedal"] + [0.0, 0.0, PEDAL_CLEARANCE]
        pressed = self.target["pedal"] - [0.0, 0.0, amount * PRESS_DEPTH]
        self.line_to(self.foot, pressed, FOOT_SPEED,
                     rpy_matrix(0.0, amount * PRESS_TILT - PEDAL_SLOPE, 0.0), contact=True)
        # The pad pushes back: hold the commanded depth, then let it up.
        self.then(lambda: self.hold_for(seconds),
                  lambda: self.line_to(self.foot, above, FOOT_SPEED, SOLE_ON_PEDAL))

    def _start_move_away_foot(self) -> None:
        """Back over where the foot rested, as high as it is over the pad, then down to the
        posture it started in: straight home, the toe caught the pad and held it down."""
        here, _ = self.pose(self.foot)
        position, rotation = self.kinematics.pose(self.rest, self.foot.frame)
        rest = position + rotation @ self.foot.offset
        self.line_to(self.foot, [rest[0], rest[1], max(here[2], rest[2])], FOOT_SPEED,
                     rotation)
        self.then(lambda: self.home(RIGHT_LEG))
        self.foot_on_pedal = False

    def _start_move_away_hand(self) -> None:
        self.home(LEFT_ARM + WAIST)
