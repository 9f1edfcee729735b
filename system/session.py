"""A scripted pilot session through the ROS command-line tools, and what it saw.

Theory of operation
-------------------
The session is what a pilot types (:data:`STEPS`): ``rostopic pub`` to switch
modules, ``rosservice call`` to send commands, a dangerous command counted
down and cancelled, temperatures watched.  Each step waits for its visible
effect (a status, a countdown state) before the next one.

Everything the pilot side observes is written down by the recorder, a small
ROS node run on the pilot PC (``python -m system.session record``): one JSON
line per message with its arrival time -- statuses, warnings, countdowns,
commands the gateway sent, joint states (neck only), images, clouds (with the
fraction of NaN points) and TF.  The robot side's view comes from the
modules' own logs (``gaze_control: command look_at ...``).  :mod:`system.compare`
turns two such records into the report.
"""

from __future__ import annotations

import argparse
import json
import re
import shlex
import sys
import threading
import time
from dataclasses import dataclass, field
from typing import Any, Callable, Dict, List, Optional

from bridge import status as status_codec
from bridge.errors import BridgeProtocolError
from system.processes import WaitTimeout, wait_until
from system.topology import PYTHON
from yarp_lite.bottle_text import parse
from yarp_lite.errors import RemoteProtocolError

MODULES = ("gaze_control", "temperature")
VALVE_IN_PELVIS = (0.66, 0.25, 0.08)  # the valve wheel, seen from the pelvis (models/walkman_drc.xml)


@dataclass
class Step:
    label: str
    argv: List[str]
    done: Callable[[List[dict]], bool]
    timeout: float = 30.0


def _status_is(module: str, state: str) -> Callable[[List[dict]], bool]:
    def check(records: List[dict]) -> bool:
        statuses = [r for r in records if r["topic"] == f"/{module}/status"]
        return bool(statuses) and statuses[-1]["state"] == state
    return check


def _countdown_is(state: str, after: int = 0) -> Callable[[List[dict]], bool]:
    def check(records: List[dict]) -> bool:
        found = [r for r in records if r["topic"] == "/gaze_control/countdown"]
        return len([r for r in found if r["state"] == state]) > after
    return check


def _temperatures_seen(count: int) -> Callable[[List[dict]], bool]:
    def check(records: List[dict]) -> bool:
        return len([r for r in records if r["topic"] == "/temperature/status"
                    and r["state"] in ("monitoring", "hot") and r["values"]]) >= count
    return check


def _pub(module: str, word: str) -> List[str]:
    return ["rostopic", "pub", "-1", f"/{module}/switch", "walkman_msgs/Switch",
            f"command: {word}"]


def _call(module: str, request: str) -> List[str]:
    return ["rosservice", "call", f"/{module}/send_command", request]


def _dangerous(request: str) -> List[str]:
    return ["rostopic", "pub", "-1", "/gaze_control/command", "walkman_msgs/Command", request]


x, y, z = VALVE_IN_PELVIS
STEPS = [
    Step("start gaze_control", _pub("gaze_control", "start"),
         _status_is("gaze_control", "ready"), 60),
    Step("start temperature", _pub("temperature", "start"),
         _status_is("temperature", "monitoring"), 60),
    Step("look at the valve", _call("gaze_control",
                                    f"{{command: look_at, numbers: [{x}, {y}, {z}]}}"),
         _status_is("gaze_control", "tracking")),
    Step("watch temperatures", ["sleep", "1"], _temperatures_seen(6)),
    Step("pause gaze_control", _pub("gaze_control", "pause"), _status_is("gaze_control", "paused")),
    Step("resume gaze_control", _pub("gaze_control", "resume"),
         _status_is("gaze_control", "tracking")),
    # ``rostopic pub -1`` holds its latched message 3 s, so the countdown to cancel is long.
    Step("dangerous: home (then cancel)",
         _dangerous("{command: home, dangerous: true, countdown: 20.0}"),
         _countdown_is("waiting")),
    Step("cancel it (press again)", _dangerous("{command: home, dangerous: true}"),
         _countdown_is("cancelled")),
    Step("dangerous: look at the valve, let it go",
         _dangerous(f"{{command: look_at, numbers: [{x}, {y}, {z}], dangerous: true, "
                    f"countdown: 2.0}}"),
         _countdown_is("sent"), 40),
    Step("stop gaze_control", _pub("gaze_control", "stop"), _status_is("gaze_control", "stopped")),
]


