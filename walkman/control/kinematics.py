"""Kinematics of Walk-Man from its URDF, in whole-body joint order (Pinocchio).

The pelvis is the fixed base: positions are expressed in the pelvis frame
(``base``); a module that walks keeps its own estimate of where the pelvis
is in the world.  Frames are the URDF links (``torso``,
``head``, ``l_hand``...) and the sensor frames (``multisense_frame``,
``l_arm_ft_frame``...).
"""

from __future__ import annotations

from pathlib import Path
from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np
import pinocchio as pin

from walkman.model import URDF_PATH
from walkman.model.description import Robot, walkman


class Kinematics:
    def __init__(self, urdf_path: Optional[Path] = None, model: Optional[Robot] = None) -> None:
        self.robot = model or walkman()
        self.model = pin.buildModelFromUrdf(str(urdf_path or URDF_PATH))
        self.data = self.model.createData()
        names = [self.model.names[i] for i in range(1, self.model.njoints)]
        # whole-body index -> pinocchio configuration index
        self.to_pin = np.array([names.index(name) for name in self.robot.joint_names])
        self.joint_names = self.robot.joint_names
        self._frames: Dict[str, int] = {}

    def frame_id(self, frame: str) -> int:
        if frame not in self._frames:
            if not self.model.existFrame(frame):
                raise KeyError(f"no frame {frame!r} in the model")
            self._frames[frame] = self.model.getFrameId(frame)
        return self._frames[frame]

    def pin_q(self, q: Sequence[float]) -> np.ndarray:
        out = np.zeros(self.model.nq)
        out[self.to_pin] = np.asarray(q, dtype=float)
        return out

    def link_placements(self, q: Sequence[float]) -> List[Tuple[str, np.ndarray, np.ndarray]]:
        """``(link, position, quaternion xyzw)`` of every body frame but the pelvis, in the
        pelvis frame: what ``/tf`` carries of a posture (the robot's, or a preview's)."""
        pin.framesForwardKinematics(self.model, self.data, self.pin_q(q))
        out = []
        for frame_id, frame in enumerate(self.model.frames):
            if frame.type != pin.FrameType.BODY or frame.name in ("pelvis", "universe"):
                continue
            placement = self.data.oMf[frame_id]
            quaternion = pin.Quaternion(placement.rotation)
            out.append((frame.name, placement.translation.copy(),
                        np.array([quaternion.x, quaternion.y, quaternion.z, quaternion.w])))
        return out

    def pose(self, q: Sequence[float], frame: str) -> Tuple[np.ndarray, np.ndarray]:
        """(position, rotation matrix) of ``frame`` in the pelvis frame."""
        pin.framesForwardKinematics(self.model, self.data, self.pin_q(q))
        placement = self.data.oMf[self.frame_id(frame)]
        return placement.translation.copy(), placement.rotation.copy()

    def point(self, q: Sequence[float], frame: str, offset: Sequence[float]) -> np.ndarray:
        """Where a point fixed in ``frame`` (``offset`` in that frame) is, pelvis frame."""
        position, rotation = self.pose(q, frame)
        return position + rotation @ np.asarray(offset, dtype=float)

    def jacobian(self, q: Sequence[float], frame: str) -> np.ndarray:
        """6 x 33 Jacobian (linear; angular) in the pelvis-aligned frame, whole-body columns."""
        pq = self.pin_q(q)
        pin.computeJointJacobians(self.model, self.data, pq)
        pin.framesForwardKinematics(self.model, self.data, pq)
        full = pin.getFrameJacobian(self.model, self.data, self.frame_id(frame),
                                    pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
        return full[:, self.to_pin]

    def com(self, q: Sequence[float]) -> np.ndarray:
        """The whole robot's centre of mass in the pelvis frame."""
        return pin.centerOfMass(self.model, self.data, self.pin_q(q)).copy()

    def gravity(self, q: Sequence[float]) -> np.ndarray:
        """Joint torques (N*m) that hold the limbs up, the pelvis fixed and level."""
        return pin.computeGeneralizedGravity(self.model, self.data, self.pin_q(q))[self.to_pin]

    def wrench_torques(self, q: Sequence[float], frame: str,
                       wrench: Sequence[float]) -> np.ndarray:
        """Joint torques (N*m, whole-body columns) that a wrench ``(f, t)`` measured in
        ``frame`` (an F/T sensor's: what the limb exerts on what is below it) puts on the
        joints above it: ``J^T w``, the static transpose-Jacobian map."""
        _, rotation = self.pose(q, frame)
        w = np.asarray(wrench, dtype=float)
        aligned = np.concatenate([rotation @ w[:3], rotation @ w[3:6]])
        return self.jacobian(q, frame).T @ aligned
