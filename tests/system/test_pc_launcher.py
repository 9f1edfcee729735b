"""The robot and pilot PC launchers, used as a user would, with a plain shell to pilot."""

import os
import signal
import subprocess
import sys

import pytest

from harness import dump_outputs_if_failed
from system.processes import Proc, descendants, wait_until
from system.topology import REPO, TASK_MODULES
from yarp_lite.freeport import free_port


def processes_mentioning(text: str) -> list:
    found = []
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                with open(f"/proc/{entry}/cmdline", "rb") as cmdline:
                    if text.encode() in cmdline.read():
                        found.append(int(entry))
            except OSError:
                pass
    return found


def test_launchers_bring_up_both_pcs_and_a_plain_shell_pilots_the_robot(tmp_path, request):
    bridge, udp = free_port(), {"robot": free_port(), "pilot": free_port()}
    launchers = {}
    try:
        for side, other in (("robot", "pilot"), ("pilot", "robot")):
            launchers[side] = Proc(
                [str(REPO / "launch_scripts" / f"{side}_pc.sh"), "--peer", "127.0.0.1",
                 # a run, as every name server gets: it hands out the numbers after its own
                 "--yarp-port", str(free_port(span=400)), "--ros-port", str(free_port()),
                 "--bridge-port", str(bridge), "--udp-port", str(udp[side]),
                 "--peer-udp-port", str(udp[other]), "--dir", str(tmp_path / side),
                 "--key", str(tmp_path / "bridge.key"), "--shuffle"], dict(os.environ),
                f"{side} PC")
        for proc in launchers.values():
            proc.wait_for(r"all up", 240)
        # The first launcher made the shared key, private, and said to copy it.
        assert oct((tmp_path / "bridge.key").stat().st_mode & 0o777) == "0o600"
        assert "created a new bridge key" in launchers["robot"].output() + \
            launchers["pilot"].output()
        shell = subprocess.run(
            ["bash", "-c", f"source {tmp_path / 'pilot' / 'pilot.env'} && "
             "rostopic pub -1 /gaze_control/switch walkman_msgs/Switch 'command: start'"],
            capture_output=True, text=True, timeout=60, env={"PATH": os.environ["PATH"],
                                                              "HOME": str(tmp_path)})
        assert shell.returncode == 0, shell.stderr
        robot_log = tmp_path / "robot" / "logs" / "gaze_control.log"
        wait_until(lambda: "gaze_control: start -> running" in robot_log.read_text(), 30,
                   message="gaze_control started on the robot PC")
        # every task of the paper has its module waiting for the pilot on the robot PC
        for task in TASK_MODULES:
            assert "ready for the pilot" in (tmp_path / "robot" / "logs" /
                                             f"{task}.log").read_text(), task
    finally:
        dump_outputs_if_failed(request, launchers.values())
        family = {side: [proc.popen.pid, *descendants(proc.popen.pid)]
                  for side, proc in launchers.items()}
        for proc in launchers.values():
            if proc.popen.poll() is None:
                os.kill(proc.popen.pid, signal.SIGINT)  # what Ctrl-C does
        codes = {side: proc.wait(60) for side, proc in launchers.items()}
    assert codes == {"robot": 0, "pilot": 0}
    assert "stopping (SIGINT)" in launchers["pilot"].output()
    assert list((tmp_path / "pilot").glob("pilot-*.bag")), "the rosbag was not closed"
    leftovers = [pid for pids in family.values() for pid in pids
                 if os.path.exists(f"/proc/{pid}") and
                 open(f"/proc/{pid}/stat").read().split(")")[1].split()[0] != "Z"]
    assert leftovers == [] and processes_mentioning(str(tmp_path)) == []


@pytest.mark.parametrize("argv, says", [
    (["pilot", "--peer", "10.0.0.2", "--sim-time"], "--sim-time is the robot PC's"),
    (["lab", "--sim-time"], "--sim-time is the robot PC's"),
    (["robot", "--sim-time"], "the robot PC needs --peer"),
])
def test_walkman_pc_refuses_simulated_time_off_the_robot_pc_by_name(argv, says):
    """The pilot's programs, countdowns and link stay on the wall clock: --sim-time is refused
    there, before anything starts (exit 2, as argparse)."""
    ran = subprocess.run([sys.executable, "-m", "system.pc", *argv], cwd=REPO,
                         capture_output=True, text=True, timeout=60)
    assert ran.returncode == 2 and says in ran.stderr, ran.stderr
