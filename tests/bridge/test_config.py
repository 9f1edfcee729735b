"""Bridge configuration: the paper's file, expansion of GYM modules, errors with lines."""

from __future__ import annotations

from pathlib import Path

import pytest

from bridge import config
from bridge.config import ConfigError
from bridge.flows import FlowKey
from bridge.main import main as bridge_main
from walkman import MODELS_DIR

MODELS = MODELS_DIR


def test_the_papers_example_loads_as_printed():
    loaded = config.load(MODELS / "bridge_paper.xml")
    assert loaded.modules == {"walking": 0, "drc_valve": 2, "drc_drive": 4, "drc_wall": 5,
                              "drc_door": 6, "gaze_control": 7, "temperature": 8,
                              "drc_plug": 11, "encoder_bridge": 9, "walking_publish": 12}
    assert loaded.period == 0.5 and loaded.gather == 0.4


def test_a_gym_module_expands_to_its_five_flows():
    loaded = config.load(MODELS / "bridge_paper.xml")
    flows = {c.label: c for c in loaded.channels if c.id == 7}
    assert [c.label for c in loaded.channels if c.id == 7] == [
        "gaze_control/switch", "gaze_control/command", "gaze_control/status",
        "gaze_control/warning", "gaze_control/receipt"]          # kinds 0..4, never reordered
    assert [c.kind for c in flows.values()] == [0, 1, 2, 3, 4]
    switch = flows["gaze_control/switch"]
    assert (switch.source, switch.destination, switch.reliable) == ("pilot", "robot", True)
    assert switch.listen_port == "/gaze_control/switch:i"        # opened on the pilot side
    assert switch.deliver_port == "/gaze_control/switch:i"       # connected on the robot side
    status = flows["gaze_control/status"]
    assert (status.source, status.reliable) == ("robot", False)
    assert status.feed_port == "/gaze_control/status:o" and status.emit_port == status.feed_port
    assert flows["gaze_control/warning"].reliable
    receipt = flows["gaze_control/receipt"]
    assert (receipt.source, receipt.reliable, receipt.expiring) == ("robot", True, False)
    assert receipt.feed_port == "/gaze_control/receipt:o"
    assert switch.expiring and flows["gaze_control/command"].expiring


def test_custom_modules_rename_ports():
    loaded = config.load(MODELS / "bridge_paper.xml")
    custom = [c for c in loaded.channels if c.id == 9]
    assert [(c.source, c.feed_port, c.listen_port, c.emit_port, c.deliver_port)
            for c in custom] == [
        ("robot", "/encoder_bridge/command:o", "/encoder_bridge/command:i",
         "/encoder_bridge/command:o", "/encoder_bridge/command:i"),
        ("pilot", "/encoder_bridge/switch:o", "/encoder_bridge/switch:i",
         "/encoder_bridge/switch:o", "/encoder_bridge/switch:i")]
    assert not custom[0].reliable and custom[1].reliable  # robot data streams, commands do not


def test_the_project_config_has_state_and_topics():
    loaded = config.load(MODELS / "bridge_drc.xml")
    assert loaded.robot_state == config.RobotStateFlow(20, "walkman", "tcp")
    assert loaded.robot_state.key == FlowKey(20, 0)
    topics = {c.label: c for c in loaded.channels if c.middleware == "ros"}
    assert topics["/multisense/points"].transport == "udp"
    assert topics["/multisense/left/camera_info"].fec == 0.5
    assert not topics["/multisense/points"].latch
    assert loaded.datagram_copies == config.DatagramCopies(commands=2, statuses=2)


def test_datagram_copies_go_to_commands_receipts_and_statuses_only():
    table = {route.label: route for route in config.load(MODELS / "bridge_drc.xml").routes()
             .values()}
    copied = {label: route.copies for label, route in table.items() if route.copies}
    assert {label for label in copied if label.startswith("drc_valve/")} == {
        "drc_valve/switch", "drc_valve/command", "drc_valve/status", "drc_valve/receipt"}
    assert not any(label.startswith("encoder_bridge") for label in copied)  # not a GYM module
    assert table["drc_valve/command"].on_tcp and table["drc_valve/command"].on_udp
    assert table["drc_valve/warning"].copies == 0 and not table["drc_valve/warning"].on_udp
    bare = config.parse('<bridge><modules><module name="a" id="1"/></modules></bridge>')
    assert not any(route.copies for route in bare.routes().values())   # off unless asked


