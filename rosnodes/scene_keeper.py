"""The gateway's part of the shared 3-D scene: ROS on this pilot PC, YARP between stations.

Theory of operation
-------------------
On the pilot roscore a Pilot Interface publishes an object it placed or dragged
on ``/pilot/scene_edit`` (``walkman_msgs/SceneObject``); the keeper stamps it with
this station and its clock, merges it into its :class:`nodekit.scene.Scene` and,
when it changed anything, publishes the whole scene latched on ``/pilot/scene``
(so a PI started later, and ``rosbag record``, see it at once) and writes the edit
on ``/pilot_gateway/<station>/scene:o``.  It reads every other station's
``scene:o`` (the gateway finds them as it finds their ``sent:o``) on ``scene:i`` and
merges what comes the same way.  Every 2 s it writes its whole scene again: a
station that came later, or missed an edit, catches up; merging is idempotent,
so the repeats cost a few hundred bytes and change nothing.  A malformed edit
from a PI or a malformed record from a station is logged and dropped.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from typing import Any

from nodekit.scene import Scene, SceneError, SceneObject, checked, from_bottle, to_bottle
from yarp_lite.bottle import Bottle
from yarp_lite.nameclient import NameClient
from yarp_lite.port import Port

log = logging.getLogger("walkman.gateway")
RESEND_S = 2.0


class SceneKeeper:
    """This station's copy of the shared scene, its ``scene:o`` and ``scene:i`` ports (opened
    here) and, once :meth:`open_ros` ran, its ROS topics (see the module's docstring)."""

    def __init__(self, station: int, prefix: str, nameclient: NameClient) -> None:
        self.station = station
        self.scene = Scene()
        self._lock = threading.Lock()
        self._publisher = None
        self.out = Port(nameclient=nameclient)
        self.out.open(f"{prefix}/scene:o", wait=math.inf)
        self.into = Port(nameclient=nameclient, reader=self._on_record)
        self.into.open(f"{prefix}/scene:i", wait=math.inf)
        self._stop = threading.Event()
        self._resender = threading.Thread(target=self._resend, name="gateway scene", daemon=True)
        self._resender.start()

    # -- ROS ---------------------------------------------------------------------------------

    def open_ros(self) -> None:
        import rospy
        from walkman_msgs.msg import Scene as SceneMsg
        from walkman_msgs.msg import SceneObject as SceneObjectMsg

        self._publisher = rospy.Publisher("/pilot/scene", SceneMsg, queue_size=5, latch=True)
        rospy.Subscriber("/pilot/scene_edit", SceneObjectMsg, self._on_edit, queue_size=50)
        self._publish()

    def _on_edit(self, msg: Any) -> None:
        try:
            edit = checked(msg.name, msg.kind, list(msg.pose), msg.sender, self.station,
                           time.time(), bool(msg.removed))
        except SceneError as exc:
            log.warning("gateway: a scene edit refused (%s): %s", msg.sender or "?", exc)
            return
        if self._merge(edit):
            log.info("gateway: scene: %s %s %s (from %s)", edit.name,
                     "removed" if edit.removed else "at",
                     "" if edit.removed else " ".join(f"{v:.3f}" for v in edit.pose),
                     edit.sender)
            self._write(edit)

    def _publish(self) -> None:
        if self._publisher is None:
            return
        import rospy
        from walkman_msgs.msg import Scene as SceneMsg
        from walkman_msgs.msg import SceneObject as SceneObjectMsg

        with self._lock:
            objects = self.scene.objects()
        msg = SceneMsg(objects=[SceneObjectMsg(name=o.name, kind=o.kind, pose=list(o.pose),
                                               sender=o.sender, station=o.station,
                                               stamp=o.stamp, removed=o.removed)
                                for o in objects])
        msg.header.stamp = rospy.Time.now()
        self._publisher.publish(msg)

    # -- YARP ---------------------------------------------------------------------------------

    def _merge(self, edit: SceneObject) -> bool:
        with self._lock:
            changed = self.scene.apply(edit)
        if changed:
            self._publish()
        return changed

    def _write(self, edit: SceneObject) -> None:
        # Port.write never raises for a peer: it drops the output that failed (logging why)
        # and says so by returning False.
        if not self.out.write(to_bottle(edit)):
            log.warning("gateway: scene edit of %s not written to every other station (the "
                        "output that failed is dropped)", edit.name)

    def _on_record(self, bottle: Bottle) -> None:
        try:
            edit = from_bottle(bottle)
        except SceneError as exc:
            log.warning("gateway: a malformed scene record from another station (%s): %s",
                        exc, str(bottle)[:120])
            return
        if edit.station != self.station and self._merge(edit):
            log.info("gateway: scene: %s from station %d (%s)", edit.name, edit.station,
                     edit.sender)

    def _resend(self) -> None:
        while not self._stop.wait(RESEND_S):
            with self._lock:
                records = self.scene.records()
            for record in records:
                self._write(record)

    def close(self) -> None:
        """Stop rewriting the scene, then close the ports (a write on a closing port would
        only be logged, but the resend loop is done before they go)."""
        self._stop.set()
        if self._resender is not threading.current_thread():
            self._resender.join(timeout=5.0)
        for port in (self.out, self.into):
            port.close()

