"""Pure parts of walkman: lifecycle, pilot messages, HAL protocol, packets, firmware, configs."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from codec_helpers import FUZZ
from walkman.control.trajectory import (JointTrajectory, quintic, quintic_acceleration,
                                        quintic_velocity)
from walkman.inifile import IniError, parse_ini
from walkman.gym.interfaces import (InterfaceError, PilotCommand, _Inbox, decode_command,
                                    decode_status, encode_command, encode_status)
from walkman.gym.lifecycle import TRANSITIONS, IllegalTransition, State, next_state
from walkman.hal import protocol
from walkman.hal.config import HalConfig, load_config
from walkman.hal.ethercat.firmware import ControlBoards, SensorBoard, pack_tx, unpack_rx
from walkman.hal.ethercat.packets import (CLEAR_FAULTS, CONTROL_RX, CONTROL_TX, SENSOR_RX,
                                          ControlRx, ControlTx, Fault, SensorRx)
from walkman.hal.protocol import HalProtocolError
from walkman.hal.thermal import ThermalModel
from walkman.model import MODELS_DIR
from walkman.model.description import walkman
from yarp_lite.bottle import Bottle, Vocab


# -- lifecycle (Figure 8) ---------------------------------------------------------------------

@pytest.mark.parametrize("state, command, after", [
    (State.CONSTRUCTOR, "start", State.RUNNING), (State.RUNNING, "pause", State.PAUSED),
    (State.PAUSED, "resume", State.RUNNING), (State.RUNNING, "stop", State.STOPPED),
    (State.PAUSED, "stop", State.STOPPED), (State.STOPPED, "start", State.RUNNING),
    (State.RUNNING, " QUIT ", State.DESTRUCTOR), (State.STOPPED, "quit", State.DESTRUCTOR),
])
def test_lifecycle_transitions(state, command, after):
    assert next_state("m", state, command) == after


@pytest.mark.parametrize("state, command", [
    (State.CONSTRUCTOR, "pause"), (State.STOPPED, "resume"), (State.RUNNING, "start"),
    (State.PAUSED, "pause"), (State.RUNNING, "dance"), (State.DESTRUCTOR, "start")])
def test_illegal_transitions_name_state_and_command(state, command):
    with pytest.raises(IllegalTransition, match=f"'{command}' is not valid while {state.value}"):
        next_state("gaze", state, command)


def test_quit_is_allowed_from_every_live_state():
    assert all(State.DESTRUCTOR in targets.values() for state, targets in TRANSITIONS.items()
               if state != State.DESTRUCTOR)


# -- pilot messages -------------------------------------------------------------------------------

@pytest.mark.parametrize("bottle, command", [
    (["start"], PilotCommand("start")), (["start", 7], PilotCommand("start", (), 7)),
    ([["look_at", 1.0, 0.0, 1.2], 8], PilotCommand("look_at", (1.0, 0.0, 1.2), 8)),
    (["look_at", 1.0, 0.0, 1.2], PilotCommand("look_at", (1.0, 0.0, 1.2))),
    ([["turn", 30]], PilotCommand("turn", (30,))),
])
def test_command_decoding(bottle, command):
    assert decode_command(Bottle(bottle)) == command
    assert decode_command(encode_command(command)) == command


def test_cmd_n_is_an_argument_for_commands_that_need_numbers():
    """``go_straight 10`` typed by a pilot is a distance, ``reach 10`` a sequence number."""
    from walkman.gym.interfaces import decoder_for
    from walkman.modules.drc_valve import Module as Valve
    from walkman.modules.walking import Module as Walking

    walking, valve = decoder_for(Walking), decoder_for(Valve)
    assert walking(Bottle(["go_straight", 10])) == PilotCommand("go_straight", (10,))
    assert walking(Bottle([["go_straight", 10], 5])) == PilotCommand("go_straight", (10,), 5)
    assert valve(Bottle(["reach", 10])) == PilotCommand("reach", (), 10)
    # turn's angle is optional for the valve: "turn SEQ" stays a sequence number.
    assert valve(Bottle(["turn", 12])) == PilotCommand("turn", (), 12)


@pytest.mark.parametrize("bottle", [[], [5], [[]], [[1, 2]], [["x"], "y"], [["x"], 1, 2]])
def test_malformed_commands(bottle):
    with pytest.raises(InterfaceError):
        decode_command(Bottle(bottle))


def test_status_dictionary_compression():
    statuses = ["idle", "ready", "reaching"]
    wire = encode_status(3, "reaching", [1.5], statuses)
    assert wire == [3, "c", 1.5]
    assert decode_status(wire, statuses) == (3, "reaching", [1.5])
    assert encode_status(4, "unlisted", (), statuses) == [4, "unlisted"]


def test_inbox_drops_repeated_sequence_numbers_and_keeps_order():
    inbox = _Inbox(decode_command)
    for bottle in (["a", 1], ["b", 2], ["a", 1], ["c"], ["c"]):
        inbox.feed(Bottle(bottle))
    inbox.feed(Bottle([]))
    assert [inbox.get().name for _ in range(4)] == ["a", "b", "c", "c"]
    assert inbox.get() is None and inbox.take_rejections() == ["empty command"]


# -- HAL protocol ----------------------------------------------------------------------------------

def test_state_round_trip():
    state = protocol.ChainState(5, 1.25, (0.1, 0.2), (0.0, 1.0), (3.0, 4.0), (30.0, 31.0))
    assert protocol.decode_state_si(protocol.encode_state_si(state), 2) == state
    with pytest.raises(HalProtocolError, match="expected 15 for 3 joints"):
        protocol.decode_state_si(protocol.encode_state_si(state), 3)
    with pytest.raises(HalProtocolError, match="float64"):
        protocol.decode_state_si(Bottle([1, 2.0, 2.0, *([0.0] * 8)]), 2)


def test_the_whole_robot_state_names_its_joints_order():
    state = protocol.ChainState(5, 1.25, (0.1, 0.2), (0.0, 1.0), (3.0, 4.0), (30.0, 31.0))
    wire = protocol.encode_whole_state(state, ["NeckYawj", "NeckPitchj"])
    assert protocol.decode_whole_state(wire, ["NeckYawj", "NeckPitchj"]) == state
    # The same joints grouped otherwise (a HAL restarted with another configuration) are
    # refused: their positions would land on the wrong joints.
    with pytest.raises(HalProtocolError, match="groups the joints differently"):
        protocol.decode_whole_state(wire, ["NeckPitchj", "NeckYawj"])
    with pytest.raises(HalProtocolError, match="expected 11 for 2 joints"):
        protocol.decode_whole_state(protocol.encode_state_si(state), ["NeckYawj", "NeckPitchj"])
    with pytest.raises(HalProtocolError, match="empty"):
        protocol.decode_whole_state(Bottle([]), ["NeckYawj"])


# -- EtherCAT packets (Figure 4) ----------------------------------------------------------------------

def test_packet_sizes_follow_figure_4():
    assert CONTROL_TX.size == 4 + 2 + 2 + 2 + 2
    assert CONTROL_RX.size == 4 + 4 + 2 + 2 + 2 + 2
    assert SENSOR_RX.size == 6 * 4 + 2 + 2 + 2


def test_packets_round_trip_with_their_resolution():
    tx = ControlTx(0.123456, CLEAR_FAULTS, 1500, 25.5, 70000)
    again = ControlTx.unpack(tx.pack())
    assert again.position_desired == pytest.approx(0.123456, abs=1e-6)
    assert (again.p_gain, again.d_gain, again.timestamp) == (1500, 25.5, 70000 & 0xFFFF)
    rx = ControlRx.unpack(ControlRx(-1.5, 1.4, 45.67, -123.456, 5, 17).pack())
    assert (rx.max_temperature, rx.torque_link, rx.fault) == (45.7, -123.46, 5)
    sensor = SensorRx.unpack(SensorRx((1.0, -2.5, 3.0, 0.1, 0.2, 0.3), 0, 9, 2).pack())
    assert sensor.values == pytest.approx((1.0, -2.5, 3.0, 0.1, 0.2, 0.3))
    with pytest.raises(ValueError, match="12 bytes"):
        ControlTx.unpack(b"\0" * 11)


def test_vectorized_firmware_speaks_the_same_bytes_as_single_packets():
    positions = np.array([0.1, -0.2, 0.3])
    image = pack_tx(positions, 0, np.array([100.0, 200.0, 300.0]), np.array([1.0, 2.0, 3.0]), 42)
    singles = b"".join(ControlTx(p, 0, g, d, 42).pack()
                       for p, g, d in zip(positions, [100, 200, 300], [1.0, 2.0, 3.0]))
    assert image == singles
    boards = ControlBoards([-1] * 3, [1] * 3, [50] * 3)
    boards.receive(image, positions)
    boards.control(positions, np.zeros(3), np.full(3, 30.0))
    answers = boards.answer(positions, np.full(3, 30.0), np.array([1, 2, 3]))
    for index in range(3):
        rx = ControlRx.unpack(answers[index * 16:(index + 1) * 16])
        assert rx.reference == pytest.approx(positions[index], abs=1e-6)
        assert rx.round_trip_us == index + 1
    assert len(unpack_rx(answers)) == 3


def test_firmware_pid_saturation_and_faults():
    boards = ControlBoards([-1.0], [1.0], [10.0])
    boards.receive(pack_tx(np.array([0.5]), CLEAR_FAULTS, np.array([100.0]), np.array([1.0]), 1),
                   np.array([0.0]))
    assert boards.control(np.array([0.0]), np.array([0.0]), np.array([30.0]))[0] == 10.0
    assert boards.fault[0] & Fault.TORQUE_SATURATED
    # the same frame again and again: after 50 cycles the board holds where it is
    for _ in range(60):
        boards.receive(pack_tx(np.array([0.5]), 0, np.array([100.0]), np.array([1.0]), 1),
                       np.array([0.2]))
    assert boards.fault[0] & Fault.COMMUNICATION_TIMEOUT and boards.reference[0] == 0.2
    boards.control(np.array([0.0]), np.array([0.0]), np.array([95.0]))
    assert boards.fault[0] & Fault.OVER_TEMPERATURE
    assert boards.control(np.array([0.0]), np.array([0.0]), np.array([95.0]))[0] == 0.0
    boards.receive(pack_tx(np.array([0.0]), CLEAR_FAULTS, np.array([100.0]), np.array([1.0]), 2),
                   np.array([0.0]))
    assert boards.fault[0] == 0
    short = ControlBoards([-1.0] * 2, [1.0] * 2, [10.0] * 2)
    short.receive(b"\0" * 13, np.zeros(2))  # a truncated image starves the second board
    assert short.fault[1] & Fault.BAD_PACKET


def test_sensor_board_rejects_non_finite_readings():
    board = SensorBoard("ft", lambda: (math.nan, 0, 0, 0, 0, 0))
    values = SensorRx.unpack(board.answer(5))
    assert values.values == (0.0,) * 6 and values.fault & Fault.BAD_PACKET


@FUZZ
@given(st.binary(max_size=600))
def test_boards_survive_any_image(image):
    boards = ControlBoards([-1.0] * 33, [1.0] * 33, [10.0] * 33)
    boards.receive(image, np.zeros(33))
    torque = boards.control(np.zeros(33), np.zeros(33), np.full(33, 30.0))
    assert np.all(np.abs(torque) <= 10.0)


# -- thermal, configuration, trajectories ----------------------------------------------------------------

def test_thermal_model_heats_under_load_and_cools():
    model = ThermalModel(2)
    for _ in range(600):
        model.step(np.array([140.0, 0.0]), 1.0)
    assert 70 < model.temperature[0] < 85 and model.temperature[1] == pytest.approx(30.0)


def test_shipped_chain_groupings_are_valid():
    for name in ("hal_chains.ini", "hal_whole_body.ini"):
        config = load_config(MODELS_DIR / name)
        assert sum(len(j) for j in config.chains.values()) == 33


@pytest.mark.parametrize("chains, problem", [
    ({"a": ["WaistLat", "WaistLat"]}, "is in chains"), ({"a": ["Nope"]}, "unknown joint"),
    ({"a": ["WaistLat"]}, "joints in no chain"), ({"a": []}, "has no joints"),
])
def test_bad_groupings_are_refused(chains, problem):
    with pytest.raises(IniError, match=problem):
        HalConfig(chains=chains).validate(walkman())


def test_ini_parsing_and_errors():
    sections = parse_ini("a 1 // comment\n# note\nb x y\n[s]\nc 2.5\n", "f.ini")
    assert sections[""] == {"a": [1], "b": ["x", "y"]} and sections["s"] == {"c": [2.5]}
    with pytest.raises(IniError, match="f.ini:2: malformed section"):
        parse_ini("a 1\n[broken\n", "f.ini")


def test_quintic_boundary_conditions():
    assert quintic(0) == 0 and quintic(1) == 1 and quintic(0.5) == pytest.approx(0.5)
    for tau in (0.0, 1.0):
        assert quintic_velocity(tau) == 0 and quintic_acceleration(tau) == 0
    trajectory = JointTrajectory(np.zeros(2), np.array([1.0, -1.0]), 2.0, t0=10.0)
    assert trajectory.at(10.0) == pytest.approx([0, 0]) and trajectory.at(12.0) == pytest.approx([1, -1])
    assert trajectory.done(12.0) and not trajectory.done(11.9)
    with pytest.raises(ValueError):
        JointTrajectory(np.zeros(1), np.ones(1), 0.0)
