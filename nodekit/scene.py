"""The pilots' shared 3-D scene: objects any pilot places, one truth across pilot stations.

Theory of operation
-------------------
The paper's perception pilot superimposed 3-D objects on the scene (the valve,
the door handle, the steering wheel) and every pilot saw them (section 3.1).
Here each object is a :class:`SceneObject`: a name (the task module it belongs
to, or ``footstep_N``), a kind (how it is drawn), a pose in the pelvis frame,
who placed it, from which pilot station and when.  :class:`Scene` merges
edits by *last writer wins* on ``(stamp, station)`` (then content, for a tie): stations apply the same
edits in any order, any number of times, and end with the same scene, so
gateways can exchange them over YARP without a master and a late station
catches up from a whole copy.  A removal is an edit too (``removed``), kept so
an older placement arriving late cannot bring the object back.

Pure data and codecs (the gateway and the PI share them): :mod:`rosnodes.scene_keeper` moves them between the
gateway's ROS topics and the other stations' YARP ports.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Dict, List, Optional, Sequence, Tuple

from yarp_lite.bottle import Bottle

#: How each kind of object is drawn (pilot/view3d_child.py) and which task it feeds.
KINDS = ("valve", "steering_wheel", "door", "drill", "plug", "footstep")
#: The task modules' objects: each task widget's pose fields follow its object.
TASK_OBJECTS = {"drc_valve": "valve", "drc_drive": "steering_wheel", "drc_door": "door",
                "drc_wall": "drill", "drc_plug": "plug"}
NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_]{0,63}$")
REACH = 20.0          # m: a pose farther from the pelvis is a typing error, not a place
FIELDS = 12           # name kind x y z roll pitch yaw sender station stamp removed


class SceneError(ValueError):
    """An object or record that is not one; the text says which field and why."""


@dataclass(frozen=True)
class SceneObject:
    name: str
    kind: str
    pose: Tuple[float, float, float, float, float, float]
    sender: str = ""
    station: int = 0
    stamp: float = 0.0
    removed: bool = False

    @property
    def version(self) -> tuple:
        """The order of edits: time, then station, then (two edits of one station in the
        same clock tick) their content, so every station picks the same one."""
        return (self.stamp, self.station, self.removed, self.pose, self.kind, self.sender)


def checked(name: object, kind: object, pose: object, sender: object = "",
            station: object = 0, stamp: object = 0.0, removed: object = False) -> SceneObject:
    """A :class:`SceneObject` from loose values, or :class:`SceneError` naming the field."""
    if not isinstance(name, str) or not NAME.match(name):
        raise SceneError(f"name: a letter then up to 63 letters, digits or _, got {name!r:.40}")
    if kind not in KINDS:
        raise SceneError(f"kind: one of {', '.join(KINDS)}, got {kind!r:.40}")
    values = list(pose) if isinstance(pose, (list, tuple)) else None
    if values is None or len(values) != 6 or not all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
            for v in values):
        raise SceneError(f"pose: 6 finite numbers (x y z roll pitch yaw), got {pose!r:.80}")
    if math.hypot(*values[:3]) > REACH:
        raise SceneError(f"pose: {math.hypot(*values[:3]):.1f} m from the pelvis, more than "
                         f"{REACH:g} m")
    if not isinstance(sender, str) or len(sender) > 200:
        raise SceneError(f"sender: a name of at most 200 characters, got {sender!r:.40}")
    if not isinstance(station, int) or isinstance(station, bool) or not 0 <= station < 1000:
        raise SceneError(f"station: 0..999, got {station!r:.20}")
    if not isinstance(stamp, (int, float)) or isinstance(stamp, bool) or \
            not math.isfinite(stamp) or stamp < 0:
        raise SceneError(f"stamp: seconds since the epoch, got {stamp!r:.20}")
    if not isinstance(removed, bool):
        raise SceneError(f"removed: true or false, got {removed!r:.20}")
    return SceneObject(name, str(kind), tuple(float(v) for v in values),  # type: ignore[arg-type]
                       sender, station, float(stamp), removed)


def to_bottle(obj: SceneObject) -> Bottle:
    """``name kind x y z roll pitch yaw sender station stamp removed`` (removed as 0/1)."""
    return Bottle([obj.name, obj.kind, *obj.pose, obj.sender, obj.station, obj.stamp,
                   int(obj.removed)])


def from_bottle(bottle: Sequence) -> SceneObject:
    """The inverse of :func:`to_bottle`; :class:`SceneError` for anything else."""
    if len(bottle) != FIELDS:
        raise SceneError(f"a scene record has {FIELDS} values, got {len(bottle)}")
    removed = bottle[11]
    if not isinstance(removed, int) or isinstance(removed, bool) or removed not in (0, 1):
        raise SceneError(f"removed: 0 or 1, got {removed!r:.20}")
    stamp = bottle[10]
    return checked(bottle[0], bottle[1], list(bottle[2:8]), bottle[8], bottle[9],
                   float(stamp) if isinstance(stamp, int) and not isinstance(stamp, bool)
                   else stamp, bool(removed))


class Scene:
    """The objects as this station knows them; edits merge, last writer wins."""

    def __init__(self) -> None:
        self._objects: Dict[str, SceneObject] = {}

    def apply(self, edit: SceneObject) -> bool:
        """Take ``edit`` if it is newer than what is known of its object; whether it was."""
        known = self._objects.get(edit.name)
        if known is not None and known.version >= edit.version:
            return False
        self._objects[edit.name] = edit
        return True

    def objects(self) -> List[SceneObject]:
        """The objects placed and not removed, by name."""
        return [obj for _, obj in sorted(self._objects.items()) if not obj.removed]

    def records(self) -> List[SceneObject]:
        """Everything known, removals included: what a late station needs."""
        return [obj for _, obj in sorted(self._objects.items())]

    def get(self, name: str) -> Optional[SceneObject]:
        obj = self._objects.get(name)
        return None if obj is None or obj.removed else obj
