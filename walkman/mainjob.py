"""The README's main job.

Stage 1 (yarp_lite): start a name server pair -- ``yarp-lite server`` and
``roscore`` -- on free ports in a private configuration, show yarp_lite ports
talking through it and a ROS topic through roscore, then shut everything down.
Later stages grow this into the full two-PC topology with the simulated robot.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from yarp_lite import network
from yarp_lite.freeport import free_port
from yarp_lite.bottle import Bottle
from yarp_lite.nameclient import NameClient
from yarp_lite.port import Port


def say(text: str) -> None:
    print(f"[main-job] {text}", flush=True)


def main() -> int:
    workdir = Path(tempfile.mkdtemp(prefix="walkman-main-"))
    os.environ.update(YARP_CONFIG_HOME=str(workdir / "yarp"), YARP_DATA_HOME=str(workdir / "data"),
                      ROS_HOME=str(workdir / "ros"), ROS_LOG_DIR=str(workdir / "ros" / "log"))
    yarp_port, ros_port = free_port(), free_port()
    os.environ["ROS_MASTER_URI"] = f"http://127.0.0.1:{ros_port}"
    os.environ["ROS_HOSTNAME"] = "127.0.0.1"
    children = []
    try:
        say(f"starting yarp-lite server on 127.0.0.1:{yarp_port}")
        children.append(subprocess.Popen(
            [sys.executable, "-m", "yarp_lite", "server", "--socket", str(yarp_port), "--ip",
             "127.0.0.1", "--write", "--silent"], start_new_session=True,
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        if shutil.which("roscore"):
            say(f"starting roscore on port {ros_port}")
            children.append(subprocess.Popen(["roscore", "-p", str(ros_port)],
                                             stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                             start_new_session=True))
        client = NameClient()
        deadline = time.time() + 20
        while not client.ping():
            if time.time() > deadline:
                say("the name server did not start")
                return 1
            time.sleep(0.1)
        received = []
        reader = Port("/demo/read", reader=received.append)
        writer = Port("/demo/write")
        outcome = network.connect("/demo/write", "/demo/read")
        say(f"connect /demo/write -> /demo/read: {outcome.message.strip()}")
        for index in range(3):
            writer.write(Bottle(["hello", index, 0.5 * index]))
        deadline = time.time() + 5
        while len(received) < 3 and time.time() < deadline:
            time.sleep(0.02)
        for bottle in received:
            say(f"/demo/read received: {bottle}")
        say("name server registry:")
        for line in client.list_lines():
            print("    " + line, flush=True)
        if shutil.which("rostopic"):
            deadline = time.time() + 30
            while subprocess.run(["rostopic", "list"], capture_output=True).returncode != 0:
                if time.time() > deadline:
                    break
                time.sleep(0.3)
            ros_ok = subprocess.run(["rostopic", "pub", "-1", "/demo/chatter", "std_msgs/String",
                                     "data: hello from ROS"], capture_output=True,
                                    timeout=60).returncode == 0
            say(f"ROS: rostopic pub through roscore {'worked' if ros_ok else 'FAILED'}")
        writer.close()
        reader.close()
        ok = len(received) == 3
        say("done: yarp_lite ports talked through the name server" if ok else "FAILED")
        return 0 if ok else 1
    finally:
        for child in children:
            try:
                os.killpg(child.pid, signal.SIGINT)
                child.wait(timeout=10)
            except (ProcessLookupError, subprocess.TimeoutExpired):
                os.killpg(child.pid, signal.SIGKILL)
        shutil.rmtree(workdir, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
