"""YARP's control-board protocol (walkman.hal.controlboard) and a HAL chain behind it.

The replies' shapes are those the real controlboardwrapper2 gives (checked
against it, Bottle for Bottle, in tests/interop/test_controlboard_oracle.py);
here the parser is driven by the package's in-memory board (walkman.hal.virtual_board), and ChainBoard by the real
simulated backend.
"""

from __future__ import annotations

import math
import struct

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from walkman.hal import controlboard as cb
from walkman.hal.controlboard import ControlBoardError, JointData, Stamp
from walkman.hal.virtual_board import VirtualBoard
from yarp_lite import bottle as codec
from yarp_lite.bottle import Bottle, Vocab, vocab_encode
from yarp_lite.bottle_text import parse


def ask(board: VirtualBoard, text: str, errors: list = None) -> Bottle:
    """What the wrapper answers to a request typed as `yarp rpc` types it."""
    return cb.respond(board, parse(text), Stamp(), 1000.0, "/tester",
                      on_error=(errors if errors is not None else []).append)


@pytest.mark.parametrize("request_text, reply_text", [
    ("get axes", "[is] axes 2 [tsta] 1 1000.0 [ok]"),
    ("[get] [axes]", "[is] [axes] 2 [tsta] 1 1000.0 [ok]"),
    ("get encs", "[is] encs (10.0 20.0) [tsta] 1 1000.0 [ok]"),
    ("get enc 1", "[is] enc 20.0 [tsta] 1 1000.0 [ok]"),
    ("get name 0", "[is] name j0 [tsta] 1 1000.0 [ok]"),
    ("get llim 1", "[is] llim -90.0 90.0 [tsta] 1 1000.0 [ok]"),
    ("get tmps", "[is] tmps (30.0 31.0) [tsta] 1 1000.0 [ok]"),
    ("get prot", "[prot] 1 9 0 [ok]"),
    ("get icmd cmds", "[is] [cmds] ([pos] [pos]) [tsta] 1 1000.0 [ok]"),
    ("get icmd cmod 1", "[is] 1 [pos] [tsta] 1 1000.0 [ok]"),
    ("get icmd cmog 1 (1)", "[is] [cmog] ([pos]) [tsta] 1 1000.0 [ok]"),
    ("get icmd what", "[tsta] 1 1000.0 [ok]"),          # sic: the real wrapper's answer
    ("get intm mods", "([stif] [stif]) [tsta] 1 1000.0 [ok]"),
    ("get torq trqs", "[is] torq (1.0 -1.0) [tsta] 1 1000.0 [ok]"),
    ("get pid pid pos 0", "[is] pid (1.0 0.0 0.0 0.0 0.0 0.0 1.0 0.0 0.0 0.0) [ok]"),
    ("get dons", "[is] dons 1 [tsta] 1 1000.0 [ok]"),
    ("set pos 0 15", "[ok]"),
    ("set vels (5 5)", "[ok]"),
    ("set icmd cmod 0 posd", "[ok]"),
    ("get foo", "[fail]"),                    # not served: [fail], as the real wrapper
    ("get enc 2", "[fail]"),                  # axis out of range
    ("set poss (1 2 3)", "[fail]"),           # wrong length
    ("get icmd cmog 2 (0)", "[fail]"),        # count and list disagree
    ("get iimp stiff 0", "[fail]"),           # an interface this robot lacks
    ("help", "[nak]"),                        # a lone word, as the real port answers
])
def test_replies_are_shaped_as_the_real_wrappers(request_text, reply_text):
    assert ask(VirtualBoard(), request_text) == parse(reply_text)


def test_what_is_refused_is_reported_with_the_reason():
    errors: list = []
    ask(VirtualBoard(), "get enc 7", errors)
    ask(VirtualBoard(), "set poss (1 2 3)", errors)
    ask(VirtualBoard(), "get foo", errors)
    assert "axis 7 out of range 0..1" in errors[0]
    assert "has 3 values, expected 2" in errors[1]
    assert "[get] [foo] is not served" in errors[2]


