"""The link-loss policy on the robot when the emulated radio is cut.  Emulated hosts; needs root.

Issue 33, item 4: on the robot side of two emulated hosts, with the HAL (sim) holding a
harnessed robot, a module declaring ``LinkLoss.pause(after=2.0)`` (it holds the left arm)
and one that keeps the default ``continue`` (it counts seconds), both started by the
pilot through the bridges.  The radio goes dark: the first module pauses, a pilot's pause
with its warning ("... paused: no link to the pilot for 2 s (link-loss policy)"), the
second keeps counting, and the HAL keeps the arm where it was -- nothing falls, nothing
goes limp.  When the radio returns the module says the link is back and stays paused
until the pilot resumes it; the pilot reads the pause's warning too.
"""

from __future__ import annotations

import re
import time
from typing import List

import pytest

from bridge_harness import Side, TwoPCs
from harness import Implementation, Proc, wait_until
from pilot_side import exists
from test_emulated_network import link  # noqa: F401 -- the emulated hosts, as a fixture

pytestmark = pytest.mark.requires("root")

CONFIG = """<bridge period="0.5">
  <modules>
    <module name="holder" id="3"/>
    <module name="ticker" id="4"/>
  </modules>
</bridge>
"""
#: The witnesses' name in what they say (the runner names a module by its Python module).
SPEAKER = "link_loss_modules"
#: The holder's policy (tests/bridge/link_loss_modules.py).
PAUSE_AFTER = 2.0
#: How far the held arm's joints may move through the cut: its servo's ripple, a thousand
#: times less than an arm let go under gravity.
STILL_RAD = 0.01


@pytest.fixture
def pcs(tmp_path, lite, link):  # noqa: F811 -- link is the fixture imported above
    config = tmp_path / "bridge.xml"
    config.write_text(CONFIG)
    two = TwoPCs(tmp_path, lite, config, link=link)
    yield two
    two.close()


def start_module(pcs: TwoPCs, spec: str, name: str) -> Proc:
    return pcs.robot.python("-m", "walkman.gym.supervisor", f"link_loss_modules:{spec}",
                            "--name", f"/{name}", name=f"{name} module")


def write(side: Side, lite: Implementation, port: str, line: str) -> None:
    result = side.world.run_tool(lite, "write", f"/test/w{time.monotonic_ns()}", port,
                                 input_text=line + "\n")
    assert result.returncode == 0, result.stdout + result.stderr


def statuses(reader: Proc) -> List[List[str]]:
    """Every status a ``yarp read`` printed, split: ``[state, data...]`` (the state a word or
    its dictionary letter: ``a`` is each witness's first; the sequence number, if shown, is
    left out: no state begins with a digit)."""
    found = []
    for line in list(reader.lines):
        words = line.split()
        if words and words[0].isdigit():
            words = words[1:]
        if words and re.match(r"^[a-z_]+$", words[0]):
            found.append(words)
    return found


def latest(reader: Proc) -> List[str]:
    lines = statuses(reader)
    return lines[-1] if lines else []


def arm(reader: Proc, what: int = 0) -> List[float]:
    """The left arm's joint angles (``what`` 0) or torques (2) in the newest ``stateSI:o``
    vector: ``SEQ TIME N q[N] qdot[N] tau[N] temperature[N]``."""
    for line in reversed(list(reader.lines)):
        values = line.split()
        if len(values) > 3 and re.match(r"^[\d.]+$", values[2]):
            count = int(float(values[2]))
            if len(values) >= 3 + 4 * count:
                start = 3 + what * count
                return [float(v) for v in values[start:start + count]]
    return []


