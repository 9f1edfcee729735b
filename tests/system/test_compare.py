"""The comparison's analysis: pure functions over what each topology recorded."""

import copy

import pytest

from bridge import status as status_codec
from system import compare
from system.session import CANCELLED_COMMAND, MODULES, SessionRecord, _parse_bridge_status
from system.topology import normalize
from yarp_lite.bottle_text import format_bottle


def observed_everything() -> dict:
    """What the pilot PC shows when the whole contract is there."""
    topics = {}
    for topic, kind in compare.CONTRACT_TOPICS.items():
        inbound = topic.endswith(("/switch", "/command"))
        topics[topic] = {"type": kind, "pub": [] if inbound else ["/node"],
                         "sub": ["/gateway"] if inbound else []}
    return {"ports": {port: [] for port in compare.CONTRACT_PORTS}, "topics": topics,
            "services": list(compare.CONTRACT_SERVICES)}


def session(kind: str, executed=None, ok=True) -> SessionRecord:
    record = SessionRecord(kind)
    record.steps = [{"label": "start gaze_control", "start": 0.0, "end": 1.0, "ok": ok}]
    record.executed = executed or {module: ["start -> running"] for module in MODULES}
    return record


def test_identical_observations_have_no_difference():
    seen = observed_everything()
    assert compare.verdict(seen, copy.deepcopy(seen), session("lab"), session("drc")) == []


def test_a_topic_missing_or_of_another_type_in_one_topology_is_a_difference():
    lab, drc = observed_everything(), observed_everything()
    del drc["topics"]["/multisense/points"]
    drc["topics"]["/joint_states"]["type"] = "std_msgs/String"
    problems = compare.verdict(lab, drc, session("lab"), session("drc"))
    assert "/multisense/points: lab sensor_msgs/PointCloud2, drc missing" in problems
    assert "/joint_states: lab sensor_msgs/JointState, drc type std_msgs/String" in problems


def test_a_switch_topic_nobody_listens_to_is_a_difference():
    lab, drc = observed_everything(), observed_everything()
    drc["topics"]["/gaze_control/switch"].update(sub=[], pub=["/rostopic"])
    assert compare.verdict(lab, drc, session("lab"), session("drc")) == [
        "/gaze_control/switch: lab walkman_msgs/Switch, drc nobody listens"]


def test_missing_in_both_is_still_reported():
    lab, drc = observed_everything(), observed_everything()
    for seen in (lab, drc):
        seen["services"].remove("/gaze_control/send_command")
    assert compare.verdict(lab, drc, session("lab"), session("drc")) == [
        "/gaze_control/send_command: missing in both topologies"]


def test_commands_executed_differently_or_a_step_without_effect_are_differences():
    seen = observed_everything()
    drc = session("drc", executed={"gaze_control": ["start -> running", "command home"],
                                   "temperature": ["start -> running"]}, ok=False)
    problems = compare.verdict(seen, seen, session("lab"), drc)
    module, cancelled = CANCELLED_COMMAND
    assert "drc: step 'start gaze_control' had no effect" in problems
    assert f"drc: the cancelled '{cancelled}' reached {module}" in problems
    assert any(p.startswith("gaze_control executed") for p in problems)


def test_expected_extras_are_listed_not_judged():
    lab, drc = observed_everything(), observed_everything()
    drc["ports"]["/bridge/pilot/status:o"] = []
    drc["ports"]["/encoder_bridge/switch:i"] = []   # a port_to_open on the pilot
    lab["topics"]["/rosout"] = {"type": "rosgraph_msgs/Log", "pub": [], "sub": []}
    own = compare.bridge_own_ports()
    assert own == ["/encoder_bridge/switch:i"]       # not its command:o: a stand-in
    assert compare.extras(lab, drc, own) == {
        "lab only": ["/rosout"], compare.DRC_ONLY: ["/bridge/pilot/status:o",
                                                    "/encoder_bridge/switch:i"],
        "drc only": []}
    assert compare.verdict(lab, drc, session("lab"), session("drc")) == []


def test_the_arrival_reports_and_the_gateways_link_port_are_the_bridges_own():
    lab, drc = observed_everything(), observed_everything()
    drc["topics"]["/multisense/points/arrived"] = {"type": "walkman_msgs/Arrival", "pub": [],
                                                   "sub": []}
    # as observe_here() reports it: the gateway's pid normalised away (the main job said
    # DIFFERENT when only the raw name was recognised)
    drc["ports"][normalize("/pilot_gateway/4242/bridge:i")] = []
    drc["topics"]["/multisense/points/elsewhere"] = {"type": "std_msgs/String", "pub": [],
                                                     "sub": []}
    names = compare.bridge_own_names()
    assert "/multisense/points/arrived" in names and \
        "/multisense/left/image_color/arrived" in names
    assert compare.extras(lab, drc, names)["drc only"] == ["/multisense/points/elsewhere"]
    assert compare.verdict(lab, drc, session("lab"), session("drc")) == [
        "/multisense/points/elsewhere: only in the drc topology (not the bridge's own)"]


def test_a_module_shown_only_through_the_bridge_is_a_difference():
    lab, drc = observed_everything(), observed_everything()
    drc["ports"]["/drc_door/switch:i"] = []          # a module the robot does not run
    assert compare.verdict(lab, drc, session("lab"), session("drc")) == [
        "/drc_door/switch:i: only in the drc topology (not the bridge's own)"]


