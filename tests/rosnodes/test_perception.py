"""The perception node's geometry and frame clock, without a renderer or ROS."""

from __future__ import annotations

import numpy as np
import pytest

from harness import ManualClock
from walkman.head_camera import (OPTICAL_ROTATION, OPTICAL_TO_CAMERA, FrameClock, cloud_points,
                                 cloud_xyz, intrinsics, optical_to)


def test_intrinsics_of_mujocos_pinhole():
    f, cx, cy = intrinsics(320, 240, 90.0)
    assert f == pytest.approx(120.0)         # half the height over tan(45 deg)
    assert (cx, cy) == (159.5, 119.5)


def test_a_wall_seen_straight_on_becomes_points_at_its_depth():
    depth = np.full((8, 12), 2.0, np.float32)
    depth[0, 0] = np.nan                       # the sky: no point
    rgb = np.zeros((8, 12, 3), np.uint8)
    rgb[..., 0], rgb[..., 1], rgb[..., 2] = 0x12, 0x34, 0x56
    f, cx, cy = intrinsics(12, 8, 60.0)
    points = cloud_points(depth, rgb, f, cx, cy, step=2)
    assert points.shape == (4, 6, 4)
    assert np.isnan(points[0, 0, 2])
    assert np.allclose(points[1:, :, 2], 2.0)
    u, v = 2 * 5, 2 * 3                        # the last sampled pixel
    assert points[3, 5, 0] == pytest.approx((u - cx) * 2.0 / f)
    assert points[3, 5, 1] == pytest.approx((v - cy) * 2.0 / f)
    assert points[1, 1, 3:].view(np.uint32)[0] == 0x123456


def test_the_cloud_s_bytes_read_back_are_its_points_and_bad_sizes_are_named():
    depth = np.linspace(1.0, 3.0, 48, dtype=np.float32).reshape(6, 8)
    depth[2, 2] = np.nan
    f, cx, cy = intrinsics(8, 6, 60.0)
    points = cloud_points(depth, np.zeros((6, 8, 3), np.uint8), f, cx, cy, step=1)
    xyz = cloud_xyz(points.tobytes(), 16, (0, 4, 8))
    assert xyz.shape == (48, 3)
    assert np.array_equal(xyz, points[..., :3].reshape(-1, 3), equal_nan=True)
    for data, step, offsets in ((points.tobytes()[:-1], 16, (0, 4, 8)),
                                (points.tobytes(), 0, (0, 4, 8)),
                                (points.tobytes(), 16, (0, 4, 14))):
        with pytest.raises(ValueError, match="is not points of"):
            cloud_xyz(data, step, offsets)


def test_the_optical_frame_is_the_camera_frame_turned_as_ros_drivers_turn_it():
    x, y, z, w = OPTICAL_ROTATION
    quaternion = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                           [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                           [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
    assert np.allclose(quaternion, OPTICAL_TO_CAMERA)
    # a point 2 m straight ahead of a camera 1 m up, looking along x: (1 right, 0.5 down)
    assert np.allclose(optical_to([[1.0, 0.5, 2.0]], [0.0, 0.0, 1.0], np.eye(3)),
                       [[2.0, -1.0, 0.5]])


def test_frames_come_at_the_rate_asked_whatever_a_frame_costs():
    clock = ManualClock()
    frames = FrameClock(2.0, clock)
    taken = []
    for _ in range(10):
        clock.now += frames.wait()
        taken.append(clock.now)
        clock.now += 0.3                       # rendering and publishing one frame
    gaps = np.diff(taken)
    assert np.allclose(gaps, 0.5)              # not 0.8 (a period after the work)


def test_a_frame_that_fell_behind_is_taken_now_not_caught_up_in_a_burst():
    clock = ManualClock()
    frames = FrameClock(2.0, clock)
    clock.now += frames.wait()
    clock.now += 1.7                           # one frame took 1.7 s (a loaded PC)
    assert frames.wait() == 0.0
    clock.now += 0.1
    assert frames.wait() == pytest.approx(0.4)  # then the rate again, from there


COMPARE = r"""
import json
import mujoco
import numpy as np
from walkman.head_camera import CAMERA, SceneCamera, intrinsics

camera = SceneCamera(320, 240)
model = camera.model
reference = mujoco.Renderer(model, 240, 320)       # the same model: no multisampling
f, cx, cy = intrinsics(320, 240, camera.fovy)
out = []
for turn in (0.0, 0.4):                            # the valve station, then the far floor
    qpos = camera.data.qpos.copy()
    qpos[model.joint("NeckYawj").qposadr[0]] = turn
    rgb, depth = camera.render(qpos)
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_forward(model, data)
    reference.update_scene(data, camera=CAMERA)
    rgb_ref = reference.render()
    # Ground truth: a ray cast through every 6th pixel (the camera looks down -z, y up).
    cam = model.cam(CAMERA).id
    origin, axes = data.cam_xpos[cam].copy(), data.cam_xmat[cam].reshape(3, 3)
    errors, missing, hit = [], 0, np.zeros(1, np.int32)
    for v in range(0, 240, 6):
        for u in range(0, 320, 6):
            ray = np.array([(u - cx) / f, -(v - cy) / f, -1.0])
            length = np.linalg.norm(ray)
            distance = mujoco.mj_ray(model, data, origin, axes @ ray / length, None, 1, -1, hit)
            if 0 <= distance / length < 0.99 * camera.far:
                if np.isnan(depth[v, u]):
                    missing += 1
                else:
                    errors.append(abs(float(depth[v, u]) - distance / length))
    out.append({"rgb_differs": float(np.mean(np.any(rgb != rgb_ref, axis=2))),
                "rays": len(errors), "missing": missing, "depth_error": max(errors),
                "rgb_mean": float(rgb.mean())})
camera.close()
print(json.dumps(out))
"""


def test_one_pass_gives_mujocos_colour_and_the_ray_cast_depth():
    """Colour as mujoco.Renderer draws it, depth as a ray cast finds it (OSMesa, as the node).

    The far floor is in the second view: a multisampled depth buffer had it up to 0.11 m out.
    """
    import json
    import os
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    result = subprocess.run([sys.executable, "-c", COMPARE], capture_output=True, text=True,
                            timeout=120, cwd=root,
                            env={**os.environ, "MUJOCO_GL": "osmesa", "PYTHONPATH": str(root)})
    assert result.returncode == 0, result.stderr[-3000:]
    for view in json.loads(result.stdout.splitlines()[-1]):
        assert view["rays"] > 500 and view["rgb_mean"] > 5, view          # a scene, not a blank
        assert view["rgb_differs"] == 0.0, view
        assert view["missing"] == 0, view
        assert view["depth_error"] < 1e-3, view                            # metres