def test_fec_auto_asks_for_repairs_sized_from_the_measured_loss():
    loaded = config.parse('<bridge><ros_topics><topic name="/a" type="a/B" id="1" '
                          'direction="robot_to_pilot" channel="udp" fec="auto"/>'
                          '<topic name="/b" type="a/B" id="2" direction="robot_to_pilot" '
                          'channel="udp" fec="0.25"/></ros_topics></bridge>')
    auto, fixed = loaded.channels
    assert (auto.fec_auto, fixed.fec_auto, fixed.fec) == (True, False, 0.25)


BAD = [
    ('<modules><module name="a" id="1"/><module name="b" id="1"/></modules>', 1,
     "duplicate id 1"),
    ('<modules>\n<module name="a" id="300"/></modules>', 2, "does not fit in 8 bits"),
    ('<modules><module name="a" id="3"/></modules>\n<custom_modules>\n<module name="c" id="3">'
     '<connection port_to_open="/x" source_port="/y" target_port="/z" location="robot" '
     'direction="robot_to_pilot"/></module></custom_modules>', 3, "duplicate id 3"),
    ('<custom_modules><module name="c" id="3">\n<connection port_to_open="/x" source_port="/y"'
     ' target_port="/z" location="robot" direction="sideways"/></module></custom_modules>', 2,
     "unknown direction 'sideways'"),
    ('<custom_modules><module name="c" id="3">\n<connection port_to_open="/x" source_port="/y"'
     ' target_port="/z" location="pilot" direction="robot_to_pilot"/></module>'
     '</custom_modules>', 2, "contradicts direction"),
    ('<custom_modules><module name="c" id="3"><connection port_to_open="/x" source_port="/y"'
     ' target_port="/z" location="robot" direction="robot_to_pilot"/>\n<connection '
     'port_to_open="/x" source_port="/w" target_port="/v" location="robot" '
     'direction="robot_to_pilot"/></module></custom_modules>', 2, "claimed twice"),
    ('<bridge><ros_topics>\n<topic name="/points" type="sensor_msgs/PointCloud2" id="4" '
     'direction="robot_to_pilot" channel="tcp"/></ros_topics></bridge>', 2,
     "TCP-ROS is unsupported: ROS data would saturate the channel"),
    ('<modules><module name="a" id="x"/></modules>', 1, "not a valid value"),
    ('<modules><module name="a" id="1">\n</modules>', 2, "malformed XML"),
    ('<modules><modul name="a" id="1"/></modules>', 1, "modul"),
    ('<bridge period="-1"/>', 1, "period must be positive"),
    # hostile input: each raised something else than ConfigError before
    ('<modules>\n<module name="a" id="%s"/></modules>' % ("9" * 5000), 2,
     "is not a usable number"),                                       # int() digit limit
    ('<bridge period="%s"/>' % ("9" * 400), 1, "is not finite"),      # float() gave inf
    ('<bridge><ros_topics>\n<topic name="/a" type="a/B" id="1" direction="robot_to_pilot" '
     'channel="udp" quality="1000"/></ros_topics></bridge>', 2,
     "quality is a JPEG quality 0..100"),                              # tiles: byte overflow
    ('<bridge><ros_topics>\n<topic name="/a" type="a/B" id="1" direction="robot_to_pilot" '
     'channel="udp" fec="sometimes"/></ros_topics></bridge>', 2, "fec"),
    ('<bridge><ros_topics>\n<topic name="/a" type="a/B" id="1" direction="robot_to_pilot" '
     'channel="udp" fec="0.9"/></ros_topics></bridge>', 2, "fec is a repair fraction 0..0.5 or auto"),
    ('<bridge>\n<datagram_copies commands="9"/></bridge>', 2, "commands is 0..5 datagram "
     "copies, got 9"),
    ('<modules>\n<module name="a\udcff" id="1"/></modules>', 2, "not text"),  # UnicodeEncodeError
    (b'<modules><module name="a\xff" id="1"/></modules>', 1, "malformed XML"),
    ('<!DOCTYPE bridge [<!ENTITY x SYSTEM "file:///etc/hostname">]>\n<bridge><modules>'
     '<module name="&x;" id="1"/></modules></bridge>', 2, "external entity"),
]


