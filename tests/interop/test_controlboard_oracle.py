"""The HAL as a real YARP robot, and a real YARP robot under our modules.

The oracle is real YARP 3.5 built with its devices: ``yarpdev --device
controlboardwrapper2 --subdevice fakeMotionControl`` is a YARP robot part.
The same ``yarp rpc`` script goes to it and to the HAL, and the replies are
compared Bottle for Bottle -- every vocab, every type, every list length --
except the values that are physics (encoder readings, limits, timestamps).
Then a C++ ``remote_controlboard`` client moves the simulated robot, and an
unchanged GYM module moves fakeMotionControl parts.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Dict, List, Tuple

import pytest

from harness import Proc, YarpWorld, wait_until
from walkman.gym.interfaces import decode_status
from yarp_lite import reference as reference_build
from yarp_lite.bottle import Bottle, Vocab
from yarp_lite.bottle_text import parse
from yarp_lite.buffered_port import BufferedPort
from yarp_lite.nameclient import NameClient

#: The HAL and a GYM module run real-time threads (tests/robot_slots.py).
pytestmark = [pytest.mark.requires("reference", "reference_devices"), pytest.mark.real_time]

PYTHON = sys.executable
CPP_CLIENT = Path(__file__).parents[1] / "walkman" / "cpp" / "remote_controlboard_client.cpp"
GAZE_STATUSES = ["ready", "moving", "tracking", "unreachable"]

#: What a YARP user types at ``yarp rpc /<robot>/<chain>/rpc:i`` (the issue's examples first).
RPC_SCRIPT = [
    "set icmd cmds (pos pos)",  # the HAL boots in position direct, fakeMotionControl in position
    "get axes", "get encs", "get enc 0", "set pos 0 10", "get name 1", "get prot",
    "[get] [axes]", "[get] [encs]", "get esps", "get icmd cmds", "get icmd cmod 1",
    "get icmd cmog 1 (1)", "get icmd what", "set icmd cmod 1 posd", "get icmd cmod 1", "set icmd cmod 1 pos",
    "set vels (10 10)", "get vels", "get vel 0", "get poss", "get type 0", "set posg 1 (0) (5)",
    "get torq trqs", "get torq axes", "get torq trq 1", "get pid pid pos 0",
    "get dpos", "get vmos",
    # refused alike
    "get foo", "set foo 1", "get enc 9", "set poss (1 2 3)", "get iimp stif 0", "frobnicate",
    "help",
]
#: Replies whose values are physics or configuration, compared by shape only.
PHYSICS = {"get encs", "get enc 0", "[get] [encs]", "get esps", "get name 1", "get torq trqs",
           "get torq trq 1", "get pid pid pos 0", "get poss", "get dpos", "get vels",
           "get vel 0", "get vmos"}
#: What fakeMotionControl does not implement (the real wrapper answers [fail], or an
#: interaction mode of 0) and the HAL does: the HAL's reply, as the wrapper shapes it.
BEYOND_THE_FAKE = {
    "get llim 0": "[is] llim -35.0 35.0 [tsta] 0 0.0 [ok]",
    "get tmps": "[is] tmps (30.0 30.0) [tsta] 0 0.0 [ok]",
    "get don 0": "[is] don 1 [tsta] 0 0.0 [ok]",
    "set stos": "[ok]",
    "get intm mods": "([stif] [stif]) [tsta] 0 0.0 [ok]",
    "get intm mode 0": "[stif] [tsta] 0 0.0 [ok]",
}


def shape(value, exact: bool) -> object:
    """What must match: vocabs and list lengths always, values when ``exact``."""
    if isinstance(value, list):
        return ("list", [shape(v, exact) for v in value])
    if isinstance(value, Vocab):
        return ("vocab", str(value))
    return (type(value).__name__, value if exact else None)


def comparable(request: str, reply: Bottle) -> object:
    """The reply without its clock; physics values (and "values vary") by shape only."""
    items = list(reply)
    if len(items) >= 4 and str(items[-4]) == "tsta":  # [tsta] count time [ok]: a clock
        items = items[:-3] + items[-1:]
    exact = request not in PHYSICS and not request.endswith("(values vary)")
    return [shape(v, exact) for v in items]


def rpc_script(world: YarpWorld, reference_impl, port: str) -> Dict[str, Bottle]:
    result = world.run_tool(reference_impl, "rpc", port, input_text="\n".join(RPC_SCRIPT) + "\n",
                            timeout=60)
    replies = [line.split("Response:", 1)[1].strip() for line in result.stdout.splitlines()
               if line.startswith("Response:")]
    assert len(replies) == len(RPC_SCRIPT), result.stdout + result.stderr
    return {request: parse(reply) for request, reply in zip(RPC_SCRIPT, replies)}


def devices_env(world: YarpWorld) -> Dict[str, str]:
    """The world's environment, with the reference build's device plugins findable."""
    return {**world.env, "YARP_DATA_DIRS": str(reference_build.devices())}


def fake_part(world: YarpWorld, tmp_path: Path, name: str, axes: int,
              names: List[str] = ()) -> Proc:
    """A real YARP robot part: controlboardwrapper2 + fakeMotionControl."""
    ini = tmp_path / f"{name.strip('/').replace('/', '_')}.ini"
    lines = ["device controlboardwrapper2", "subdevice fakeMotionControl", f"name {name}",
             "[GENERAL]", f"Joints {axes}"]
    if names:
        lines.append("AxisName " + " ".join(f'"{n}"' for n in names))
    ini.write_text("\n".join(lines) + "\n")
    prefix = reference_build.prefix()
    part = world.start(["stdbuf", "-oL", "-eL", str(prefix / "bin" / "yarpdev"), "--from",
                        str(ini)], f"yarpdev {name}", env=devices_env(world))
    part.wait_for("device active in background", timeout=30)
    return part


def start_hal(world: YarpWorld, backend: str = "sim") -> Proc:
    hal = world.start([PYTHON, "-m", "walkman.hal.server", "--backend", backend, "--scene",
                       "robot"], f"hal-{backend}")
    hal.wait_for("HAL for walkman", timeout=60)
    return hal


@pytest.fixture
def world(make_world, reference, monkeypatch):
    world = make_world(reference)  # the real yarpserver
    world.apply_to_process(monkeypatch)
    return world


def test_yarp_rpc_gets_the_replies_a_real_control_board_gives(world, reference, tmp_path):
    start_hal(world)
    fake_part(world, tmp_path, "/fake/head", 2)
    ours = rpc_script(world, reference, "/walkman/head/rpc:i")
    theirs = rpc_script(world, reference, "/fake/head/rpc:i")
    differences = [f"{request!r}:\n   HAL  {ours[request].to_text()}\n   YARP "
                   f"{theirs[request].to_text()}" for request in RPC_SCRIPT
                   if comparable(request, ours[request]) != comparable(request, theirs[request])]
    assert ours["get axes"] == Bottle([Vocab("is"), "axes", 2, *ours["get axes"][3:]])
    assert differences == [], "\n".join(differences)
    assert str(ours["get name 1"][2]) == "NeckPitchj"
    for request, expected in BEYOND_THE_FAKE.items():
        reply = rpc_script_one(world, reference, "/walkman/head/rpc:i", request)
        assert comparable(request + " (values vary)", reply) == \
            comparable(request + " (values vary)", parse(expected)), (request, reply.to_text())


def rpc_script_one(world: YarpWorld, reference_impl, port: str, request: str) -> Bottle:
    result = world.run_tool(reference_impl, "rpc", port, input_text=request + "\n", timeout=30)
    line = next(line for line in result.stdout.splitlines() if line.startswith("Response:"))
    return parse(line.split("Response:", 1)[1])


@pytest.mark.parametrize("backend, part, axis, target, carrier", [
    ("sim", "head", 1, 30.0, "tcp"),
    ("sim", "left_arm", 3, -40.0, "udp"),      # remote_controlboard's default carrier
    ("ethercat", "head", 0, 20.0, "tcp"),
])
def test_a_cpp_remote_controlboard_moves_the_simulated_robot(world, tmp_path, backend, part,
                                                             axis, target, carrier):
    client = reference_build.compile_cpp(CPP_CLIENT, "remote_controlboard_client",
                                   ("YARP_os", "YARP_init", "YARP_dev", "YARP_sig"))
    hal = start_hal(world, backend)
    run = world.start(["stdbuf", "-oL", str(client), f"/walkman/{part}", f"/cpp/{part}",
                       carrier, str(axis), str(target)], "remote_controlboard client",
                      env=devices_env(world))
    assert run.wait(timeout=120) == 0, run.output()
    out = run.output()
    from walkman.hal.config import load_config

    joints = load_config(None).chains[part]
    for index, joint in enumerate(joints):
        assert f"name {index} {joint}" in out
    assert f"axes {len(joints)}" in out
    assert "reached position" in out and "motion done 1" in out and "reached direct" in out
    # The HAL saw a real YARP client's commands, and logged no refusal of them.
    assert "refused command" not in hal.output()


class Gaze:
    """gaze_control as a process, with its status read and its ports written by real YARP."""

    def __init__(self, world: YarpWorld, reference_impl) -> None:
        self.world, self.reference = world, reference_impl
        self.module = world.start([PYTHON, "-m", "walkman.gym.supervisor", "gaze_control"],
                                  "module gaze_control")
        self.module.wait_for("ready for the pilot", timeout=60)
        self.status = BufferedPort("/test/gaze/status:i")
        NameClient().subscribe("/gaze_control/status:o", self.status.name)

    def state(self):
        bottle = self.status.read(timeout=2)
        return decode_status(bottle, GAZE_STATUSES)[1] if bottle is not None else None

    def send(self, port: str, line: str) -> None:
        result = self.world.run_tool(self.reference, "write", "/test/writer",
                                     f"/gaze_control/{port}", input_text=line + "\n")
        assert result.returncode == 0, result.stderr

    def start(self) -> None:
        self.send("switch:i", "start")
        wait_until(lambda: self.state() == "ready", 30, message="gaze_control ready")

    def close(self) -> None:
        self.status.close()


def test_an_unchanged_gym_module_moves_a_real_yarp_robot(world, reference, tmp_path):
    head = fake_part(world, tmp_path, "/walkman/head", 2, ["NeckYawj", "NeckPitchj"])
    fake_part(world, tmp_path, "/walkman/torso", 3)      # axes named joint0.. : taken by order
    gaze = Gaze(world, reference)
    try:
        before = rpc_script_one(world, reference, "/walkman/head/rpc:i", "get encs")[2]
        gaze.start()
        gaze.send("command:i", "look_at 1.0 0.4 0.1")

        def head_turned() -> bool:
            encs = rpc_script_one(world, reference, "/walkman/head/rpc:i", "get encs")[2]
            return encs[0] > before[0] + 10 and encs[1] > before[1] + 5
        wait_until(head_turned, 20, message="the fake head turned left and down")
        modes = rpc_script_one(world, reference, "/walkman/head/rpc:i", "get icmd cmds")
        assert [str(m) for m in modes[2]] == ["posd", "posd"]
        assert "taking them as ['WaistLat', 'WaistSag', 'WaistYaw']" in gaze.module.output()
        assert head.popen.poll() is None
    finally:
        gaze.close()


def test_arbitration_holds_when_one_commander_is_a_real_yarp_client(world, tmp_path):
    """A module's whole-body interface streams to the neck; a C++ remote_controlboard
    asking for the same joints is refused (its mode change, hence its moves), and said so."""
    import threading

    from walkman.hal.robot import Robot

    hal = start_hal(world)
    robot = Robot("/holder")
    assert robot.wait_until_ready(20)
    stop = threading.Event()
    reference_q = robot.sense_position()

    def hold_the_neck() -> None:
        while not stop.wait(0.01):
            robot.move(reference_q, joints=["NeckYawj", "NeckPitchj"])
    holder = threading.Thread(target=hold_the_neck, daemon=True)
    holder.start()
    try:
        client = reference_build.compile_cpp(CPP_CLIENT, "remote_controlboard_client",
                                             ("YARP_os", "YARP_init", "YARP_dev", "YARP_sig"))
        run = world.start(["stdbuf", "-oL", str(client), "/walkman/head", "/cpp/intruder",
                           "tcp", "0", "25"], "remote_controlboard intruder",
                          env=devices_env(world))
        assert run.wait(timeout=60) == 1, run.output()
        assert "not reached position" in run.output()
        # Its mode change is refused (the holder holds the joint), so its positionMove finds
        # the joint in position direct and is skipped; both said in the HAL's log.
        wait_until(lambda: "/cpp/intruder may not change the mode of NeckYawj" in hal.output(),
                   10, message="the HAL refused the intruder's mode change and said so")
        assert "position_move from /cpp/intruder skipped for NeckYawj" in hal.output()
        # The holder kept its joints: the neck stayed where it holds it.
        yaw = robot.index["NeckYawj"]
        assert abs(robot.sense_position()[yaw] - reference_q[yaw]) < 0.02
    finally:
        stop.set()
        holder.join(timeout=5)
        robot.close()


def real_device(world: YarpWorld, name: str, *args: str) -> Proc:
    """A real YARP sensor wrapper (analogServer, inertial) with a fake subdevice."""
    part = world.start(["stdbuf", "-oL", "-eL", str(reference_build.prefix() / "bin" / "yarpdev"),
                        *args], f"yarpdev {name}", env=devices_env(world))
    part.wait_for("device active in background", timeout=30)
    return part


def one_message(world: YarpWorld, reference_impl, port: str) -> Tuple[str, Bottle]:
    """(envelope, data) of one message read by the real ``yarp read ... envelope``,
    which prints the envelope on a line of its own, then the data."""
    reader = world.tool(reference_impl, "read", f"/test/read{abs(hash(port)) % 10000}", port,
                        "envelope")
    envelope = reader.wait_for(r"^\d+ [\d.e+-]+ *$", 20).string
    wait_until(lambda: envelope in reader.lines[:-1], 20, message=f"data after {envelope!r}")
    lines = list(reader.lines)
    reader.kill()
    return envelope.strip(), parse(lines[lines.index(envelope) + 1])


def test_the_ft_sensors_and_the_imu_stream_as_yarps_wrappers_do(world, reference, tmp_path):
    start_hal(world)
    real_device(world, "analogServer", "--device", "analogServer", "--subdevice",
                "fakeAnalogSensor", "--name", "/fake/ft/analog:o", "--period", "10",
                "--channels", "6")
    real_device(world, "inertial", "--device", "inertial", "--subdevice", "fakeIMU", "--name",
                "/fake/inertial")
    for ours, theirs, size in (("/walkman/l_leg_ft/analog:o", "/fake/ft/analog:o", 6),
                               ("/walkman/inertial", "/fake/inertial", 12)):
        (our_envelope, our_data), (their_envelope, their_data) = (
            one_message(world, reference, ours), one_message(world, reference, theirs))
        # Both are float64 Vectors (fakeAnalogSensor streams one channel, the HAL six).
        assert all(isinstance(v, float) for v in [*our_data, *their_data])
        assert len(our_data) == size
        # The envelope is a Stamp: an int32 count and a float64 time, like theirs.
        for envelope in (our_envelope, their_envelope):
            count, time_s = envelope.split()
            assert count.isdigit() and float(time_s) > 1e9   # an unsigned count, a wall time
    # Calibration (tare) over the wrapper's rpc port, answered as analogServer answers it.
    for port in ("/walkman/l_leg_ft/analog:o/rpc:i", "/fake/ft/analog:o/rpc:i"):
        assert rpc_script_one(world, reference, port, "iana cal") == Bottle([0]), port
        assert rpc_script_one(world, reference, port, "iana fly") == Bottle([Vocab("fail")])
    # Offsets set over rpc (as YARP's analogsensorclient sends them: one list) shift the stream.
    _, before = one_message(world, reference, "/walkman/l_leg_ft/analog:o")
    assert rpc_script_one(world, reference, "/walkman/l_leg_ft/analog:o/rpc:i",
                          "iana cal (0 0 1000 0 0 0)") == Bottle([0])
    _, after = one_message(world, reference, "/walkman/l_leg_ft/analog:o")
    assert abs(before[2] - after[2] - 1000.0) < 200.0, (before, after)
