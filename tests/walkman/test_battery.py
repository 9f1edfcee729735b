"""The robot's battery: the model (drain, sag, warnings once), YARP's batteryWrapper wire
form, and the HAL streaming it -- read by the real YARP's ``yarp read`` -- and warning."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, strategies as st

from harness import missing_reference, wait_until
from walkman.hal import battery
from walkman.hal.battery import Battery, BatteryReading, BatteryStatus
from yarp_lite.bottle import decode, encode
from yarp_lite.bottle_text import parse
from yarp_lite.nameclient import NameClient

from tests.walkman.test_gym_hal import start_hal


def test_an_hour_at_a_kilowatt_empties_a_kilowatt_hour_pack():
    pack = Battery(100.0)
    for _ in range(360):
        pack.step(1000.0, 10.0)
    assert pack.charge == pytest.approx(0.0, abs=1e-9)
    half = Battery(100.0, speedup=10.0)
    half.step(500.0, 36.0)                     # 500 W for 360 s of simulated battery time
    assert half.charge == pytest.approx(0.95)


def test_the_voltage_sags_under_load_and_falls_with_the_charge():
    pack = Battery(80.0)
    pack.step(0.0, 0.0)
    resting = pack.voltage
    pack.step(2000.0, 0.0)
    assert pack.voltage < resting - 2.0        # ~40 A through 80 mOhm
    voltages = [battery.open_circuit_voltage(c / 10) for c in range(11)]
    assert voltages == sorted(voltages) and voltages[0] == battery.EMPTY_V \
        and voltages[-1] == battery.FULL_V


def test_the_power_drawn_grows_with_torque_and_motion_and_never_regenerates():
    still = battery.electric_power(np.zeros(33), np.zeros(33))
    holding = battery.electric_power(np.full(33, 60.0), np.zeros(33))
    lifting = battery.electric_power(np.full(33, 60.0), np.full(33, 1.0))
    braking = battery.electric_power(np.full(33, 60.0), np.full(33, -1.0))
    assert still == battery.BASE_LOAD < holding < lifting
    assert braking == holding


def test_each_level_warns_once_per_discharge_and_again_after_a_charge():
    pack = Battery(25.0)
    said = []
    for _ in range(400):
        pack.step(1000.0, 4.0)                 # 0.11 % a step
        said += pack.warnings()
    assert [text.split(" (")[0] for text in said] == \
        ["battery below 20 %", "battery below 10 %", "battery below 5 %"]
    assert "plan a reset" in said[-1]
    assert pack.warnings() == []
    pack.charge = 0.3                          # a new pack
    assert pack.warnings() == []
    pack.charge = 0.19
    assert pack.warnings()[0].startswith("battery below 20 %")
    assert Battery(15.0).warnings() == []      # started below: nothing crossed


def test_the_status_follows_the_charge_as_yarps_ibattery_says_it():
    assert Battery(50).reading().status == BatteryStatus.OK_IN_USE == 2
    assert Battery(15).reading().status == BatteryStatus.LOW_WARNING == 5
    assert Battery(5).reading().status == BatteryStatus.CRITICAL_WARNING == 6


def test_bad_settings_are_refused_with_what_is_wrong():
    with pytest.raises(ValueError, match="0..100 %, got 120"):
        Battery(120)
    with pytest.raises(ValueError, match="positive"):
        Battery(50, speedup=0)


def test_the_reading_is_batterywrappers_five_values_on_the_wire():
    reading = BatteryReading(48.25, 3.5, 87.5, 30.0, BatteryStatus.OK_IN_USE)
    bottle = battery.encode_reading(reading)
    # float64 x4 then int32, as BatteryWrapper::run() adds them.
    assert encode(bottle) == bytes.fromhex("00010000" "05000000") + b"".join(
        bytes.fromhex("0a000000") + np.float64(v).tobytes() for v in (48.25, 3.5, 87.5, 30.0)) \
        + bytes.fromhex("01000000" "02000000")
    assert battery.decode_reading(decode(encode(bottle))) == reading


@given(st.lists(st.one_of(st.floats(allow_nan=True), st.integers(-10, 10), st.text(max_size=3)),
                max_size=7))
def test_any_other_message_is_refused_with_what_is_wrong(values):
    try:
        reading = battery.decode_reading(values)
    except ValueError as error:
        assert str(error)
        return
    assert len(values) == 5 and reading.status in BatteryStatus


def test_the_hal_streams_its_battery_and_warns_as_it_runs_down(lite_world, implementations):
    """The HAL on a nearly flat pack, drained 500 times faster: a real YARP ``yarp read``
    reads batteryWrapper's stream, and the levels are warned on ``/walkman/warning:o``."""
    tool = implementations["yarp"]
    if tool is None:
        missing_reference()
    lite = implementations["yarp_lite"]
    warnings = lite_world.tool(lite, "read", "/test/hal_warnings")
    wait_until(lambda: NameClient().query("/test/hal_warnings") is not None, 20,
               message="the warnings reader")
    # Connected by the name server as soon as the HAL registers its port: before it runs.
    NameClient().subscribe("/walkman/warning:o", "/test/hal_warnings")
    hal = start_hal(lite_world, "sim", "--battery", "24", "--battery-speedup", "500")
    reader = lite_world.tool(tool, "read", "/test/battery", "/walkman/battery/data:o")
    lines = []

    def readings():
        lines[:] = [parse(line) for line in reader.output().splitlines()
                    if len(line.split()) == 5 and line.split()[0][0].isdigit()]
        return len(lines) >= 3
    wait_until(readings, 30, message=f"three battery readings (got {reader.output()[-500:]})")
    decoded = [battery.decode_reading(list(values)) for values in lines]
    charges = [r.charge for r in decoded]
    assert charges == sorted(charges, reverse=True) and charges[0] < 24.0
    assert all(40.0 < r.voltage < 55.0 and r.current > 0 for r in decoded)
    wait_until(lambda: "battery below 10 %" in warnings.output(), 30,
               message=f"the 10 % warning (got {warnings.output()[-500:]})")
    assert warnings.output().count("battery below 20 %") == 1
    assert "battery below 20 %" in hal.output()
    # The rpc beside it answers as batteryWrapper does.
    answer = lite_world.run_tool(lite, "rpc", "/walkman/battery/rpc:i",
                                 input_text="[ibat] [btnf]\n").stdout
    assert "[is] [btnf]" in answer and "Wh pack" in answer
    assert math.isfinite(decoded[-1].temperature)
