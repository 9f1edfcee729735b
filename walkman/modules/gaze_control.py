"""gaze_control: the head looks at a point the pilot gives.

Commands (pelvis frame, metres): ``look_at X Y Z`` (or ``(look_at X Y Z) SEQ``),
``home`` (look straight ahead), ``set_time T`` (seconds per head motion).
The neck angles come from the kinematic model (the camera's forward axis is
aimed at the point) and the head gets there along a quintic trajectory.  A
point outside the neck's range is refused with a warning; the head stays.
"""

from __future__ import annotations

import math
from typing import Optional, Tuple

import numpy as np

from walkman.control.trajectory import JointTrajectory
from walkman.gym.link_loss import LinkLoss
from walkman.gym.thread import ControlThread

NECK = ("NeckYawj", "NeckPitchj")
AIM_TOLERANCE = math.radians(1.0)


def aim_error(kinematics, q: np.ndarray, target: np.ndarray) -> Tuple[float, float]:
    """(yaw error, pitch error) of the camera's forward axis towards ``target``."""
    position, rotation = kinematics.pose(q, "multisense_frame")
    direction = rotation.T @ (target - position)  # target in the camera frame
    yaw_error = math.atan2(direction[1], direction[0])
    pitch_error = -math.atan2(direction[2], math.hypot(direction[0], direction[1]))
    return yaw_error, pitch_error


def neck_angles(kinematics, q: np.ndarray, target: np.ndarray,
                iterations: int = 8) -> Tuple[np.ndarray, float]:
    """Neck joint values aiming the camera at ``target``; returns them and the residual."""
    q = np.array(q, dtype=float)
    yaw, pitch = (kinematics.joint_names.index(name) for name in NECK)
    for _ in range(iterations):
        yaw_error, pitch_error = aim_error(kinematics, q, target)
        q[yaw] += yaw_error
        q[pitch] += pitch_error
        if abs(yaw_error) + abs(pitch_error) < 1e-5:
            break
    residual = math.hypot(*aim_error(kinematics, q, target))
    return q[[yaw, pitch]], residual


class Module(ControlThread):
    statuses = ["ready", "moving", "tracking", "unreachable"]
    status_format = {"unreachable": "target ({0:.2f}, {1:.2f}, {2:.2f}) m",
                     "*": "neck yaw {0:.2f} rad, pitch {1:.2f} rad"}
    arguments = {"look_at": (3, 3, "X Y Z m, pelvis frame"), "track": (3, 3, "X Y Z m"),
                 "home": (0, 0, ""), "set_time": (1, 1, "T s, 0.1..20")}
    # The head moves nothing else and keeps looking where the pilot will want to see when
    # the link returns.
    link_loss = LinkLoss.CONTINUE

    def custom_init(self) -> bool:
        self.duration = float(self.config.get("trajectory_time", 1.5))
        self.neck = [self.robot.index[name] for name in NECK]
        self.lower = self.robot.lower[self.neck]
        self.upper = self.robot.upper[self.neck]
        self.reference = self.robot.sense_position()
        self.trajectory: Optional[JointTrajectory] = None
        self.target: Optional[np.ndarray] = None
        self.status_interface.set_status("ready")
        return True

    def custom_resume(self) -> bool:
        if self.trajectory is not None:  # finish the interrupted motion from where we are
            now = self.now()
            remaining = max(0.3, self.trajectory.duration - (now - self.trajectory.t0))
            self.trajectory = JointTrajectory(self.robot.sense_position()[self.neck],
                                              self.trajectory.goal, remaining, now)
        return True

    def handle(self, command) -> None:
        name = command.name
        if name in ("look_at", "track") and len(command.args) == 3:
            try:
                target = np.array([float(value) for value in command.args])
            except (TypeError, ValueError):
                self.warning_interface.warn(f"gaze_control: look_at needs 3 numbers, got "
                                            f"{command.args}")
                return
            self.look_at(target)
        elif name == "home":
            self.go(np.zeros(2))
            self.target = None
        elif name == "set_time" and len(command.args) == 1:
            value = float(command.args[0]) if isinstance(command.args[0], (int, float)) else 0.0
            if 0.1 <= value <= 20:
                self.duration = value
            else:
                self.warning_interface.warn(f"gaze_control: set_time needs 0.1..20 s, got "
                                            f"{command.args[0]}")
        else:
            self.warning_interface.warn(
                f"gaze_control: command '{name}' with {len(command.args)} arguments is not "
                f"valid (look_at X Y Z, home, set_time T)")

    def look_at(self, target: np.ndarray) -> None:
        q = self.robot.sense_position()
        goal, residual = neck_angles(self.kinematics, q, target)
        if np.any(goal < self.lower - 1e-6) or np.any(goal > self.upper + 1e-6) or \
                residual > AIM_TOLERANCE or not np.all(np.isfinite(goal)):
            self.status_interface.set_status("unreachable", *map(float, target))
            self.warning_interface.warn(
                f"gaze_control: cannot look at {np.round(target, 3).tolist()} (neck would need "
                f"{np.round(np.degrees(goal), 1).tolist()} deg); the head stays")
            return
        self.target = target
        self.go(goal)

    def go(self, goal: np.ndarray) -> None:
        start = self.reference[self.neck]
        self.trajectory = JointTrajectory(start, np.clip(goal, self.lower, self.upper),
                                          self.duration, self.now())
        self.status_interface.set_status("moving", *map(float, goal))

    def run(self) -> None:
        command = self.command_interface.get_command()
        if command is not None:
            self.handle(command)
        if self.trajectory is None:
            return
        now = self.now()
        self.reference[self.neck] = self.trajectory.at(now)
        self.robot.move(self.reference, joints=NECK)
        if self.trajectory.done(now):
            goal = self.trajectory.goal
            self.trajectory = None
            self.status_interface.set_status("tracking" if self.target is not None else "ready",
                                             *map(float, goal))