#: What the cancelled dangerous command would look like in a module's log: never there.
CANCELLED_COMMAND = ("gaze_control", "command home")


@dataclass
class SessionRecord:
    topology: str
    records: List[dict] = field(default_factory=list)
    steps: List[dict] = field(default_factory=list)           # label, start, end, ok
    executed: Dict[str, List[str]] = field(default_factory=dict)  # module -> commands run
    bridge_samples: List[dict] = field(default_factory=list)   # robot bridge status over time
    completeness: Dict[str, float] = field(default_factory=dict)  # topic -> share received
    started: float = 0.0
    ended: float = 0.0


def run(topology, progress: Callable[[str], None] = print) -> SessionRecord:
    """Play :data:`STEPS` on a started topology; what the pilot saw, step by step."""
    pilot = topology.pilot
    record = SessionRecord(topology.kind, started=time.time())
    recorder = pilot.start("recorder", [PYTHON, "-m", "system.session", "record"])
    recorder.wait_for(r"^recording", 60)
    samplers = {}
    if topology.kind == "drc":
        for side in ("robot", "pilot"):
            samplers[side] = topology.pcs[side].start(
                f"bridge-sampler-{side}", [PYTHON, "-m", "yarp_lite", "read",
                                           f"/session/bridge/{side}",
                                           f"/bridge/{side}/status:o"])

    def records() -> List[dict]:
        return [json.loads(line) for line in list(recorder.lines) if line.startswith("{")]

    wait_until(lambda: _status_is("gaze_control", "initializing")(records()) or
               _status_is("gaze_control", "ready")(records()), 60,
               message="the gaze_control status on the pilot side")
    for number, step in enumerate(STEPS, 1):
        progress(f"[{number}/{len(STEPS)}] {step.label}: {shlex.join(step.argv)}")
        begin = time.time()
        tool = pilot.run(step.argv, timeout=step.timeout)
        ok = True
        try:
            wait_until(lambda: step.done(records()), step.timeout,
                       message=f"the effect of '{step.label}'")
        except WaitTimeout as exc:
            ok = False
            progress(f"      did not happen: {str(exc).splitlines()[0]}\n      "
                     f"tool said: {tool.output()[-300:]}")
        record.steps.append({"label": step.label, "start": begin, "end": time.time(), "ok": ok,
                             "tool": " ".join(step.argv)})
        progress(f"      {'done' if ok else 'FAILED'} in {time.time() - begin:.1f} s")
    time.sleep(2.0)  # the last statuses and samples
    recorder.interrupt()
    record.records = records()
    record.ended = time.time()
    for module in MODULES:
        pattern = re.compile(rf"{module}: (command .*) \(seq|{module}: (\w+ -> \w+)$")
        matches = [pattern.search(line) for line in topology.process(module).lines]
        record.executed[module] = [m.group(1) or m.group(2) for m in matches if m]
    for side, sampler in samplers.items():
        samples = [s for s in map(_parse_bridge_status, list(sampler.lines)) if s]
        sampler.kill()
        if side == "robot":
            record.bridge_samples = samples
        elif samples:
            record.completeness = samples[-1]["completeness"]
    return record


def _parse_bridge_status(line: str) -> Optional[dict]:
    """One ``yarp read`` line of ``/bridge/robot/status:o``: time and bytes per id."""
    try:
        status = status_codec.from_bottle(parse(line))
        tcp, udp = status["tcp"], status.get("udp", {})
        return {"t": float(status["time"]), "bytes_out": int(tcp["bytes_out"]),
                "tcp_by_id": {int(k): int(v) for k, v in tcp["bytes_by_id"].items()},
                "udp_by_id": {int(k): int(v) for k, v in udp.get("bytes_by_id", {}).items()},
                "completeness": {name: float(flow["mean_completeness"])
                                 for name, flow in udp.get("flows", {}).items()}}
    except (BridgeProtocolError, RemoteProtocolError, KeyError, TypeError, ValueError,
            AttributeError):
        return None  # not a status line (the tool's own messages)


