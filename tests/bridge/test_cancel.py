"""Cancelling a queued command: done before it leaves, or refused -- never both.

The pilot bridge's journal replaces a command by a tombstone only while no frame has
claimed it (bridge.transport.journal); a cancel racing the frame that would carry the command
(the link's return, or the command's own send) therefore either wins -- the robot
receives the tombstone, the module nothing -- or is told "too late" -- the robot
receives the command.  Run 50 times through two real TCP channels, the cancel sent
0-2 ms after the command, where the sender thread claims it.
"""

from __future__ import annotations

import random
import time

from bridge.transport.journal import is_tombstone
from harness import wait_until
from test_tcp_channel import COMMAND, pair  # noqa: F401 -- two channels on loopback
from walkman.gym.validity import split
from yarp_lite.bottle import Bottle

ROUNDS = 50


def spin(seconds: float) -> None:
    """Wait a sub-millisecond moment exactly: the thing under test is the race's instant."""
    until = time.perf_counter() + seconds
    while time.perf_counter() < until:
        pass


def test_a_cancel_racing_the_frame_is_either_done_or_refused_never_both(pair):
    robot, pilot = pair(period=5.0)
    chance = random.Random(33)            # the same interleavings on every run
    outcomes = {"cancelled": 0, "too late": 0}
    for number in range(ROUNDS):
        pilot.channel.send_reliable(COMMAND, Bottle([Bottle(["go", number]), number]))
        spin(chance.uniform(0.0, 0.002))
        cancelled, too_late = pilot.journal.cancel({COMMAND}, lambda payload: True)
        # Neither: it left, reached the robot and was acknowledged within the spin -- gone
        # from the outbox (the gateway then answers "no queued command N"): too late too.
        assert len(cancelled) + len(too_late) <= 1, (cancelled, too_late)
        wait_until(lambda: len(robot.reliable) == number + 1, 10,
                   message=f"round {number}: the frame")
        message, _ = split(robot.reliable[number])
        if cancelled:
            assert is_tombstone(message), f"round {number}: cancelled, yet {message} came"
            outcomes["cancelled"] += 1
        else:
            assert message == Bottle([Bottle(["go", number]), number]), message
            outcomes["too late"] += 1
        wait_until(lambda: pilot.journal.waiting() == 0, 10, message="acknowledged")
    print(f"{ROUNDS} races: {outcomes}")
