"""The simulated robot's head camera: a MuJoCo copy of the scene, posed by the HAL, rendered.

Theory of operation
-------------------
The HAL's simulator publishes the whole scene's positions on
``/<robot>/sim/world:o`` (30 Hz).  :class:`HeadCamera` keeps a copy of the same
MuJoCo scene, poses it from the latest reading, and renders the ``multisense``
camera on the CPU (OSMesa, no display needed) into the ROS messages the real
Multisense head gives (colour, depth, camera info, organized cloud), all in the
``multisense_optical_frame`` (z forward, x right, y down).  A region of
interest crops what is sent (the pilot asks only what it needs over a slow
link), and the resolution can change between frames.

Two programs drive it: ``walkman-perception`` (:mod:`rosnodes.perception`, a
plain ROS node) and the ``perception`` GYM module
(:mod:`walkman.modules.perception`, which the pilot starts, pauses and
retargets).  The geometry (:func:`intrinsics`, :func:`cloud_points`) is pure
numpy, tested without a renderer.  Frames are due at the rate asked whatever
one costs (:class:`FrameClock`).
"""

from __future__ import annotations

import logging
import math
import statistics
import threading
import time
from dataclasses import dataclass
from typing import Dict, List, Optional, Tuple

import numpy as np

log = logging.getLogger("walkman.perception")

FRAME = "multisense_optical_frame"
CAMERA = "multisense"
#: multisense_frame -> multisense_optical_frame (x right, y down, z ahead), xyzw, as in
#: every ROS camera driver's static transform; and as a matrix (optical axes in the
#: camera frame's: x right = -y, y down = -z, z ahead = x)
OPTICAL_ROTATION = (-0.5, 0.5, -0.5, 0.5)
OPTICAL_TO_CAMERA = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
#: How often the node logs its frame rate and where a frame's time goes.
SUMMARY_PERIOD_S = 10.0


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


def cloud_xyz(data: bytes, point_step: int, offsets: Tuple[int, int, int]) -> np.ndarray:
    """The x y z (float32, little-endian, at ``offsets`` in each point) of a cloud's
    points as an N x 3 array -- :func:`cloud_points` read back, as the PI reads it."""
    if point_step <= 0 or len(data) % point_step or max(offsets) + 4 > point_step:
        raise ValueError(f"a cloud of {len(data)} bytes is not points of {point_step} bytes "
                         f"with x y z at {offsets}")
    raw = np.frombuffer(data, np.uint8).reshape(-1, point_step)
    return np.stack([raw[:, k:k + 4].copy().view("<f4")[:, 0] for k in offsets], axis=1)


def optical_to(xyz: np.ndarray, position: np.ndarray, rotation: np.ndarray) -> np.ndarray:
    """Points of the optical frame in the frame where ``multisense_frame`` sits at
    ``position``, turned by ``rotation`` (the pelvis frame, from the robot's kinematics)."""
    return np.asarray(position, float) + np.asarray(xyz, float) @ (
        np.asarray(rotation, float) @ OPTICAL_TO_CAMERA).T


class StageTimes:
    """Per-frame seconds of each stage, summarised for the log (and bench_perception)."""

    def __init__(self) -> None:
        self.samples: Dict[str, List[float]] = {}
        self.since = time.monotonic()

    def add(self, stage: str, seconds: float) -> None:
        self.samples.setdefault(stage, []).append(seconds)

    def summary(self) -> str:
        """``N frames in S s (R Hz); render 120.3 ms, ...`` (medians), then start afresh."""
        elapsed = time.monotonic() - self.since
        count = len(self.samples.get("render", []))
        parts = [f"{stage} {statistics.median(values) * 1e3:.1f} ms"
                 for stage, values in self.samples.items() if values]
        self.samples, self.since = {}, time.monotonic()
        return (f"{count} frames in {elapsed:.1f} s ({count / elapsed:.2f} Hz); "
                f"median per frame: {', '.join(parts) or 'none'}")


class FrameClock:
    """Frames at the rate asked, whatever a frame costs: each is due a period after the
    last was due (waiting a whole period after the work made 2 Hz into 1/(0.5 s + render)),
    and a frame that fell behind is taken now, not caught up in a burst."""

    def __init__(self, rate: float, clock=time.monotonic) -> None:
        self.period = 1.0 / rate
        self.clock = clock
        self.due = clock()

    def wait(self) -> float:
        """Seconds to wait until the next frame is due (0: now); that frame is then taken."""
        now = self.clock()
        self.due = max(self.due + self.period, now)
        return self.due - now