@pytest.mark.two_pcs
def test_a_cut_link_pauses_the_module_that_asked_and_the_hal_holds_the_robot(pcs, lite, link):
    link.apply("drc", loss=0)
    pcs.start_name_servers()
    pcs.robot.python("-m", "walkman.hal.server", "--backend", "sim",
                     name="hal").wait_for("HAL for walkman", 60)
    holder = start_module(pcs, "Holder", "holder")
    ticker = start_module(pcs, "Ticker", "ticker")
    pcs.start_bridge(pcs.robot)
    pcs.start_bridge(pcs.pilot)
    holder.wait_for("ready for the pilot .*link-loss policy pause after 2 s", 60)
    ticker.wait_for("ready for the pilot .*link-loss policy continue", 60)
    pcs.wait_linked()
    # What the robot's side says, read there (the pilot hears nothing during the cut).
    robot = pcs.robot.world
    holder_status = robot.tool(lite, "read", "/test/holder/status", "/holder/status:o")
    holder_warnings = robot.tool(lite, "read", "/test/holder/warnings", "/holder/warning:o")
    ticker_status = robot.tool(lite, "read", "/test/ticker/status", "/ticker/status:o")
    left_arm = robot.tool(lite, "read", "/test/left_arm", "/walkman/left_arm/stateSI:o")
    for module in ("holder", "ticker"):
        wait_until(lambda: all(exists(pcs.pilot, lite, f"/{module}/{port}")
                               for port in ("switch:i", "warning:o")), 60,
                   message=f"the robot's /{module} shown on the pilot's name server")
    pilot_warnings = pcs.pilot.world.tool(lite, "read", "/test/pilot/warnings",
                                          "/holder/warning:o")
    wait_until(lambda: exists(pcs.pilot, lite, "/holder/warning:o", "/test/pilot/warnings"),
               30, message="the pilot reading the holder's warnings")
    write(pcs.pilot, lite, "/holder/switch:i", "start 2")
    write(pcs.pilot, lite, "/ticker/switch:i", "start 2")
    wait_until(lambda: latest(holder_status)[:1] == ["a"], 60,
               message=f"the holder holding (status {latest(holder_status)})")
    wait_until(lambda: latest(ticker_status)[:1] == ["a"], 60,
               message=f"the ticker ticking (status {latest(ticker_status)})")
    wait_until(lambda: len(arm(left_arm)) == 7, 30, message="the left arm's state")
    before = arm(left_arm)
    load = max(abs(t) for t in arm(left_arm, 2))
    print(f"the held left arm carries up to {load:.1f} Nm")
    assert load > 1.0   # gravity pulls on it: a joint let go would fall, not stay

    link.blackout(True)
    cut = time.monotonic()
    paused = holder_warnings.wait_for(
        rf"{SPEAKER}: paused: no link to the pilot for (\d+) s \(link-loss policy\)", 30)
    took = time.monotonic() - cut
    print(f"paused by its link-loss policy {took:.1f} s after the cut")
    # The bridge says down after 1.5 s of silence; then the policy's 2 s, a watchdog tick.
    assert took >= PAUSE_AFTER and int(paused.group(1)) >= PAUSE_AFTER
    wait_until(lambda: latest(holder_status)[:1] == ["paused"], 10,
               message=f"the holder paused (status {latest(holder_status)})")
    # Through the cut the other module goes on, and the HAL holds the arm the holder let go.
    counted = int(latest(ticker_status)[1])
    wait_until(lambda: int(latest(ticker_status)[1]) >= counted + 3, 20,
               message=f"the ticker counting on (status {latest(ticker_status)})")
    assert latest(ticker_status)[0] == "a"
    after = arm(left_arm)
    moved = max(abs(a - b) for a, b in zip(after, before))
    print(f"left arm moved at most {moved:.4f} rad through the cut")
    assert moved < STILL_RAD, (before, after)
    assert max(abs(t) for t in arm(left_arm, 2)) > 1.0   # still carried: no zero torque
    assert latest(holder_status)[0] == "paused"

    link.blackout(False)
    holder_warnings.wait_for(rf"{SPEAKER}: the link to the pilot is back; the link-loss "
                             rf"policy paused the module \d+ s ago and it stays paused until "
                             rf"the pilot resumes it", 60)
    pilot_warnings.wait_for(r"paused: no link to the pilot for \d+ s \(link-loss policy\)", 60)
    assert latest(holder_status)[0] == "paused"          # the pilot decides...
    assert max(abs(a - b) for a, b in zip(arm(left_arm), before)) < STILL_RAD
    write(pcs.pilot, lite, "/holder/switch:i", "resume 3")
    wait_until(lambda: latest(holder_status)[:1] == ["a"], 30,
               message=f"the holder resumed by the pilot (status {latest(holder_status)})")