def test_a_move_reaches_the_board_with_its_owner():
    board = VirtualBoard()
    ask(board, "set posg 1 (1) (12.5)")
    ask(board, "set stos")
    assert board.commands == [("position_move", [1], [12.5], "/tester"),
                              ("stop", [0, 1], [], "/tester")]


def test_rpc_stamps_count_up():
    board, stamp = VirtualBoard(), Stamp()
    first = cb.respond(board, parse("get axes"), stamp, 5.0)
    second = cb.respond(board, parse("get axes"), stamp, 6.0)
    assert first[-3:-1] == [1, 5.0] and second[-3:-1] == [2, 6.0]


@given(st.lists(st.one_of(st.integers(-3, 40), st.floats(allow_nan=True), st.text(max_size=5),
                          st.sampled_from([Vocab(v) for v in ("get", "set", "icmd", "intm",
                                                              "torq", "pid", "enc", "encs",
                                                              "posg", "cmog", "dons", "name")]),
                          st.lists(st.integers(-2, 3), max_size=3)), max_size=7))
def test_any_request_gets_an_answer_and_never_an_exception(items):
    reply = cb.respond(VirtualBoard(), Bottle(items), Stamp(), 1.0)
    assert str(reply[-1]) in ("ok", "fail", "nak")


# -- command:i ----------------------------------------------------------------------------

@pytest.mark.parametrize("message, expected", [
    ("([dpos]) (1.0 2.0)", cb.StreamCommand("direct", (0, 1), (1.0, 2.0))),
    ("([dpog] 1 (1)) (5.0)", cb.StreamCommand("direct", (1,), (5.0,))),
    ("([dpo] 0) (3.0)", cb.StreamCommand("direct", (0,), (3.0,))),
    ("([poss]) (1.0 2.0)", cb.StreamCommand("position_move", (0, 1), (1.0, 2.0))),
    ("([vmos]) (0.5 0.0)", cb.StreamCommand("velocity_move", (0, 1), (0.5, 0.0))),
    ("([dpos] (seq 42)) (1.0 2.0)", cb.StreamCommand("direct", (0, 1), (1.0, 2.0), 42)),
])
def test_streaming_commands_decode(message, expected):
    assert cb.decode_stream(parse(message), 2) == expected


@pytest.mark.parametrize("message, problem", [
    ("[dpos] (1.0 2.0)", "is \\(head\\) \\(values\\)"),
    ("([jump]) (1.0 2.0)", "\\[jump\\] is not served"),
    ("([dpos]) (1.0 2.0 3.0)", "carries 3 values for 2 axes"),
    ("([dpos]) (1.0)", "has 1 values for 2 joints"),
    ("([dpog] 2 (0)) (1.0 1.0)", "item 2 has 1 values, expected 2"),
    ("([dpog] 1 (5)) (1.0)", "axis 5 out of range"),
    ("([dpo] 0) (inf)", "finite"),
])
def test_malformed_streaming_commands_are_refused_with_the_reason(message, problem):
    with pytest.raises(ControlBoardError, match=problem):
        cb.decode_stream(parse(message), 2)


def test_what_a_client_streams_decodes_to_the_same_command():
    for joints in (None, [1]):
        values = [7.5] if joints else [7.5, -2.0]
        message = cb.encode_stream("direct", values, joints, seq=9)
        decoded = cb.decode_stream(codec.decode(codec.encode(message)), 2)
        assert decoded.values == tuple(values) and decoded.seq == 9
        assert decoded.joints == ((1,) if joints else (0, 1))


# -- stateExt:o --------------------------------------------------------------------------

def test_joint_data_is_the_22_fields_of_jointData_thrift():
    data = JointData((1.0, 2.0), (0.5, 0.0), None, (3.0, 4.0), ("posd", "pos"), ("stif", "stif"))
    encoded = codec.encode(cb.encode_joint_data(data, 2))
    # A list of 22, then jointPosition as a typed float64 list and its validity vocab.
    assert encoded[:8] == struct.pack("<ii", 256, 22)
    assert encoded[8:16] == struct.pack("<ii", 256 + 10, 2)
    assert encoded[32:40] == struct.pack("<ii", 9, vocab_encode("ok"))
    decoded = cb.decode_joint_data(codec.decode(encoded))
    assert decoded == data
    # controlMode is a VectorOf<int>: typed int32 list of vocab codes.
    modes = cb.encode_joint_data(data, 2)[18]
    assert list(modes) == [vocab_encode("posd"), vocab_encode("pos")]


