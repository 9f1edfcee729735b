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
import time
from typing import Optional, Sequence

import numpy as np
import pinocchio as pin

from walkman.control.fsm import StateMachine
from walkman.control.ik import InverseKinematics
from walkman.control.trajectory import CartesianTrajectory, JointTrajectory, duration_for
from walkman.gym.thread import ControlThread

ARM = ["LShSag", "LShLat", "LShYaw", "LElbj", "LForearmPlate", "LWrj1", "LWrj2"]
WAIST = ["WaistLat", "WaistSag", "WaistYaw"]
JOINTS = ARM + WAIST
HAND = "l_handj"
FRAME = "l_hand"
GRIP = np.array([0.0, 0.0, -0.1])     # the grip point in the hand frame (models: l_hand_grip)
APPROACH_GAP = 0.045                  # m in front of the rim when approached (grasp within 6 cm)
REACH_GAP = 0.165                     # m in front of the rim when reached
HAND_CLOSED, HAND_OPEN = 1.2, 0.0     # rad
ACTION_TOLERANCE = 0.01               # m, FACTS.md: action_done under 1 cm
OVERDUE_S = 2.0                       # s after a trajectory's end before saying it is stuck
SPEED = 0.15                          # m/s, peak Cartesian speed
TURN_SPEED = 0.6                      # rad/s, peak wheel speed

COMMANDS = ("valvedatasent", "reach", "approach", "grasp", "turn", "ungrasp", "move_away",
            "home")  # the pilot's; action_done and hand_done are the module's own events
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