# -- the recorder (runs on the pilot PC) ----------------------------------------------------

#: s the recorder waits for the gateway's command topics before it says it is recording
RECORDER_CONNECT_S = 30.0


def record_main() -> int:
    import numpy as np
    import rospy
    from sensor_msgs.msg import Image, JointState, PointCloud2
    from tf2_msgs.msg import TFMessage

    from nodekit.msgs import ensure_importable

    ensure_importable()
    from walkman_msgs.msg import CommandState, Countdown, SentCommand, Status, Warning

    lock = threading.Lock()

    def emit(topic: str, **fields: Any) -> None:
        line = json.dumps({"t": time.time(), "topic": topic, **fields}) + "\n"
        with lock:  # rospy calls back from one thread per topic
            sys.stdout.write(line)
            sys.stdout.flush()

    rospy.init_node("session_recorder", anonymous=True, disable_signals=True)
    for module in MODULES:
        rospy.Subscriber(f"/{module}/status", Status, lambda m, mod=module: emit(
            f"/{mod}/status", seq=m.seq, state=m.state, values=list(m.values)))
        rospy.Subscriber(f"/{module}/warning", Warning, lambda m, mod=module: emit(
            f"/{mod}/warning", seq=m.seq, text=m.text))
    rospy.Subscriber("/gaze_control/countdown", Countdown, lambda m: emit(
        "/gaze_control/countdown", command=m.command, state=m.state, remaining=m.remaining))
    commands = [rospy.Subscriber("/pilot/sent_commands", SentCommand, lambda m: emit(
        "/pilot/sent_commands", module=m.module, port=m.port, text=m.text, seq=m.seq,
        stamp=m.header.stamp.to_sec())),
        rospy.Subscriber("/pilot/command_states", CommandState, lambda m: emit(
            "/pilot/command_states", module=m.module, port=m.port, seq=m.seq, state=m.state,
            stamp=m.header.stamp.to_sec()), queue_size=50)]

    def on_joints(msg: Any) -> None:
        names = list(msg.name)
        neck = [msg.position[names.index(n)] for n in ("NeckYawj", "NeckPitchj") if n in names]
        emit("/joint_states", neck=neck)

    def on_cloud(msg: Any) -> None:
        points = np.frombuffer(msg.data, np.float32).reshape(-1, msg.point_step // 4)
        emit("/multisense/points", nan=float(np.isnan(points[:, 0]).mean()),
             stamp=msg.header.stamp.to_sec())

    rospy.Subscriber("/joint_states", JointState, on_joints, queue_size=50)
    rospy.Subscriber("/multisense/points", PointCloud2, on_cloud, queue_size=5)
    rospy.Subscriber("/multisense/left/image_color", Image, lambda m: emit(
        "/multisense/left/image_color", stamp=m.header.stamp.to_sec()), queue_size=5)
    rospy.Subscriber("/tf", TFMessage, lambda m: emit("/tf", frames=len(m.transforms)),
                     queue_size=50)
    # The session's first command must not go out before the recorder hears the gateway:
    # a ROS subscription connects after it is made (fc140's lab run missed its first
    # command, and the report paired the rest with the drc run's one row off).
    deadline = time.monotonic() + RECORDER_CONNECT_S
    while any(sub.get_num_connections() == 0 for sub in commands):
        if time.monotonic() > deadline:
            print(f"the gateway's command topics have no publisher after "
                  f"{RECORDER_CONNECT_S:g} s: is the gateway running?", file=sys.stderr)
            return 1
        time.sleep(0.05)
    print("recording", flush=True)
    try:
        while not rospy.is_shutdown():
            time.sleep(0.2)
    except KeyboardInterrupt:
        pass  # Ctrl-C is how the user ends the recording
    return 0


def main(argv: Optional[List[str]] = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m system.session")
    parser.add_argument("verb", choices=["record"])
    parser.parse_args(argv)
    return record_main()


if __name__ == "__main__":
    sys.exit(main())
