"""drc_drive end to end: HAL with the robot seated in the car (harness off), the module as a
process, yarp-lite write.

Done when turn_left/turn_right turn the sim steering wheel by the angle, the status
shows the wheel's angle as the robot measures it, and accelerate presses the sim
throttle for the time and as far as asked.
"""

import time

import pytest

from harness import wait_until
from walkman.model.mjcf import PILOT_POSES

WHEEL = PILOT_POSES["car"]


def test_steer_and_accelerate(task_at):
    """Seated in the car with the harness off: the seat holds the robot, which ends where it
    sat, upright."""
    drive = task_at("car", "drc_drive", "--harness", "off")
    seated = drive.scene.base()
    drive.command(WHEEL, "ready")
    for command, state in (("reach", "reached"), ("approach", "approached"),
                           ("grasp", "grasped"), ("drive", "drive")):
        drive.command(command, state)
    start = drive.scene.prop("steering")
    for command, angle in (("turn_left 0.5", 0.5), ("turn_right 1.0", -1.0)):
        before = drive.scene.prop("steering")
        drive.send("command", command)
        wait_until(lambda: drive.pilot.state() != "drive", 10, message=command)
        drive.pilot.wait_state("drive", 40)
        assert drive.scene.prop("steering") - before == pytest.approx(angle, rel=0.1), command
    # The status: the angle asked in all, and the one the hand on the rim measures, which is
    # the wheel's in the world -- once the status after the turn's end has come (statuses
    # come twice a second; the wheel settles after the state's change: fc14 of 2026-11-28
    # read the one before, 0.13 rad short, on a loaded PC).
    seen = []          # (measured, the world's), the last look: said if they never match

    def measured_matches_the_world() -> bool:
        seen[:] = [drive.pilot.data()[4], drive.scene.prop("steering") - start]
        return abs(seen[0] - seen[1]) <= 0.1

    try:
        wait_until(measured_matches_the_world, 10,
                   message="the status's measured angle to match the wheel's within 0.1 rad")
    except Exception as exc:
        raise AssertionError(f"{exc}: measured {seen[0]:+.3f} rad, the world's wheel "
                             f"{seen[1]:+.3f} rad") from exc
    assert drive.pilot.data()[3] == pytest.approx(-0.5)
    drive.send("command", "accelerate 1")
    drive.pilot.wait_warning("the foot is not on the pedal (rotate_foot first)")
    drive.send("command", "rotate_foot")   # from drive back to drive: see it leave first
    wait_until(lambda: drive.pilot.state() != "drive", 10, message="rotate_foot")
    drive.pilot.wait_state("drive", 40)
    # The pedal sampled on the simulator's clock from before the command until the module is
    # back in ``drive``: a status seen late no longer cuts the press short (fc58 of the fifth
    # 2026-11-28 session, load 52: 0.78 s of 2 s measured from when the test saw
    # "accelerating").  Between samples the edges are unknown: the press lasted at least
    # from the first pressed sample to the last, at most between the unpressed ones around.
    samples = [drive.scene.timed_prop("throttle")]      # (simulator's time, throttle angle)
    drive.send("command", "accelerate 2")
    began, state, deadline = False, None, time.monotonic() + 60
    while True:
        samples.append(drive.scene.timed_prop("throttle"))   # the next, at 30 Hz
        state = drive.pilot.state(timeout=0) or state          # a status if one came
        began = began or state == "accelerating"
        if began and state == "drive":
            break
        assert time.monotonic() < deadline, ("accelerate 2 still running", state)
    samples.append(drive.scene.timed_prop("throttle"))
    peak = max(angle for _, angle in samples)
    assert peak > 0.1  # of the pedal's 0.35 rad
    pressed = [i for i, (_, angle) in enumerate(samples) if angle > peak / 2]
    at_least = samples[pressed[-1]][0] - samples[pressed[0]][0]
    at_most = samples[min(pressed[-1] + 1, len(samples) - 1)][0] - \
        samples[max(pressed[0] - 1, 0)][0]
    assert at_least <= 2 + 2.0 and at_most >= 0.8 * 2, (at_least, at_most)
    drive.send("command", "accelerate 1 0.4")      # 40 % of the travel
    wait_until(lambda: drive.pilot.state() == "accelerating", 10, message="accelerating 40 %")
    partial = []
    while drive.pilot.state() != "drive":
        partial.append(drive.scene.prop("throttle"))
    assert 0.1 * peak < max(partial) < 0.75 * peak, (max(partial), peak)
    drive.send("command", "move_away_foot")   # from drive back to drive: see it leave first
    wait_until(lambda: drive.pilot.state() != "drive", 10, message="move_away_foot")
    drive.pilot.wait_state("drive", 40)
    for command, state in (("ungrasp", "ungrasped"), ("move_away_hand", "moved_away_hand")):
        drive.command(command, state)
    assert drive.scene.prop("throttle") < 0.02
    x, y, z, yaw = drive.scene.base()
    assert abs(x - seated[0]) < 0.03 and abs(y - seated[1]) < 0.03 and \
        abs(z - seated[2]) < 0.03 and abs(yaw - seated[3]) < 0.05, (seated, drive.scene.base())
    assert drive.scene.tilt() < 0.1