class Module(ControlThread):
    statuses = list(TABLE) + ["refused"]

    def custom_init(self) -> bool:
        self.fsm = StateMachine(TABLE, "idle", "drc_valve")
        self.ik = InverseKinematics(self.kinematics)
        self.joints = self.ik.joints_of(JOINTS)
        self.hand = self.robot.index[HAND]
        self.command_joints = JOINTS + [HAND]
        self.rest = self.robot.sense_position()
        self.reference = self.rest.copy()
        self.trajectory = CartesianTrajectory()
        self.joint_trajectory: Optional[JointTrajectory] = None
        self.full_pose = False
        self.goal: Optional[np.ndarray] = None
        self.hand_goal: Optional[float] = None
        self.valve: Optional[dict] = None
        self._report()
        return True

    # -- the pilot's commands ----------------------------------------------------------

    def run(self) -> None:
        command = self.command_interface.get_command()
        if command is not None:
            self.handle(command.name, command.args)
        self.track()

    def handle(self, name: str, args: Sequence) -> None:
        if name not in COMMANDS:
            self.warning_interface.warn(f"drc_valve: unknown command '{name}' (commands: "
                                        f"{', '.join(COMMANDS)})")
            return
        if not self.fsm.accepts(name):
            step = self.fsm.fire(name)  # refused: the state stays, the pilot hears why
            self.warning_interface.warn(step.reason)
            return
        try:
            start = getattr(self, f"_start_{name}")
            start(*self._numbers(name, args))
        except (TypeError, ValueError) as exc:
            self.warning_interface.warn(f"drc_valve: {name} refused: {exc}")
            return
        self.fsm.fire(name)
        self._report()

    @staticmethod
    def _numbers(name: str, args: Sequence) -> list:
        values = []
        for value in args:
            if isinstance(value, bool) or not isinstance(value, (int, float)) or \
                    not math.isfinite(value):
                raise ValueError(f"'{value}' is not a finite number")
            values.append(float(value))
        wanted = {"valvedatasent": (7, 7), "turn": (0, 1)}.get(name, (0, 0))
        if not wanted[0] <= len(values) <= wanted[1]:
            raise ValueError(f"takes {wanted[0]}..{wanted[1]} numbers, got {len(values)}"
                             if wanted[0] != wanted[1] else
                             f"takes {wanted[0]} numbers (X Y Z ROLL PITCH YAW RADIUS), got "
                             f"{len(values)}")
        return values

    def _start_valvedatasent(self, x, y, z, roll, pitch, yaw, radius) -> None:
        if not 0.05 <= radius <= 0.5:
            raise ValueError(f"radius {radius} m is not a valve's (0.05..0.5)")
        rotation = rpy_matrix(roll, pitch, yaw)
        center = np.array([x, y, z])
        axis = rotation[:, 0]
        grip = center + radius * rotation[:, 2]
        valve = {"center": center, "axis": axis, "grip": grip, "radius": radius,
                 "approach": grip - APPROACH_GAP * axis, "reach": grip - REACH_GAP * axis}
        q = self.robot.sense_position()
        for point in ("reach", "approach"):
            result = self.ik.solve(FRAME, valve[point], None, q, JOINTS, offset=GRIP,
                                   restarts=6, rest=self.rest)
            if not result.reached:
                self.status_interface.set_status("refused", *map(float, valve[point]))
                raise ValueError(f"the hand cannot reach the valve's {point} point "
                                 f"{np.round(valve[point], 3).tolist()} (misses by "
                                 f"{result.position_error * 100:.1f} cm)")
        self.valve = valve

    def _start_reach(self) -> None:
        self._line_to(self.valve["reach"])

    def _start_approach(self) -> None:
        self._line_to(self.valve["approach"])

    def _start_move_away(self) -> None:
        # Back to the reach point: checked reachable at valvedatasent, clear of the wheel.
        self._line_to(self.valve["reach"])

    def _start_grasp(self) -> None:
        self.hand_goal = HAND_CLOSED

    def _start_ungrasp(self) -> None:
        self.hand_goal = HAND_OPEN

    def _start_turn(self, angle: float = math.pi / 2) -> None:
        if abs(angle) > 2 * math.pi:
            raise ValueError(f"turn by at most 2 pi rad, got {angle}")
        position, rotation = self.hand_pose()
        self.trajectory.set_circular((position, rotation), self.valve["center"],
                                     self.valve["axis"], angle,
                                     duration_for(angle, TURN_SPEED, 1.0), time.monotonic())
        self.full_pose = True
        self.goal = self.trajectory.goal()[0]
        self._said_overdue = False

    def _start_home(self) -> None:
        self.trajectory.reset()
        now = self.robot.sense_position()
        distance = float(np.max(np.abs(self.rest[self.joints] - now[self.joints])))
        self.joint_trajectory = JointTrajectory(now[self.joints], self.rest[self.joints],
                                                duration_for(distance, 0.5, 1.0),
                                                time.monotonic())

    def _line_to(self, goal: np.ndarray) -> None:
        start = self.grip_point()
        self.trajectory.set_linear((start, np.eye(3)), (goal, np.eye(3)),
                                   duration_for(float(np.linalg.norm(goal - start)), SPEED, 1.0),
                                   time.monotonic())
        self.full_pose = False
        self.goal = goal
        self._said_overdue = False

    # -- every tick --------------------------------------------------------------------

    def hand_pose(self):
        position, rotation = self.kinematics.pose(self.robot.sense_position(), FRAME)
        return position + rotation @ GRIP, rotation

    def grip_point(self) -> np.ndarray:
        return self.hand_pose()[0]

    def track(self) -> None:
        now = time.monotonic()
        if self.trajectory.active:
            position, rotation = self.trajectory.at(now)
            result = self.ik.solve(FRAME, position, rotation if self.full_pose else None,
                                   self.reference, JOINTS, offset=GRIP, restarts=0,
                                   rest=self.rest)
            self.reference[self.joints] = result.q[self.joints]
            if self.trajectory.done(now):
                error = float(np.linalg.norm(self.grip_point() - self.goal))
                if error < ACTION_TOLERANCE:
                    self.trajectory.reset()
                    self._event("action_done")
                elif now - self.trajectory.t0 > self.trajectory.duration + OVERDUE_S and \
                        not self._said_overdue:
                    self._said_overdue = True
                    self.warning_interface.warn(
                        f"drc_valve: {self.fsm.state}: the hand stays {error * 100:.1f} cm from "
                        f"its goal (IK {result.position_error * 100:.1f} cm); still trying")
        elif self.joint_trajectory is not None:
            self.reference[self.joints] = self.joint_trajectory.at(now)
            if self.joint_trajectory.done(now):
                self.joint_trajectory = None
                self._event("action_done")
        if self.hand_goal is not None:
            self.reference[self.hand] = self.hand_goal
            sensed = self.robot.sense_position()[self.hand]
            if abs(sensed - self.hand_goal) < 0.3:
                self.hand_goal = None
                self._event("hand_done")
        self.robot.move(self.reference, joints=self.command_joints)

    def _event(self, event: str) -> None:
        self.fsm.fire(event)
        self._report()

    def _report(self) -> None:
        data = [] if self.valve is None else [float(v) for v in self.valve["center"]]
        self.status_interface.set_status(self.fsm.state, *data)

    def custom_pause(self) -> bool:
        self.reference = self.robot.sense_position()  # hold where we are
        return True

    def custom_resume(self) -> bool:
        if self.trajectory.active:  # finish the motion from where the hand is now
            goal = self.goal
            if self.full_pose:
                self.warning_interface.warn("drc_valve: a turn paused halfway ends here; send "
                                            "turn again for the rest")
                self.trajectory.reset()
                self._event("action_done")
            else:
                self._line_to(goal)
        return True