@pytest.mark.parametrize("bottle, problem", [
    (Bottle([1.0] * 21), "22 fields"),
    (Bottle([Bottle([1.0]), Vocab("maybe")] * 11), "malformed"),
    (Bottle([Bottle(["x"]), Vocab("ok")] * 11), "float64"),
    (Bottle([Bottle([1.0, 2.0]), Vocab("ok"), Bottle([1.0]), Vocab("ok")] +
            [Bottle([1.0, 2.0]), Vocab("ok")] * 9), "jointVelocity has 1 values"),
])
def test_a_malformed_joint_data_is_refused(bottle, problem):
    with pytest.raises(ControlBoardError, match=problem):
        cb.decode_joint_data(bottle)


def test_stamp_envelope_round_trip():
    stamp = Stamp().update(1795456583.2427039)
    assert Stamp.from_envelope(stamp.envelope()) == stamp
    assert Stamp.from_envelope("garbage") is None


# -- a HAL chain behind the protocol --------------------------------------------------------

@pytest.fixture(scope="module")
def backend():
    from walkman.hal.server import make_backend

    backend = make_backend("sim", False, "locked", 1.0)
    yield backend
    backend.close()


def run(board, backend, seconds: float) -> None:
    for _ in range(int(seconds / backend.dt)):
        board.step(backend.dt)
        backend.step()


def test_a_chain_moves_by_control_mode_as_a_motor_board(backend):
    from walkman.hal.chain import ChainBoard

    assert ChainBoard("head", ["NeckYawj", "NeckPitchj"], backend).control_modes() == \
        ["posd", "posd"]                          # Walk-Man's boards: position servos
    board = ChainBoard("head", ["NeckYawj", "NeckPitchj"], backend, boot_mode="pos")
    assert board.control_modes() == ["pos", "pos"]
    board.command("set_ref_speeds", [0], [60.0])
    board.command("position_move", [0], [20.0], "/a")
    assert not board.motion_done([0])
    run(board, backend, 0.2)                       # 60 deg/s: 12 degrees on the way
    assert 8.0 < board.vector("target_positions")[0] == 20.0
    assert math.degrees(backend.reference[backend.index["NeckYawj"]]) == pytest.approx(12.0, abs=1.5)
    run(board, backend, 0.6)
    assert board.motion_done([0])
    assert board.vector("encoders")[0] == pytest.approx(20.0, abs=2.0)
    # Position direct is refused until the joint is in posd mode, then applied at once.
    board.command("direct", [0], [-10.0], "/a")
    run(board, backend, 0.01)
    assert math.degrees(backend.reference[backend.index["NeckYawj"]]) == pytest.approx(20.0)
    assert board.refused == 1
    board.set_control_modes([0], ["posd"])
    board.command("direct", [0], [-10.0], "/a")
    run(board, backend, 0.01)
    assert math.degrees(backend.reference[backend.index["NeckYawj"]]) == pytest.approx(-10.0)
    # Velocity mode moves the reference, and its watchdog stops a silent one.
    board.set_control_modes([1], ["vel"])
    start = math.degrees(backend.reference[backend.index["NeckPitchj"]])
    board.command("velocity_move", [1], [10.0], "/a")
    run(board, backend, 0.5)
    moved = math.degrees(backend.reference[backend.index["NeckPitchj"]]) - start
    assert 0.8 < moved < 1.2                       # 0.1 s at 10 deg/s, then the watchdog
    with pytest.raises(ControlBoardError, match="control mode 'torq' is not offered"):
        board.set_control_modes([0], ["torq"])


