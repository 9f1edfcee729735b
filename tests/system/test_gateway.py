"""The pilot gateway, driven with the real ROS command-line tools against a real module."""

import re
import sys

import pytest

from system.processes import ROSCORE_READY, wait_until
from system.topology import REPO
from walkman.modules.witness import read_log

PYTHON = sys.executable
CONFIG = """<bridge>
  <modules><module name="counter" id="1" statuses="idle counting"/></modules>
</bridge>
"""


def start_counter(pc):
    return pc.start("counter", [PYTHON, "-m", "walkman.gym.supervisor", "witness",
                                "--name", "/counter"])


def rosservice(pc, *args: str) -> str:
    return pc.run(["rosservice", "call", *args], timeout=60).output()


def executed(log) -> list:
    """What the witness ran: ``name seq`` each."""
    return [f"{e.name} {e.seq}" for e in read_log(log)]


@pytest.fixture
def config(tmp_path):
    path = tmp_path / "bridge.xml"
    path.write_text(CONFIG)
    return path


def test_unknown_modules_and_bad_options_are_refused_by_name(make_pc, config):
    pc = make_pc()
    tool = pc.run([PYTHON, "-m", "rosnodes.gateway", "--config", str(config),
                   "--modules", "counter,walking"])
    assert tool.popen.returncode == 2
    assert f"unknown module(s) walking; {config} lists counter" in tool.output()
    tool = pc.run([PYTHON, "-m", "rosnodes.gateway", "--config", str(config), "--countdown", "0"])
    assert tool.popen.returncode == 2 and "--countdown must be positive" in tool.output()
    broken = config.with_name("broken.xml")
    broken.write_text(CONFIG.replace('id="1"', 'id="300"'))
    tool = pc.run([PYTHON, "-m", "rosnodes.gateway", "--config", str(broken)])
    assert tool.popen.returncode == 2 and "broken.xml" in tool.output()


def test_a_gateway_started_before_roscore_waits_serves_and_survives_a_roscore_restart(
        make_pc, config, counter):
    pc = make_pc()
    gateway = pc.start("gateway", [PYTHON, "-m", "rosnodes.gateway", "--config", str(config)])
    gateway.wait_for(r"waiting for the ROS master", 30)
    pc.start_name_servers()
    start_counter(pc).wait_for("ready for the pilot", 60)
    gateway.wait_for(r"ROS topics and services up", 60)
    gateway.wait_for(r"connected .*/counter/command:o -> /counter/command:i", 30)

    # A plain shell: the env file, then the ROS tools.
    shell = pc.run(["bash", "-c", f"source {REPO}/launch_scripts/walkman_env.sh && "
                    f"source {pc.write_env_file()} && rosmsg show walkman_msgs/Command && "
                    "rostopic pub -1 /counter/switch walkman_msgs/Switch 'command: start'"],
                   timeout=60)
    assert "bool dangerous" in shell.output()
    wait_until(lambda: "state: \"idle\"" in rosservice(pc, "/counter/get_status"), 30,
               message="the counter idle after start")
    reply = rosservice(pc, "/counter/send_command", "{command: count}")
    seq = int(re.search(r"seq: (\d+)", reply).group(1))
    wait_until(lambda: executed(counter) == [f"count {seq}"], 20,
               message=f"count {seq} executed once")

    # Malformed pilot messages: refused with the reason, nothing reaches the module.
    assert "'dance' is not a switch command" in rosservice(
        pc, "/counter/switch_and_wait", "{command: dance}")
    assert "must be one word" in rosservice(pc, "/counter/send_command",
                                            "{command: 'two words'}")
    assert "is not a command" in rosservice(pc, "/counter/send_command", "{text: '(('}")
    warnings = pc.start("warnings", ["rostopic", "echo", "/counter/warning/text"])

    def refused_on_the_warning_topic() -> bool:  # (again until `rostopic echo` has subscribed)
        pc.run(["rostopic", "pub", "-1", "/counter/switch", "walkman_msgs/Switch",
                "command: fly"], timeout=60)
        return "gateway: 'fly' is not a switch command" in warnings.output()

    wait_until(refused_on_the_warning_topic, 60, message="the refusal on /counter/warning")
    assert executed(counter) == [f"count {seq}"]

    # roscore dies and comes back: the gateway registers again, the tools work again.
    pc.kill("roscore")
    pc.start_roscore().wait_for(ROSCORE_READY, 60)
    gateway.wait_for(r"the ROS master restarted", 60)
    wait_until(lambda: "ok: True" in rosservice(pc, "/counter/send_command",
                                                     "{command: again}"), 60,
               message="the gateway's services back after the roscore restart")
    wait_until(lambda: len(executed(counter)) == 2 and "again" in executed(counter)[1], 20,
               message="the second command executed")


def test_roslaunch_starts_the_pilot_nodes(make_pc, config, tmp_path):
    pc = make_pc()
    pc.start_name_servers()
    launch = pc.start("roslaunch", ["roslaunch", "walkman_launch", "pilot.launch",
                                    f"config:={config}", f"bag:={tmp_path / 'session.bag'}"])
    launch.wait_for(r"ROS topics and services up", 90)
    wait_until(lambda: "/counter/get_status" in pc.run(["rosservice", "list"]).output(), 30,
               message="the gateway's services")
    nodes = pc.run(["rosnode", "list"]).output()
    assert "/pilot_gateway" in nodes and "/session_record" in nodes, nodes
    launch.interrupt()
    assert (tmp_path / "session.bag").exists()


