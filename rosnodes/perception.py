"""``walkman-perception``: the head camera of the simulated robot, on the robot's roscore.

Theory of operation
-------------------
The HAL's simulator publishes the whole scene's positions on
``/<robot>/sim/world:o`` (30 Hz).  This node keeps a copy of the same MuJoCo
scene, poses it from the latest reading, and renders the ``multisense`` camera
on the CPU (OSMesa, no display needed) at ``--rate`` Hz:

=================================  ============================================
``/multisense/left/image_color``   ``sensor_msgs/Image`` rgb8
``/multisense/depth``              ``sensor_msgs/Image`` 32FC1, metres, NaN = sky
``/multisense/left/camera_info``   ``sensor_msgs/CameraInfo`` (pinhole from fovy)
``/multisense/points``             ``sensor_msgs/PointCloud2`` organized, xyz + rgb,
                                   one point every ``--cloud-step`` pixels
=================================  ============================================

All in the ``multisense_optical_frame`` (z forward, x right, y down).  The
geometry (:func:`intrinsics`, :func:`cloud_points`) is pure numpy, tested
without a renderer.
"""

from __future__ import annotations

import argparse
import logging
import math
import os
import sys
import threading
import time
from typing import Optional, Tuple

import numpy as np

log = logging.getLogger("walkman.perception")

FRAME = "multisense_optical_frame"
CAMERA = "multisense"


def intrinsics(width: int, height: int, fovy_deg: float) -> Tuple[float, float, float]:
    """``(f, cx, cy)`` in pixels of MuJoCo's pinhole camera (square pixels)."""
    f = height / 2.0 / math.tan(math.radians(fovy_deg) / 2.0)
    return f, (width - 1) / 2.0, (height - 1) / 2.0


def cloud_points(depth: np.ndarray, rgb: np.ndarray, f: float, cx: float, cy: float,
                 step: int) -> np.ndarray:
    """An organized cloud (rows x cols x 4 float32: x y z rgb) from depth, every ``step`` px."""
    z = depth[::step, ::step].astype(np.float32)
    v, u = np.mgrid[0:depth.shape[0]:step, 0:depth.shape[1]:step].astype(np.float32)
    points = np.empty(z.shape + (4,), np.float32)
    points[..., 0] = (u - cx) * z / f
    points[..., 1] = (v - cy) * z / f
    points[..., 2] = z
    colors = rgb[::step, ::step].astype(np.uint32)
    packed = (colors[..., 0] << 16) | (colors[..., 1] << 8) | colors[..., 2]
    points[..., 3] = packed.view(np.float32)
    return points