def test_command_latency_is_timed_to_the_receipt_of_that_very_command():
    """From the gateway's stamp to the module's receipt for that command (module, port,
    seq), whatever the statuses did and whenever the recorder heard of either."""
    record = session("drc")
    record.records = [
        {"t": 0.0, "topic": "/gaze_control/status", "state": "ready"},
        # the lab's case: the status changed before the command's stamp was taken ...
        {"t": 9.99, "topic": "/gaze_control/status", "state": "tracking"},
        {"t": 10.5, "topic": "/pilot/sent_commands", "module": "gaze_control",
         "port": "switch", "text": "start 3", "seq": 3, "stamp": 10.0},
        {"t": 10.6, "topic": "/pilot/command_states", "module": "gaze_control",
         "port": "switch", "seq": 3, "state": "delivered", "stamp": 10.004},
        {"t": 10.6, "topic": "/pilot/command_states", "module": "gaze_control",
         "port": "switch", "seq": 3, "state": "accepted", "stamp": 10.012},
        # ... and the next change seconds later must not be taken for its effect
        {"t": 17.8, "topic": "/gaze_control/status", "state": "paused"},
        # another module's receipt with the same seq is not this command's
        {"t": 18.0, "topic": "/pilot/command_states", "module": "drc_valve",
         "port": "command", "seq": 4, "state": "accepted", "stamp": 18.0},
        {"t": 18.1, "topic": "/pilot/sent_commands", "module": "gaze_control",
         "port": "command", "text": "look_at 4", "seq": 4, "stamp": 17.9},
    ]
    assert compare.command_latencies(record) == [
        compare.CommandLatency("gaze_control start 3", pytest.approx(0.012)),
        compare.CommandLatency("gaze_control look_at 4", None, "no receipt")]
    assert [c.shown() for c in compare.command_latencies(record)] == ["12", "no receipt"]


def test_the_two_runs_commands_are_paired_by_their_words_not_their_order():
    """fc140: the lab's recorder missed the session's first command, and zipping the two
    runs in order put every drc figure beside the lab's next command.  Paired by the
    command's words (the gateway's sequence number is each run's own) and how many times it
    was sent before, a command one run lacks gets a row of its own."""
    L = compare.CommandLatency
    lab = [L("temperature start 860004433", 0.002), L("gaze_control pause 860126625", 0.004),
           L("gaze_control (look_at 0.66 0.25 0.08) 860077057", 0.010),
           L("gaze_control (look_at 0.66 0.25 0.08) 860420097", 0.010)]
    drc = [L("gaze_control start 860884449", 0.149), L("temperature start 860948657", 0.111),
           L("gaze_control pause 861074065", 0.115),
           L("gaze_control (look_at 0.66 0.25 0.08) 861015601", 0.122),
           L("gaze_control (look_at 0.66 0.25 0.08) 861384769", 0.112)]
    rows = compare.paired_latencies(lab, drc)
    assert [(words, a and a.seconds, b and b.seconds) for words, a, b in rows] == [
        ("gaze_control start", None, 0.149), ("temperature start", 0.002, 0.111),
        ("gaze_control pause", 0.004, 0.115),
        ("gaze_control (look_at 0.66 0.25 0.08)", 0.010, 0.122),
        ("gaze_control (look_at 0.66 0.25 0.08)", 0.010, 0.112)]


def test_a_receipt_stamped_before_its_command_gives_no_figure():
    record = session("drc")
    record.records = [
        {"t": 1.0, "topic": "/pilot/command_states", "module": "temperature", "port": "switch",
         "seq": 9, "state": "refused", "stamp": 4.998},
        {"t": 1.0, "topic": "/pilot/sent_commands", "module": "temperature", "port": "switch",
         "text": "pause 9", "seq": 9, "stamp": 5.0}]
    assert compare.command_latencies(record) == [
        compare.CommandLatency("temperature pause 9", None, "answered before its stamp")]


def bridge_line(t: float, tcp: dict, udp: dict) -> str:
    value = {"side": "robot", "time": t, "tcp": {"bytes_out": sum(tcp.values()),
                                                 "bytes_by_id": tcp},
             "udp": {"bytes_by_id": udp, "flows": {"/multisense/points": {
                 "mean_completeness": 0.75}}}}
    return format_bottle(status_codec.to_bottle(value))


def test_bridge_samples_give_bandwidth_per_id():
    lines = [bridge_line(100.0 + i, {7: 10 * i, 20: 100 * i}, {31: 1000 * i}) for i in range(11)]
    record = session("drc")
    record.bridge_samples = [_parse_bridge_status(line) for line in lines]
    assert record.bridge_samples[3]["completeness"] == {"/multisense/points": 0.75}
    assert compare.mean_bandwidth(record) == {("tcp", 7): 80.0, ("tcp", 20): 800.0,
                                              ("udp", 31): 8000.0}
    series = compare.bandwidth_by_id(record, window_s=5.0)
    assert series[31][-1] == (10.0, pytest.approx(8000.0))
    assert _parse_bridge_status("yarp: Receiving input from /bridge/robot/status:o") is None


def test_volatile_names_are_normalized():
    assert normalize("/pilot_gateway/4242/status") == "/pilot_gateway/N/status"
    assert normalize("/rostopic_1234_1700000000000") == "/rostopic"
