"""perception: the robot's head camera as a GYM module the pilot starts, pauses and retargets.

Theory of operation
-------------------
The paper built perception on the GYM template like every other module (section
3.1), so the perception pilot could stop it to free the link, ask a lower rate
or a smaller picture when the link is bad, and start it again.  This module
drives :class:`walkman.head_camera.HeadCamera` (the same camera
``walkman-perception`` runs as a plain ROS node) and publishes the Multisense
topics on the robot's roscore; the bridge carries them to the pilots.

Its control thread ticks every 50 ms (``contexts/perception/perception.ini``)
and renders when a frame is due at the rate asked (2 Hz unless the pilot says):
paused or stopped, no frame is rendered or sent.  Commands:

* ``set_rate HZ``: 0 (no frames, the module stays running) .. 30;
* ``set_resolution W H``: 16x16 .. 1280x960 pixels (drops the region);
* ``set_region X Y W H``: send only this window of the picture, in pixels
  (``CameraInfo.roi`` says where it lies); ``full_frame`` sends all again.

Its status is ``waiting`` (no scene from the HAL yet), ``streaming`` or ``idle``
(rate 0) with the rate, the resolution and the window sent; a scene that stops
coming for 10 s is warned once.
"""

from __future__ import annotations

import logging
import os
import time
from typing import Any, Dict, List, Optional

from walkman.gym.link_loss import LinkLoss
from walkman.gym.thread import GenericThread
from walkman.head_camera import MAX_SIZE, FrameClock, HeadCamera, Region, topics

log = logging.getLogger(__name__)

DEFAULT_RATE = 2.0
MAX_RATE = 30.0
SILENT_WORLD_S = 10.0


class Module(GenericThread):
    statuses = ["waiting", "streaming", "idle"]
    arguments = {"set_rate": (1, 1, "HZ frames per second, 0..30"),
                 "set_resolution": (2, 2, "W H pixels"),
                 "set_region": (4, 4, "X Y W H pixels of the picture"),
                 "full_frame": (0, 0, "")}
    status_format = {"*": "{0:g} Hz, {1:.0f}x{2:.0f} px, sending {5:.0f}x{6:.0f} at "
                          "({3:.0f}, {4:.0f})"}
    # What the camera sees is the pilots' only view of the scene: it goes on while the link
    # is down, so the pictures are there the moment it returns.
    link_loss = LinkLoss.CONTINUE

    def custom_init(self) -> bool:
        from nodekit.connections import ConnectionKeeper
        from nodekit.msgs import ensure_importable
        from nodekit.ros_node import RosNode

        os.environ.setdefault("MUJOCO_GL", "osmesa")
        ensure_importable()
        robot = str(self.config.get("robot_name", "walkman"))
        self.camera = HeadCamera(robot, DEFAULT_RATE, int(self.config.get("width", 320)),
                                 int(self.config.get("height", 240)),
                                 int(self.config.get("cloud_step", 4)))
        self.rate = float(self.config.get("rate", DEFAULT_RATE))
        self.frames_due: Optional[FrameClock] = FrameClock(self.rate) if self.rate else None
        self.publishers: Dict[str, Any] = {}
        self.ros = RosNode(str(self.config.get("ros_name", "walkman_perception")))
        self.ros.when_ready(lambda: self.publishers.update(topics()))
        self.ros.start()
        self.keeper = ConnectionKeeper()
        self.camera.open_yarp(self.keeper, f"/{self.name.strip('/')}/world:i")
        self.keeper.start()
        self.next_frame = 0.0
        self.world_since: Optional[float] = None   # when the scene was last seen
        self.silence_warned = False
        self.report()
        return True

    def custom_resume(self) -> bool:
        self.frames_due = FrameClock(self.rate) if self.rate else None   # no burst of frames
        self.next_frame = 0.0
        return True

    def custom_release(self) -> None:
        self.keeper.stop()
        self.camera.close_port()
        self.camera.camera.close()
        self.ros.stop()

    # -- the loop ------------------------------------------------------------------------

    def run(self) -> None:
        command = self.command_interface.get_command()
        if command is not None:
            self.handle(command.name, list(command.args))
        if self.frames_due is None or not self.publishers or time.monotonic() < self.next_frame:
            return
        self.next_frame = time.monotonic() + self.frames_due.wait()
        import rospy

        sent = self.camera.publish(self.publishers, rospy.Time.now())
        now = time.monotonic()
        if sent:
            self.world_since, self.silence_warned = now, False
            progress = self.camera.progress()
            if progress:
                log.info("%s: %s", self.name.lstrip("/"), progress)
        elif self.world_since is not None and now - self.world_since > SILENT_WORLD_S and \
                not self.silence_warned:
            self.silence_warned = True
            self.warning_interface.warn(
                f"{self.name.lstrip('/')}: no scene from /{self.camera.robot}/sim/world:o for "
                f"{SILENT_WORLD_S:g} s (is walkman-hal running the sim?); no pictures meanwhile")
        if self.world_since is None and self.camera.world is not None:
            self.world_since = now
        self.report()

    # -- the pilot's commands ------------------------------------------------------------

    def handle(self, name: str, args: List[Any]) -> None:
        try:
            numbers = [float(a) for a in args]
        except (TypeError, ValueError):
            self.refuse(f"{name} takes numbers, got {args}")
            return
        try:
            if name == "set_rate" and len(numbers) == 1:
                self.set_rate(numbers[0])
            elif name == "set_resolution" and len(numbers) == 2:
                self.camera.resize(*self._pixels(numbers))
            elif name == "set_region" and len(numbers) == 4:
                self.camera.set_region(Region(*self._pixels(numbers)))
            elif name == "full_frame" and not numbers:
                self.camera.set_region(None)
            else:
                offered = ", ".join(f"{command} ({usage or 'no numbers'})"
                                    for command, (_, _, usage) in self.arguments.items())
                self.refuse(f"command '{name}' with {len(args)} numbers is not one of "
                            f"{offered}")
                return
        except ValueError as error:
            self.refuse(f"{name} {' '.join(map(str, args))}: {error}")
            return
        self.report()

    def set_rate(self, rate: float) -> None:
        if not 0.0 <= rate <= MAX_RATE:
            raise ValueError(f"a rate is 0..{MAX_RATE:g} frames per second, got {rate:g}")
        self.rate = rate
        self.frames_due = FrameClock(rate) if rate > 0 else None
        self.next_frame = 0.0

    @staticmethod
    def _pixels(numbers: List[float]) -> List[int]:
        if any(n != int(n) or n < 0 or n > max(MAX_SIZE) for n in numbers):
            raise ValueError(f"pixels are whole numbers 0..{max(MAX_SIZE)}, got "
                             f"{[f'{n:g}' for n in numbers]}")
        return [int(n) for n in numbers]

    def refuse(self, text: str) -> None:
        self.warning_interface.warn(f"{self.name.lstrip('/')}: {text}")

    def report(self) -> None:
        camera = self.camera.camera
        region = self.camera.region or Region(0, 0, camera.width, camera.height)
        state = "idle" if self.rate == 0 else \
            "waiting" if self.camera.world is None else "streaming"
        self.status_interface.set_status(state, self.rate, camera.width, camera.height,
                                         region.x, region.y, region.width, region.height)
