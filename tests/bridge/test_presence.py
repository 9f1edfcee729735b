"""Which endpoints stand in for a program on the other side, and the remembered word."""

from __future__ import annotations

import logging

from bridge import config as bridge_config
from bridge.flows import FlowKey
from bridge.gym.presence import PresenceMemory, module_end, stand_ins, watched

CONFIG = """<bridge>
  <modules><module name="gaze_control" id="7"/></modules>
  <custom_modules>
    <module name="encoder_bridge" id="9">
      <connection port_to_open="/command:i" source_port="/command:o"
                  target_port="/command:i" location="robot" direction="robot_to_pilot"/>
      <connection port_to_open="/switch:i" source_port="/switch:o"
                  target_port="/switch:i" location="pilot" direction="pilot_to_robot"/>
    </module>
  </custom_modules>
  <robot_state id="20" robot="walkman" channel="tcp" rate="10"/>
  <ros_topics>
    <topic name="/multisense/points" type="sensor_msgs/PointCloud2" id="31"
           direction="robot_to_pilot" channel="udp"/>
  </ros_topics>
</bridge>
"""


def test_a_gym_module_is_watched_on_the_robot_and_stood_in_for_on_the_pilot():
    config = bridge_config.parse(CONFIG)
    gym = {FlowKey(7, kind) for kind in range(4)}
    assert gym <= watched(config, "robot") and not gym & watched(config, "pilot")
    assert gym <= stand_ins(config, "pilot") and not gym & stand_ins(config, "robot")
    assert {module_end(config.channel(key)) for key in gym} == {"robot"}


def test_custom_connections_follow_where_their_programs_are():
    config = bridge_config.parse(CONFIG)
    # A robot program's /encoder_bridge/command:o feeds the robot bridge's
    # /encoder_bridge/command:i; the pilot's bridge opens /encoder_bridge/command:o (a
    # stand-in for the robot program's port) and writes to a pilot program's command:i.
    assert module_end(config.channel(FlowKey(9, 0))) == "robot"
    assert FlowKey(9, 0) in stand_ins(config, "pilot") and FlowKey(9, 0) in watched(config, "robot")
    # The other way: the robot's bridge opens /encoder_bridge/switch:o as the stand-in.
    assert module_end(config.channel(FlowKey(9, 1))) == "pilot"
    assert FlowKey(9, 1) in watched(config, "pilot") and FlowKey(9, 1) in stand_ins(config, "robot")
    # The ports both sides' programs connect to (port_to_open) are the bridge's own.
    assert config.channel(FlowKey(9, 0)).listen_port == "/encoder_bridge/command:i"
    assert FlowKey(9, 0) not in stand_ins(config, "robot")


def test_ros_topics_and_the_robot_state_have_no_stand_ins():
    config = bridge_config.parse(CONFIG)
    for side in ("robot", "pilot"):
        assert FlowKey(31, 0) not in stand_ins(config, side) | watched(config, side)
        assert FlowKey(20, 0) not in stand_ins(config, side) | watched(config, side)


def test_the_memory_keeps_labels_and_forgets_what_the_configuration_no_longer_has(tmp_path):
    config = bridge_config.parse(CONFIG)
    memory = PresenceMemory(tmp_path / "state", config)
    assert memory.load() == frozenset()          # nothing remembered yet
    memory.save(frozenset({FlowKey(7, 0), FlowKey(7, 2), FlowKey(200, 1)}))
    assert '"gaze_control/status"' in memory.path.read_text()
    assert memory.load() == {FlowKey(7, 0), FlowKey(7, 2)}
    renumbered = bridge_config.parse(CONFIG.replace('id="7"', 'id="8"'))
    assert PresenceMemory(tmp_path / "state", renumbered).load() == {FlowKey(8, 0),
                                                                      FlowKey(8, 2)}


def test_an_unreadable_memory_is_empty_and_says_why(tmp_path, caplog):
    config = bridge_config.parse(CONFIG)
    memory = PresenceMemory(tmp_path, config)
    for text in ("{not json", '{"present": "gaze_control/status"}', "[]"):
        memory.path.write_text(text)
        with caplog.at_level(logging.WARNING, logger="bridge.gym.presence"):
            assert memory.load() == frozenset()
        assert "is not a presence file" in caplog.text
        caplog.clear()