def test_a_second_gateway_on_the_same_roscore_refuses_instead_of_doubling_commands(
        make_pc, config, counter):
    pc = make_pc()
    pc.start_name_servers()
    first = pc.start("gateway", [PYTHON, "-m", "rosnodes.gateway", "--config", str(config)])
    first.wait_for(r"ROS topics and services up", 60)
    second = pc.run([PYTHON, "-m", "rosnodes.gateway", "--config", str(config)], timeout=60)
    assert second.popen.returncode == 2
    assert "another pilot gateway already serves these modules on this roscore" in \
        second.output()
    start_counter(pc).wait_for("ready for the pilot", 60)
    first.wait_for(r"connected .*/counter/command:o -> /counter/command:i", 30)
    pc.run(["rostopic", "pub", "-1", "/counter/switch", "walkman_msgs/Switch",
            "command: start"], timeout=60)
    wait_until(lambda: "state: \"idle\"" in rosservice(pc, "/counter/get_status"), 30,
               message="the counter idle after start")
    reply = rosservice(pc, "/counter/send_command", "{command: once}")
    seq = int(re.search(r"seq: (\d+)", reply).group(1))
    wait_until(lambda: executed(counter) == [f"once {seq}"], 20,
               message="the command executed exactly once")


def test_a_gateway_whose_ros_side_cannot_open_says_why_and_ends(make_pc, config):
    """Its ROS thread failing (here the generated messages unimportable, as on a checkout
    whose messages were not yet generated) used to leave a gateway running that never
    served: it ends with the reason instead, so its launcher sees it."""
    pc = make_pc()
    pc.start_name_servers()
    broken = ("import sys; sys.modules['walkman_msgs.srv'] = None; "
              "from rosnodes.gateway import main; sys.exit(main(sys.argv[1:]))")
    tool = pc.run([PYTHON, "-c", broken, "--config", str(config)], timeout=60)
    assert tool.popen.returncode == 2, tool.output()
    assert re.search(r"walkman-pilot-gateway: its ROS side did not open: Gateway\._open_ros "
                     r"raised ModuleNotFoundError: .*walkman_msgs\.srv", tool.output()), \
        tool.output()


def test_a_switch_sent_before_the_module_is_connected_waits_for_it(make_pc, config, counter):
    """Just after start-up the pilot's first command may beat the connection keeper:
    it is delivered once the connection is made, not dropped."""
    pc = make_pc()
    pc.start_name_servers()
    gateway = pc.start("gateway", [PYTHON, "-m", "rosnodes.gateway", "--config", str(config)])
    gateway.wait_for(r"ROS topics and services up", 60)
    pc.start("pub", ["rostopic", "pub", "-1", "/counter/switch", "walkman_msgs/Switch",
                     "command: start"])
    gateway.wait_for(r"no connection to /counter yet; the message waits for it", 60)
    module = start_counter(pc)
    module.wait_for("start -> running", 30)
    assert "is not reachable" not in gateway.output()


def test_the_scene_crosses_to_another_pilot_station_even_one_that_came_later(
        make_pc, config, tmp_path):
    """Two pilot PCs (a roscore and a gateway each, one pilot YARP name server): an object
    placed on the first (``rostopic pub`` standing in for a PI) is in the second's latched
    ``/pilot/scene`` -- the second gateway started after the edit and caught up -- and a
    drag on the second comes back to the first; a malformed edit is refused by name."""
    import shutil

    first, second = make_pc("pilot1"), make_pc("pilot2")
    first.start_name_servers()
    gateway = [PYTHON, "-m", "rosnodes.gateway", "--config", str(config)]
    first.start("gateway", gateway).wait_for(r"ROS topics and services up", 60)
    first.run(["rostopic", "pub", "-1", "/pilot/scene_edit", "walkman_msgs/SceneObject",
               "{name: drc_valve, kind: valve, pose: [0.66, 0.25, 0.08, 0, 0, 0], "
               "sender: pi_main}"], timeout=60)
    first.processes["gateway"].wait_for(r"gateway: scene: drc_valve at 0.660 0.250 0.080 "
                                        r".*\(from pi_main\)", 30)

    (second.root / "yarp").mkdir(parents=True)
    for conf in (first.root / "yarp").glob("*.conf"):
        shutil.copy(conf, second.root / "yarp" / conf.name)
    second.start_roscore().wait_for(ROSCORE_READY, 60)
    later = second.start("gateway", gateway)
    later.wait_for(r"gateway: scene: drc_valve from station 1 \(pi_main\)", 60)
    echoed = second.run(["rostopic", "echo", "-n", "1", "/pilot/scene"], timeout=60).output()
    assert "name: \"drc_valve\"" in echoed and "0.66" in echoed and "station: 1" in echoed, \
        echoed

    second.run(["rostopic", "pub", "-1", "/pilot/scene_edit", "walkman_msgs/SceneObject",
                "{name: drc_valve, kind: valve, pose: [0.70, 0.25, 0.08, 0, 0, 0], "
                "sender: pi_perception}"], timeout=60)
    first.processes["gateway"].wait_for(r"gateway: scene: drc_valve from station 2 "
                                        r"\(pi_perception\)", 30)
    echoed = first.run(["rostopic", "echo", "-n", "1", "/pilot/scene"], timeout=60).output()
    assert "0.7" in echoed and "pi_perception" in echoed, echoed

    first.run(["rostopic", "pub", "-1", "/pilot/scene_edit", "walkman_msgs/SceneObject",
               "{name: drc_valve, kind: teapot, pose: [0.7, 0.25, 0.08, 0, 0, 0]}"],
              timeout=60)
    first.processes["gateway"].wait_for(r"a scene edit refused \(\?\): kind: one of valve", 30)
