"""Robot state codec: Table 1 resolution, deltas, rotation of temperatures, bad input."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from bridge.errors import BridgeProtocolError
from bridge.wire import state_codec
from bridge.wire.state_codec import Layout, RobotState, StateDecoder, StateEncoder
from codec_helpers import FUZZ

LAYOUT = Layout(tuple((chain, tuple(f"{chain}_{i}" for i in range(count))) for chain, count in (
    ("torso", 3), ("head", 2), ("left_arm", 7), ("right_arm", 7), ("left_leg", 6),
    ("right_leg", 6), ("left_hand", 1), ("right_hand", 1))))
JOINTS = LAYOUT.joints


def state(t: float, rng: np.random.Generator, moving: bool = True) -> RobotState:
    q = np.sin(t + np.arange(JOINTS)) if moving else np.linspace(-1, 1, JOINTS)
    tau = 50 * np.cos(2 * t + np.arange(JOINTS)) if moving else np.full(JOINTS, 3.0)
    temperature = 35 + 0.01 * t + rng.normal(0, 0.05, JOINTS) if moving else np.full(JOINTS, 40.0)
    return RobotState(LAYOUT, t, q, tau, temperature)


def test_layout_counts_the_walkman_joints():
    assert JOINTS == 33


def test_quantization_keeps_table_1_resolution():
    q = np.linspace(-3.9, 3.9, 1001)
    back = state_codec.encoders_from_codes(state_codec.quantize_encoders(q))
    assert np.max(np.abs(back - q)) <= 8 / 65536
    tau = np.array([-250.0, -10.0, -0.5, 0.0, 0.4, 12.0, 219.0])
    back_tau = state_codec.torques_from_codes(state_codec.quantize_torques(tau))
    assert np.all(np.abs(back_tau - tau) <= np.maximum(0.03 * np.abs(tau), 0.05))
    temperature = np.array([-20.0, 25.37, 80.0])
    assert np.allclose(state_codec.temperatures_from_codes(
        state_codec.quantize_temperatures(temperature)), temperature, atol=0.005)


def test_a_stream_round_trips_within_quantization():
    rng = np.random.default_rng(1)
    encoder, decoder = StateEncoder(period=1.0), StateDecoder()
    latest_temperature = {}
    for step in range(20):
        sent = state(step * 1.0, rng)
        got = decoder.decode(encoder.encode(sent))
        assert got.layout == LAYOUT and got.time == pytest.approx(sent.time, abs=1e-3)
        assert np.max(np.abs(got.q - sent.q)) <= 8 / 65536
        for index in got.fresh_temperatures:
            latest_temperature[index] = sent.temperature[index]
            assert got.temperature[index] == pytest.approx(sent.temperature[index], abs=0.006)
        if step == 0:
            assert len(got.fresh_temperatures) == JOINTS  # the key frame carries them all
        else:
            assert len(got.fresh_temperatures) == 7       # seven joints per second


def test_table_1_information_fits_in_half_the_papers_bits():
    """Moving every joint: the payload is about Table 1's minus its ids and overhead."""
    rng = np.random.default_rng(2)
    encoder = StateEncoder(period=1.0)
    encoder.encode(state(0.0, rng))
    sizes = [len(encoder.encode(state(float(t), rng))) for t in range(1, 30)]
    assert max(sizes) * 8 <= 528 + 264 + 7 * 16 + 3 * 8  # encoders, torques, temps, header
    still = StateEncoder(period=1.0)
    still.encode(state(0.0, rng, moving=False))
    assert len(still.encode(state(1.0, rng, moving=False))) <= 20


def test_a_new_connection_starts_with_a_key_frame():
    rng = np.random.default_rng(3)
    encoder = StateEncoder()
    encoder.encode(state(0.0, rng))
    delta = encoder.encode(state(0.5, rng))
    with pytest.raises(BridgeProtocolError, match="before any key frame"):
        StateDecoder().decode(delta)
    encoder.reset()
    assert StateDecoder().decode(encoder.encode(state(1.0, rng))).layout == LAYOUT


@FUZZ
@given(st.binary(max_size=120))
def test_any_input_decodes_or_raises_the_peer_error(data):
    decoder = StateDecoder()
    encoder = StateEncoder()
    decoder.decode(encoder.encode(state(0.0, np.random.default_rng(0))))
    for candidate in (data, b"\x01" + data):
        try:
            decoder.decode(candidate)
        except BridgeProtocolError:
            pass


def test_truncated_frames_are_refused():
    frame = StateEncoder().encode(state(0.0, np.random.default_rng(0)))
    for cut in range(1, len(frame)):
        with pytest.raises(BridgeProtocolError):
            StateDecoder().decode(frame[:cut])


def test_a_refused_frame_leaves_the_previous_one_in_place():
    rng = np.random.default_rng(4)
    encoder, decoder = StateEncoder(), StateDecoder()
    first = decoder.decode(encoder.encode(state(0.0, rng)))
    second_frame = encoder.encode(state(0.5, rng))
    bad_key = StateEncoder().encode(state(9.0, rng))[:-1]  # a truncated key frame
    with pytest.raises(BridgeProtocolError, match="truncated"):
        decoder.decode(bad_key)
    second = decoder.decode(second_frame)  # still the delta of the first frame
    assert second.time == 0.5 and first.time == 0.0
    assert np.allclose(second.q, np.sin(0.5 + np.arange(JOINTS)), atol=2e-4)


def test_a_key_frame_carries_every_temperature_from_joint_zero():
    cold = RobotState(LAYOUT, 0.0, np.zeros(JOINTS), np.zeros(JOINTS), np.full(JOINTS, -99.5))
    frame = bytearray(StateEncoder().encode(cold))
    start = len(frame) - JOINTS - 2  # start, count, then one byte per joint (code 50)
    assert frame[start:start + 2] == bytes((0, JOINTS))
    frame[start] = 1
    with pytest.raises(BridgeProtocolError, match="temperatures 1\\+33 do not fit"):
        StateDecoder().decode(bytes(frame))
