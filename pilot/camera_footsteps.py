"""Footsteps from the head camera's last cloud, as the PI places them (sans-IO).

The cloud comes in the camera's optical frame; it is taken to the pelvis frame by the
robot's last joint state (the URDF's ``multisense_frame`` and the optical turn, as ``/tf``
would), and :func:`walkman.control.ground_ahead.footsteps_from_cloud` places the footsteps
from where the soles stand.  A refusal names the cloud it was judged on -- its size and its
age: over the DRC link a cloud is 0.6-0.9 s old when it arrives, and one rendered before
perception took the pilot's finer settings came 1.3 s late at a quarter of the points; its
coarse rows refused the floor as sloping.  Seeing "1200 points, 1.3 s old", a pilot knows to
click again on the next one.
"""

from __future__ import annotations

from typing import Any, List, Optional, Sequence, Tuple

from pilot.link import CloudEvent

Pose = Tuple[float, ...]


def footsteps_from_camera(cloud: Optional[CloudEvent], posture: Optional[Sequence[float]],
                          kinematics: Any, distance: float,
                          now: float) -> Tuple[List[Pose], str]:
    """Footsteps ``distance`` m ahead placed on ``cloud`` with the robot in ``posture``
    (``kinematics``: :class:`walkman.control.kinematics.Kinematics`; ``now``: the wall
    clock, s, what the cloud's age is told by): (footsteps, "") or ([], why not)."""
    from walkman.control.ground_ahead import GroundError, footsteps_from_cloud
    from walkman.head_camera import FRAME, optical_to
    from walkman.modules.walking import sole_poses

    if posture is None:
        return [], "the feet's posture is not known yet (no joint state from the robot)"
    if cloud is None or cloud.xyz is None:
        return [], "no point cloud from the head camera yet (is perception running?)"
    if cloud.frame not in ("", FRAME):
        return [], f"the cloud is in {cloud.frame}, not {FRAME}"
    points = optical_to(cloud.xyz, *kinematics.pose(posture, "multisense_frame"))
    try:
        return footsteps_from_cloud(points, sole_poses(kinematics, posture), distance), ""
    except GroundError as exc:
        age = max(0.0, now - cloud.stamp_ns * 1e-9)
        return [], (f"no footsteps from the camera: {exc} (judged on a cloud of "
                    f"{cloud.points} points, {age:.1f} s old)")