class SceneCamera:
    """A MuJoCo copy of the scene, posed from the simulator, rendered off-screen.

    One pass gives both images: the scene is drawn once and its colour and depth
    buffers read together (``mujoco.Renderer`` draws it twice, once per buffer,
    with a full ``mj_forward`` each time), and the pose needs only kinematics.
    Depth comes back as OpenGL's reversed-Z buffer and is turned into metres
    the way ``mujoco.Renderer`` does; the buffers are reused frame to frame.

    The off-screen buffer has no multisampling: resolving a multisampled depth
    buffer put the far floor up to 0.11 m out (at 9-11 m, against a ray cast),
    which is why ``mujoco.Renderer`` draws depth in a separate segmented pass.
    Without it depth matches a ray cast to micrometres and colour loses only
    its anti-aliased edges (a camera's own pixels are not anti-aliased either).
    """

    def __init__(self, width: int, height: int) -> None:
        import mujoco
        from mujoco import gl_context

        from walkman.hal.sim import SCENE_PATH

        self.mujoco = mujoco
        self.model = mujoco.MjModel.from_xml_path(str(SCENE_PATH))
        self.model.vis.quality.offsamples = 0          # exact depth (see above)
        self.data = mujoco.MjData(self.model)
        mujoco.mj_resetDataKeyframe(self.model, self.data, 0)
        self.width, self.height = width, height
        self.gl = gl_context.GLContext(width, height)
        self.gl.make_current()
        self.scene = mujoco.MjvScene(self.model, maxgeom=10000)
        self.option = mujoco.MjvOption()
        self.view = mujoco.MjvCamera()
        self.view.type = mujoco.mjtCamera.mjCAMERA_FIXED
        self.view.fixedcamid = self.model.cam(CAMERA).id
        self.context = mujoco.MjrContext(self.model, mujoco.mjtFontScale.mjFONTSCALE_150)
        mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN, self.context)
        self.context.readDepthMap = mujoco.mjtDepthMap.mjDEPTH_ZEROFAR
        self.rect = mujoco.MjrRect(0, 0, width, height)
        self._rgb = np.empty((height, width, 3), np.uint8)
        self._depth = np.empty((height, width), np.float32)
        self.fovy = float(self.model.cam(CAMERA).fovy[0])
        extent = self.model.stat.extent
        near = np.float32(self.model.vis.map.znear * extent)
        far = np.float32(self.model.vis.map.zfar * extent)
        self.far = float(far)
        # OpenGL's perspective matrix in reversed-Z, as mujoco.Renderer undoes it.
        c = -(far + near) / (far - near)
        d = -(np.float32(2) * far * near) / (far - near)
        self._c, self._d = np.float32(-0.5) * c - np.float32(0.5), np.float32(-0.5) * d

    @property
    def nq(self) -> int:
        return int(self.model.nq)

    def render(self, qpos: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
        """Colour (rgb8) and depth (metres, NaN = nothing within the far plane)."""
        mujoco = self.mujoco
        self.data.qpos[:] = qpos
        mujoco.mj_kinematics(self.model, self.data)
        mujoco.mj_camlight(self.model, self.data)
        self.gl.make_current()
        mujoco.mjv_updateScene(self.model, self.data, self.option, None, self.view,
                               mujoco.mjtCatBit.mjCAT_ALL, self.scene)
        mujoco.mjr_render(self.rect, self.scene, self.context)
        mujoco.mjr_readPixels(self._rgb, self._depth, self.rect, self.context)
        rgb = np.flipud(self._rgb).copy()  # OpenGL's rows start at the bottom
        depth = (self._d / (np.flipud(self._depth).astype(np.float64) + self._c)
                 ).astype(np.float32)
        depth[depth >= 0.99 * self.far] = np.nan
        return rgb, depth

    def close(self) -> None:
        self.gl.make_current()
        self.context.free()
        self.gl.free()


@dataclass(frozen=True)
class Region:
    """A region of interest, in pixels of the full image."""

    x: int
    y: int
    width: int
    height: int

    def check(self, width: int, height: int) -> None:
        """ValueError naming what is wrong, for an image of ``width`` x ``height``."""
        if self.width < 8 or self.height < 8:
            raise ValueError(f"a region is at least 8x8 pixels, got {self.width}x{self.height}")
        if self.x < 0 or self.y < 0 or self.x + self.width > width or \
                self.y + self.height > height:
            raise ValueError(f"region {self.width}x{self.height} at ({self.x}, {self.y}) is not "
                             f"inside the {width}x{height} image")


#: Resolutions a pilot may ask (what the MuJoCo off-screen buffer of the scene allows).
MIN_SIZE, MAX_SIZE = (16, 16), (1280, 960)


def topics() -> Dict[str, object]:
    """The Multisense head's ROS publishers, on this process's node."""
    import rospy
    from sensor_msgs.msg import CameraInfo, Image, PointCloud2

    return dict(image=rospy.Publisher("/multisense/left/image_color", Image, queue_size=2),
                depth=rospy.Publisher("/multisense/depth", Image, queue_size=2),
                info=rospy.Publisher("/multisense/left/camera_info", CameraInfo, queue_size=2),
                cloud=rospy.Publisher("/multisense/points", PointCloud2, queue_size=2))


class HeadCamera:
    def __init__(self, robot: str, rate: float, width: int, height: int, step: int) -> None:
        self.robot = robot
        self.rate = rate
        self.step = step
        self.camera = SceneCamera(width, height)
        self.region: Optional[Region] = None
        self.port = None                          # the HAL's world, once open_yarp ran
        self.world: Optional[np.ndarray] = None
        self.world_time = 0.0
        self._lock = threading.Lock()
        self.frames = 0
        self.stages = StageTimes()

    def resize(self, width: int, height: int) -> None:
        """Render at another resolution from the next frame (the region is dropped)."""
        if not (MIN_SIZE[0] <= width <= MAX_SIZE[0] and MIN_SIZE[1] <= height <= MAX_SIZE[1]):
            raise ValueError(f"a resolution is {MIN_SIZE[0]}..{MAX_SIZE[0]} x "
                             f"{MIN_SIZE[1]}..{MAX_SIZE[1]} pixels, got {width}x{height}")
        self.camera.close()
        self.camera = SceneCamera(width, height)
        self.region = None

    def set_region(self, region: Optional[Region]) -> None:
        if region is not None:
            region.check(self.camera.width, self.camera.height)
        self.region = region

    def publish(self, publishers: Dict[str, object], stamp) -> bool:
        """Render one frame and publish it; False while the HAL's world has not come."""
        frames = self.messages(stamp)
        if frames is None:
            return False
        published = time.perf_counter()
        for key, msg in zip(("image", "depth", "info", "cloud"), frames):
            publishers[key].publish(msg)
        self.stages.add("publish", time.perf_counter() - published)
        return True

    def progress(self) -> Optional[str]:
        """What the log says after a frame went out: the first one, then every
        :data:`SUMMARY_PERIOD_S` the rate delivered and each stage's median time (the rate
        counted from the first frame, not from the wait for the HAL)."""
        if self.frames == 1:
            self.stages.summary()
            return f"first frame published ({self.camera.width}x{self.camera.height})"
        if time.monotonic() - self.stages.since >= SUMMARY_PERIOD_S:
            return self.stages.summary()
        return None

    def open_yarp(self, keeper, port_name: str = "/perception/world:i") -> None:
        """Follow the HAL's world (the scene's positions) on ``port_name``."""
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
        port.open(port_name, wait=math.inf)
        keeper.want(protocol.world_port_name(self.robot), port.name, port, ours_is_source=False,
                    carrier="fast_tcp")
        self.port = port

    def close_port(self) -> None:
        if self.port is not None:
            self.port.close()

    def messages(self, stamp) -> Optional[tuple]:
        from sensor_msgs.msg import CameraInfo, Image, PointCloud2, PointField

        with self._lock:
            world = None if self.world is None else self.world.copy()
        if world is None:
            return None
        started = time.perf_counter()
        rgb, depth = self.camera.render(world)
        rendered = time.perf_counter()
        self.stages.add("render", rendered - started)
        f, cx, cy = intrinsics(self.camera.width, self.camera.height, self.camera.fovy)
        region = self.region
        if region is not None:   # what is sent is the region; the cloud keeps its geometry
            rgb = rgb[region.y:region.y + region.height, region.x:region.x + region.width]
            depth = depth[region.y:region.y + region.height, region.x:region.x + region.width]
        x0, y0 = (region.x, region.y) if region is not None else (0, 0)
        height, width = rgb.shape[:2]
        image = Image(height=height, width=width, encoding="rgb8", is_bigendian=0,
                      step=width * 3, data=rgb.tobytes())
        depth_image = Image(height=height, width=width, encoding="32FC1", is_bigendian=0,
                            step=width * 4, data=depth.tobytes())
        info = CameraInfo(height=self.camera.height, width=self.camera.width,
                          distortion_model="plumb_bob",
                          D=[0.0] * 5, K=[f, 0, cx, 0, f, cy, 0, 0, 1],
                          R=[1, 0, 0, 0, 1, 0, 0, 0, 1], P=[f, 0, cx, 0, 0, f, cy, 0, 0, 0, 1, 0])
        if region is not None:   # ROS's way to say the image is a window of the sensor's
            info.roi.x_offset, info.roi.y_offset = region.x, region.y
            info.roi.width, info.roi.height = region.width, region.height
        points = cloud_points(depth, rgb, f, cx - x0, cy - y0, self.step)
        clouded = time.perf_counter()
        self.stages.add("cloud", clouded - rendered)
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
        self.stages.add("messages", time.perf_counter() - clouded)
        return image, depth_image, info, cloud