class SceneCamera:
    """A MuJoCo copy of the scene, posed from the simulator, rendered off-screen."""

    def __init__(self, width: int, height: int) -> None:
        import mujoco

        from walkman.hal.sim import SCENE_PATH

        self.mujoco = mujoco
        self.model = mujoco.MjModel.from_xml_path(str(SCENE_PATH))
        self.data = mujoco.MjData(self.model)
        mujoco.mj_resetDataKeyframe(self.model, self.data, 0)
        self.renderer = mujoco.Renderer(self.model, height, width)
        self.width, self.height = width, height
        self.fovy = float(self.model.cam(CAMERA).fovy[0])
        self.far = float(self.model.vis.map.zfar * self.model.stat.extent)

    @property
    def nq(self) -> int:
        return int(self.model.nq)

    def render(self, qpos: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
        self.data.qpos[:] = qpos
        self.mujoco.mj_forward(self.model, self.data)
        self.renderer.update_scene(self.data, camera=CAMERA)
        rgb = self.renderer.render().copy()
        self.renderer.enable_depth_rendering()
        self.renderer.update_scene(self.data, camera=CAMERA)
        depth = self.renderer.render().astype(np.float32)
        self.renderer.disable_depth_rendering()
        depth[depth >= 0.99 * self.far] = np.nan
        return rgb, depth

    def close(self) -> None:
        self.renderer.close()


class PerceptionNode:
    def __init__(self, robot: str, rate: float, width: int, height: int, step: int) -> None:
        self.robot = robot
        self.rate = rate
        self.step = step
        self.camera = SceneCamera(width, height)
        self.world: Optional[np.ndarray] = None
        self.world_time = 0.0
        self._lock = threading.Lock()
        self.frames = 0

    def open_yarp(self, keeper) -> None:
        from walkman.hal import protocol
        from walkman.hal.protocol import HalProtocolError
        from yarp_lite.buffered_port import BufferedPort

        def on_world(bottle) -> None:
            try:
                t, qpos = protocol.decode_world(bottle, self.camera.nq)
            except HalProtocolError as exc:
                log.warning("perception: %s (is the HAL running the same scene?)", exc)
                return
            with self._lock:
                self.world, self.world_time = np.asarray(qpos), t

        port = BufferedPort(on_read=on_world)
        port.open("/perception/world:i", wait=math.inf)
        keeper.want(protocol.world_port_name(self.robot), port.name, port, ours_is_source=False,
                    carrier="fast_tcp")
        self.port = port

    def messages(self, stamp) -> Optional[tuple]:
        from sensor_msgs.msg import CameraInfo, Image, PointCloud2, PointField

        with self._lock:
            world = None if self.world is None else self.world.copy()
        if world is None:
            return None
        rgb, depth = self.camera.render(world)
        f, cx, cy = intrinsics(self.camera.width, self.camera.height, self.camera.fovy)
        height, width = rgb.shape[:2]
        image = Image(height=height, width=width, encoding="rgb8", is_bigendian=0,
                      step=width * 3, data=rgb.tobytes())
        depth_image = Image(height=height, width=width, encoding="32FC1", is_bigendian=0,
                            step=width * 4, data=depth.tobytes())
        info = CameraInfo(height=height, width=width, distortion_model="plumb_bob",
                          D=[0.0] * 5, K=[f, 0, cx, 0, f, cy, 0, 0, 1],
                          R=[1, 0, 0, 0, 1, 0, 0, 0, 1], P=[f, 0, cx, 0, 0, f, cy, 0, 0, 0, 1, 0])
        points = cloud_points(depth, rgb, f, cx, cy, self.step)
        fields = [PointField("x", 0, PointField.FLOAT32, 1), PointField("y", 4, PointField.FLOAT32, 1),
                  PointField("z", 8, PointField.FLOAT32, 1),
                  PointField("rgb", 12, PointField.FLOAT32, 1)]
        cloud = PointCloud2(height=points.shape[0], width=points.shape[1], fields=fields,
                            is_bigendian=False, point_step=16, row_step=16 * points.shape[1],
                            is_dense=bool(np.isfinite(points[..., 2]).all()),
                            data=points.tobytes())
        self.frames += 1
        for msg in (image, depth_image, info, cloud):
            msg.header.stamp, msg.header.frame_id, msg.header.seq = stamp, FRAME, self.frames
        return image, depth_image, info, cloud


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="walkman-perception",
                                     description="The simulated head camera as ROS topics.")
    parser.add_argument("--robot", default="walkman")
    parser.add_argument("--rate", type=float, default=2.0, help="frames per second (default 2)")
    parser.add_argument("--width", type=int, default=320)
    parser.add_argument("--height", type=int, default=240)
    parser.add_argument("--cloud-step", type=int, default=4,
                        help="one cloud point every N pixels (default 4)")
    options = parser.parse_args(argv)
    if not 0 < options.rate <= 30 or options.width < 16 or options.height < 16 or \
            options.cloud_step < 1:
        parser.error("need 0 < rate <= 30, width and height >= 16, cloud-step >= 1")
    os.environ.setdefault("MUJOCO_GL", "osmesa")
    from nodekit.logs import configure_logging

    configure_logging("perception", False)
    from nodekit.connections import ConnectionKeeper
    from nodekit.ros_node import RosNode

    node = PerceptionNode(options.robot, options.rate, options.width, options.height,
                          options.cloud_step)
    ros = RosNode("walkman_perception")
    publishers = {}

    def open_topics() -> None:
        import rospy
        from sensor_msgs.msg import CameraInfo, Image, PointCloud2

        publishers.update(
            image=rospy.Publisher("/multisense/left/image_color", Image, queue_size=2),
            depth=rospy.Publisher("/multisense/depth", Image, queue_size=2),
            info=rospy.Publisher("/multisense/left/camera_info", CameraInfo, queue_size=2),
            cloud=rospy.Publisher("/multisense/points", PointCloud2, queue_size=2))

    ros.when_ready(open_topics)
    ros.start()
    keeper = ConnectionKeeper()
    node.open_yarp(keeper)
    keeper.start()
    stop = threading.Event()
    import signal

    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    said = 0.0
    while not stop.wait(1.0 / options.rate):
        if not publishers:
            continue
        import rospy

        frames = node.messages(rospy.Time.now())
        if frames is None:
            if time.monotonic() - said > 10:
                log.info("perception: waiting for /%s/sim/world:o (is walkman-hal running "
                         "the sim?)", options.robot)
                said = time.monotonic()
            continue
        for key, msg in zip(("image", "depth", "info", "cloud"), frames):
            publishers[key].publish(msg)
        if node.frames == 1:
            log.info("perception: first frame published (%dx%d, cloud %dx%d)", options.width,
                     options.height, frames[3].width, frames[3].height)
    keeper.stop()
    node.camera.close()
    ros.stop()
    return 0


if __name__ == "__main__":
    sys.exit(main())