@pytest.mark.parametrize("text, line, problem", BAD)
def test_errors_name_the_file_line_and_problem(text, line, problem):
    with pytest.raises(ConfigError) as caught:
        config.parse(text, "bridge.xml")
    assert str(caught.value).startswith(f"bridge.xml:{line}: ")
    assert problem in str(caught.value)


def test_a_file_is_read_as_bytes_and_bounded(tmp_path):
    latin = tmp_path / "latin.xml"
    latin.write_bytes(b'<modules><module name="caf\xe9" id="1"/></modules>')
    with pytest.raises(ConfigError, match="latin.xml:1: malformed XML"):
        config.load(latin)  # UnicodeDecodeError before
    declared = tmp_path / "declared.xml"
    declared.write_bytes(b'<?xml version="1.0" encoding="ISO-8859-1"?>\n'
                         b'<bridge><modules><module name="caf\xe9" id="1"/></modules></bridge>')
    assert config.load(declared).modules == {"caf\xe9": 1}
    big = tmp_path / "big.xml"
    big.write_bytes(b"<bridge>" + b" " * config.MAX_CONFIG_BYTES + b"</bridge>")
    with pytest.raises(ConfigError, match="big.xml:1: larger than"):
        config.load(big)


def test_the_check_command_prints_the_table_or_the_error(tmp_path, capsys):
    assert bridge_main(["--check", str(MODELS / "bridge_paper.xml")]) == 0
    out = capsys.readouterr().out
    assert "gaze_control/switch" in out and "reliable" in out
    bad = tmp_path / "bad.xml"
    bad.write_text(BAD[0][0])
    assert bridge_main(["--check", str(bad)]) == 1
    assert "bad.xml:1: duplicate id 1" in capsys.readouterr().err


def test_command_line_mistakes_are_named(capsys):
    with pytest.raises(SystemExit):
        bridge_main(["--side", "robot"])
    assert "missing --config, --peer" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        bridge_main(["--side", "robot", "--config", "x", "--peer", "h", "--udp-rate", "fast"])
    assert "'fast' is not a rate" in capsys.readouterr().err


def test_the_xml_may_name_the_key_file_relative_to_itself(tmp_path):
    text = '<bridge key="keys/bridge.key"><modules><module name="m" id="1"/></modules></bridge>'
    assert config.parse(text, str(tmp_path / "b.xml")).key_file == tmp_path / "keys/bridge.key"
    assert config.parse(text.replace("keys/", "/etc/walkman/"), "b.xml").key_file == \
        Path("/etc/walkman/bridge.key")
    assert config.parse("<modules/>", "b.xml").key_file is None
    with pytest.raises(ConfigError, match="b.xml:1: key names no file"):
        config.parse('<bridge key=" "><modules/></bridge>', "b.xml")


def test_the_bridge_refuses_to_start_without_a_key_or_with_a_shared_one(tmp_path, capsys):
    xml = tmp_path / "b.xml"
    xml.write_text('<bridge key="bridge.key"><modules><module name="m" id="1"/></modules>'
                   '</bridge>')
    argv = ["--side", "robot", "--config", str(xml), "--peer", "127.0.0.1"]
    assert bridge_main(argv) == 1
    assert "does not exist; create one with 'walkman-bridge --gen-key" in capsys.readouterr().err
    assert bridge_main(["--gen-key", str(tmp_path / "bridge.key")]) == 0
    (tmp_path / "bridge.key").chmod(0o640)
    assert bridge_main(argv) == 1
    assert "accessible by others (mode 0640)" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        bridge_main(["--side", "robot", "--config", str(MODELS / "bridge_paper.xml"),
                     "--peer", "127.0.0.1"])
    assert "missing --key FILE" in capsys.readouterr().err
