"""``tf2_msgs/TFMessage`` of a posture: the links' placements as ``/tf`` carries them.

One builder for the robot's own ``/tf`` (``walkman-joint-state``) and the pilot
PC's preview ghost, whose frames carry a prefix (``preview/l_hand``) that RViz's
second robot model reads with its *TF Prefix*.
"""

from __future__ import annotations

from typing import Iterable, Sequence, Tuple

Placement = Tuple[str, Sequence[float], Sequence[float]]   # link, xyz, quaternion xyzw


def transform(parent: str, child: str, position: Sequence[float],
              quaternion: Sequence[float], now):
    """One ``geometry_msgs/TransformStamped``."""
    from geometry_msgs.msg import TransformStamped

    out = TransformStamped()
    out.header.stamp, out.header.frame_id, out.child_frame_id = now, parent, child
    (out.transform.translation.x, out.transform.translation.y,
     out.transform.translation.z) = (float(v) for v in position)
    (out.transform.rotation.x, out.transform.rotation.y, out.transform.rotation.z,
     out.transform.rotation.w) = (float(v) for v in quaternion)
    return out


def tf_message(placements: Iterable[Placement], now, root: str = "pelvis", prefix: str = "",
               extra: Iterable = ()):
    """Every placement as a child of ``root``, names prefixed with ``prefix/`` if given
    (``root`` too, hung from the unprefixed root at identity); ``extra`` transforms added."""
    from tf2_msgs.msg import TFMessage

    name = (lambda link: f"{prefix}/{link}") if prefix else (lambda link: link)
    transforms = [transform(root, name(root), (0, 0, 0), (0, 0, 0, 1), now)] if prefix else []
    transforms += [transform(name(root), name(link), position, quaternion, now)
                   for link, position, quaternion in placements]
    return TFMessage(transforms + list(extra))
