#!/usr/bin/env python3
"""Perception at the rate asked: where a frame's time goes, and the rate delivered.

    .venv/bin/python bench/bench_perception.py [--quick] [--rate 2] [--seconds 30]

1. **A frame's stages**, in this process (320x240, a cloud point every 4 pixels,
   OSMesa as the node): the node's one-pass render (``SceneCamera``, no
   multisampling) against ``mujoco.Renderer`` drawing colour and depth in two
   passes after a full ``mj_forward`` (what the node did before), interleaved frame by frame; then
   the cloud, the ROS messages and their serialisation (what ``publish`` costs).
2. **The rate delivered with the whole robot PC running**: the ``drc`` topology
   on loopback (HAL, modules, joint state, both bridges, gateway, rosbag) with
   the perception node asked for ``--rate``; ``rostopic hz`` on the robot's
   roscore counts the clouds and images that arrive, and the node's own log
   says where its time went.
"""

from __future__ import annotations

import argparse
import io
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Dict, List

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
os.environ.setdefault("MUJOCO_GL", "osmesa")

from host import say_machine  # noqa: E402  (bench/ is the script's folder)

WIDTH, HEIGHT, STEP = 320, 240, 4


def say(text: str) -> None:
    print(text, flush=True)


def ms(values: List[float]) -> str:
    ordered = sorted(values)
    return f"{statistics.median(ordered) * 1e3:8.1f} {ordered[int(0.9 * (len(ordered) - 1))] * 1e3:8.1f}"


def two_pass(renderer, model, qpos):
    """What the node did before: mujoco.Renderer, a full mj_forward, colour then depth."""
    import mujoco

    from walkman.head_camera import CAMERA

    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_forward(model, data)
    renderer.update_scene(data, camera=CAMERA)
    rgb = renderer.render().copy()
    renderer.enable_depth_rendering()
    renderer.update_scene(data, camera=CAMERA)
    depth = renderer.render().astype("float32")
    renderer.disable_depth_rendering()
    return rgb, depth


def stages(frames: int) -> Dict[str, List[float]]:
    import mujoco
    import numpy as np

    from nodekit.msgs import generate
    from walkman.head_camera import HeadCamera

    generate()
    node = HeadCamera("walkman", 2.0, WIDTH, HEIGHT, STEP)
    camera = node.camera
    from walkman.hal.sim import SCENE_PATH

    model_before = mujoco.MjModel.from_xml_path(str(SCENE_PATH))  # multisampled, as before
    renderer = mujoco.Renderer(model_before, HEIGHT, WIDTH)
    neck = camera.model.joint("NeckYawj").qposadr[0]
    base = camera.data.qpos.copy()
    before: List[float] = []
    serialise: List[float] = []
    for index in range(frames):
        qpos = base.copy()
        qpos[neck] = 0.5 * np.sin(index / 5)       # the head turning: every frame differs
        started = time.perf_counter()
        two_pass(renderer, model_before, qpos)
        before.append(time.perf_counter() - started)
        node.world = qpos
        import rospy

        messages = node.messages(rospy.Time(index))
        started = time.perf_counter()
        for message in messages:
            message.serialize(io.BytesIO())
        serialise.append(time.perf_counter() - started)
    renderer.close()
    camera.close()
    result = {"render (two passes, before)": before}
    result.update({f"{stage} (now)": values for stage, values in node.stages.samples.items()})
    result["serialise (publish)"] = serialise
    return result


def delivered(rate: float, seconds: float) -> Dict[str, object]:
    from system.topology import Topology

    with tempfile.TemporaryDirectory() as tmp:
        topology = Topology("drc", Path(tmp), perception_rate=rate)
        try:
            topology.start_name_servers()
            topology.start_all()
            topology.wait_ready(180)
            node = topology.process("perception")
            node.wait_for("first frame published", 120)
            time.sleep(3)
            env = topology.robot.env
            rates = {}
            for topic in ("/multisense/points", "/multisense/left/image_color"):
                hz = subprocess.run(["timeout", str(seconds), "rostopic", "hz", topic],
                                    env=env, capture_output=True, text=True)
                found = re.findall(r"average rate: ([\d.]+)", hz.stdout)
                rates[topic] = float(found[-1]) if found else 0.0
            summaries = [line for line in node.lines if "frames in" in line]
            return {"rates": rates, "summary": summaries[-1] if summaries else "(no summary yet)"}
        finally:
            topology.close()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="fewer frames, shorter counts")
    parser.add_argument("--rate", type=float, default=2.0, help="frames per second asked")
    parser.add_argument("--seconds", type=float, default=30.0,
                        help="how long rostopic hz counts each topic")
    options = parser.parse_args()
    say_machine()
    frames = 10 if options.quick else 40
    say(f"\n1. One frame ({WIDTH}x{HEIGHT}, cloud every {STEP} px), {frames} frames, "
        f"in this process                 median      p90 (ms)")
    for stage, values in stages(frames).items():
        say(f"   {stage:<44} {ms(values)}")
    seconds = 15.0 if options.quick else options.seconds
    say(f"\n2. Rate delivered, the drc topology on loopback, perception asked for "
        f"{options.rate:g} Hz (rostopic hz, {seconds:.0f} s per topic)")
    result = delivered(options.rate, seconds)
    for topic, hz in result["rates"].items():
        say(f"   {topic:<44} {hz:8.2f} Hz")
    say(f"   the node: {result['summary'].split('perception: ', 1)[-1]}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