def test_arbitration_decides_before_a_command_is_recorded(backend):
    from walkman.hal.chain import ChainBoard

    index = backend.index["NeckYawj"]
    board = ChainBoard("head", ["NeckYawj", "NeckPitchj"], backend,
                       arbitrate=lambda owner, joints: {j for j in joints if owner == "/holder"
                                                        or j != index})
    board.set_control_modes([0, 1], ["posd", "posd"])
    board.command("direct", [0, 1], [5.0, 6.0], "/other")
    run(board, backend, 0.01)
    assert board.vector("direct_references")[1] == 6.0
    assert board.vector("direct_references")[0] != 5.0
    board.command("direct", [0], [5.0], "/holder")
    assert board.vector("direct_references")[0] == 5.0
    assert np.isfinite(board.vector("encoders")).all()


def test_a_command_in_the_wrong_mode_is_told_to_its_sender_and_claims_nothing(backend):
    from walkman.hal.chain import ChainBoard

    told, claimed = [], []
    board = ChainBoard("head", ["NeckYawj", "NeckPitchj"], backend,
                       arbitrate=lambda owner, joints: claimed.append((owner, joints))
                       or set(joints),
                       on_refused=lambda owner, text: told.append((owner, text)),
                       boot_mode="pos")
    board.command("direct", [0, 1], [1.0, 2.0], "/gaze")     # both joints boot in pos
    assert told and told[0][0] == "/gaze" and "not in [posd] mode but [pos], [pos]" in told[0][1]
    assert claimed == []                                      # arbitration never asked
    for _ in range(20):                                       # a flood is told once per burst
        board.command("direct", [0, 1], [1.0, 2.0], "/gaze")
    assert len(told) == 2 and "#10 of this burst" in told[1][1]
    board.command("set_ref_speeds", [1], [5.0], "/gui")       # speeds are commands too
    assert claimed[-1] == ("/gui", [backend.index["NeckPitchj"]])


def test_stop_holds_the_servo_reference(backend):
    from walkman.hal.chain import ChainBoard

    board = ChainBoard("head", ["NeckYawj", "NeckPitchj"], backend, boot_mode="pos")
    board.command("set_ref_speeds", [0], [100.0])
    board.command("position_move", [0], [30.0])
    run(board, backend, 0.1)
    board.command("stop", [0], [])
    reference = math.degrees(backend.reference[backend.index["NeckYawj"]])
    assert board.vector("target_positions")[0] == pytest.approx(reference)
    run(board, backend, 0.1)
    assert math.degrees(backend.reference[backend.index["NeckYawj"]]) == pytest.approx(reference)


def test_the_pilots_stop_all_holds_every_joint_and_refuses_commands_until_released(backend):
    from walkman.hal.chain import ChainBoard

    told = []
    board = ChainBoard("head", ["NeckYawj", "NeckPitchj"], backend, boot_mode="pos",
                       on_halted=lambda owner, text: told.append((owner, text)))
    board.command("set_ref_speeds", [0], [60.0])
    board.command("position_move", [0], [30.0], "/gaze")
    run(board, backend, 0.2)                       # on its way: about 12 degrees
    board.halt(True)
    held = math.degrees(backend.reference[backend.index["NeckYawj"]])
    board.command("position_move", [0], [-30.0], "/gaze")
    board.command("position_move", [0], [-30.0], "/gaze")
    run(board, backend, 0.5)
    assert math.degrees(backend.reference[backend.index["NeckYawj"]]) == pytest.approx(held)
    assert board.motion_done([0])                  # held still: the move was stopped too
    assert told == [("/gaze", "HAL: position_move from /gaze not applied: head is held by the "
                              "pilot's stop-all (#1 of this burst)")]   # once per burst
    with pytest.raises(ControlBoardError, match="cannot change while the pilot's stop-all"):
        board.set_control_modes([0], ["idl"])     # idle would drop the torque
    board.halt(False)
    board.command("position_move", [0], [-30.0], "/gaze")
    run(board, backend, 0.2)
    assert math.degrees(backend.reference[backend.index["NeckYawj"]]) < held - 5
