"""The Generic Widget tells "link down" from "module dead" (issue 33, Tests).  Root and Xvfb.

Real processes on the two emulated hosts (network namespaces, the ``drc`` profile on
the user-space radio, its loss set to 0 so that no lost keep-alive fakes a cut): on the
robot the HAL (MuJoCo), ``gaze_control``, ``temperature`` and the robot's bridge; on
the pilot its bridge, the gateway and a Pilot Interface under Xvfb (the ``status-pilot``
layout below), driven by ``tests/system/pi_driver.py link``,
which polls the widgets' real label texts.

1. Link up, ``temperature`` killed with SIGKILL: its widget says "not running (last:
   …)"; ``gaze_control``'s never stops showing its state meanwhile.
2. Blackout of the radio: every module widget says "link down for N s; module …"
   (``temperature``: "silent since before the cut", the pilot knew it was dead), none
   says "not running", and neither module's ``start`` is enabled (it would wait in the
   queue for the link).  The time from the cut to each widget's label is printed.
3. Six seconds into the cut, every tab read as a pilot reads it (issue 66): the Status
   tab's banner and each module's "heard", the camera's caption, the 3-D view's banner, the
   link's summary and every module line say the link is down, and each age shown is at
   least the cut's: nothing the robot sent before the cut reads as live.
4. Link back: ``gaze_control`` shows its state again, ``temperature`` "not running".

The PI is the main pilot's (``main-pilot``: every tab, librviz beside them), and the robot
streams its camera and joint states, so that each tab has something to show as old.

The bound on cut -> widget.  The issue asks for 2 s.  The PI learns of a cut from the
gateway's ``/bridge/link`` (:mod:`nodekit.link_watch`): down once the pilot bridge's
status (every :data:`bridge.node.STATUS_PERIOD`, 0.5 s) says the robot's bridge has
been silent for over :data:`~nodekit.link_watch.SILENT_DOWN` (1.5 s).  The silence
begins with the last frame before the cut, so by its own configuration the link watch
says "down" up to SILENT_DOWN + STATUS_PERIOD = 2.0 s after the cut -- before the
status's YARP hop, the gateway's ROS message and the PI's event loop.  2 s is then no
bound a test can hold on a loaded 2-core box; the test asserts SILENT_DOWN +
STATUS_PERIOD + :data:`TRANSPORT_S` and prints the figures.  Measured here (8 runs,
2 of them beside two CPU burners at load 20-40): 1.43-1.98 s, median 1.58 s, of which
the widget's own part (gateway's decision -> label) is under 0.03 s.
Screenshots (module-dead, link-down, link-back) are kept in the test's folder and
copied to ``out/pilot-link-down`` for a look.
"""

from __future__ import annotations

import re
import shutil
import signal
import time

import pytest

from bridge.node import STATUS_PERIOD
from nodekit.link_watch import SILENT_DOWN
from system.topology import REPO, Topology
from tests.system.conftest import dump_outputs_if_failed
from tests.system.test_pilot_gui import display, start_pi  # noqa: F401 -- the Xvfb fixture

pytestmark = pytest.mark.requires("root", "xvfb")

VICTIM, OTHER = "temperature", "gaze_control"
#: What runs: the camera and the joint states for the tabs to show, no recording.
PROGRAMS = ("hal", "gaze_control", "temperature", "perception", "bridge_robot", "bridge_pilot",
            "gateway", "joint_state_pilot")
#: The bridge status's YARP hop, the gateway's ROS message and the PI's Qt loop, under load.
TRANSPORT_S = 1.0
LINK_DOWN_BOUND_S = SILENT_DOWN + STATUS_PERIOD + TRANSPORT_S
#: The issue's figure, printed beside the measurement.
ISSUE_GOAL_S = 2.0


#: An age as the PI words it (pilot.link_cut.age_text): "0.4 s", "18 s", "3 min".
AGE = r"[\d.]+ (?:s|min)"


def seconds(age: str) -> float:
    number, unit = age.split()
    return float(number) * (60 if unit == "min" else 1)


def every_tab_says_the_link_is_down(lines, into_cut: float) -> None:
    """The driver's ``TEXT where | text`` lines, read ``into_cut`` seconds into the cut: each
    says the link is down, and every age it gives is at least most of the cut's (a value
    that kept arriving would read "0.1 s ago")."""
    texts = dict(line[5:].split(" | ", 1) for line in lines if line.startswith("TEXT "))
    for where, text in texts.items():
        print(f"during the cut, {where}: {text!r}")
    assert not [t for t in texts.values() if "not running" in t or "(hidden)" in t], texts
    patterns = {
        "status banner": rf"link down for {AGE}: the states, charts and battery below as of "
                         rf"(?P<age>{AGE}) ago",
        "camera caption": rf"link down for {AGE}: frame \d+ as of (?P<age>{AGE}) ago \|.*",
        "3-D view banner": rf"link down for {AGE}: the robot as of (?P<age>{AGE}) ago, "
                           rf"the cloud as of (?P<age2>{AGE}) ago",
        "link summary": rf"link down for {AGE} \| no round trip while down \|.*",
    }
    for where, pattern in patterns.items():
        assert where in texts, f"no {where} in the PI: {sorted(texts)}"
        match = re.fullmatch(pattern, texts[where])
        assert match, f"{where} during the cut: {texts[where]!r}"
        for age in (v for k, v in match.groupdict().items() if v):
            assert seconds(age) >= into_cut - 2, \
                f"{where} shows what the robot sent {age} ago, {into_cut:.1f} s into the cut"
    heard = {k: v for k, v in texts.items() if k.startswith("status heard ")}
    modules = {k: v for k, v in texts.items() if k.startswith(("task_", "generic_"))}
    assert heard and modules, sorted(texts)
    for where, text in heard.items():
        assert re.fullmatch(rf"(never|{AGE} ago) \(link down {AGE}\)", text), (where, text)
    for where, text in modules.items():
        assert text.startswith("link down for "), (where, text)
    # One source (/bridge/link): every widget counts the cut from the same moment.
    downs = {where: seconds(m.group(1)) for where, text in texts.items()
             for m in [re.search(rf"link down (?:for )?({AGE})", text)] if m}
    assert max(downs.values()) - min(downs.values()) <= 1.5, downs


@pytest.fixture
def drc_hosts(emulated_link, tmp_path, request):
    """The drc topology on the emulated hosts; every process and namespace gone after."""
    topology = Topology("drc", tmp_path / "drc", link=emulated_link, profile="drc", loss=0.0)
    try:
        topology.start_name_servers()
        topology.start_all(PROGRAMS)
        for name in PROGRAMS:
            topology.process(name).wait_for(topology.table[name].ready, 180)
        yield topology
    finally:
        for pc in topology.unique_pcs():
            dump_outputs_if_failed(request, pc.processes.values())
        topology.close()


def step(pi, pattern: str, timeout: float) -> str:
    """The PI driver's line matching ``pattern``; its FAIL, if it fails first, fails the test."""
    line = pi.wait_for(rf"{pattern}|FAIL", timeout).group(0)
    assert not line.startswith("FAIL"), pi.output()
    return line


@pytest.mark.two_pcs
def test_the_widgets_tell_a_cut_link_from_a_dead_module(display, drc_hosts, emulated_link,
                                                         tmp_path):
    # the display first: it outlives the PI, which the topology stops
    out = tmp_path / "screens"
    out.mkdir()
    try:
        pi = start_pi(drc_hosts.pilot, display, "link", out, VICTIM, OTHER)
        step(pi, "STEP both running", 240)

        drc_hosts.process(VICTIM).kill(signal.SIGKILL)     # the module, not the link
        pi.send("killed\n")
        step(pi, f"STEP {VICTIM} dead", 90)

        cut = time.time()
        emulated_link.blackout(True)
        pi.send(f"cut {cut:.6f}\n")
        step(pi, "STEP link down shown", 60)
        shown = {m.group(1): (float(m.group(2)), m.group(3)) for m in
                 map(re.compile(r"^LINKDOWN (\S+) ([\d.]+) (.*)$").match, pi.lines) if m}
        gateway = {m.group(1): float(m.group(2)) for m in
                   map(re.compile(r"^GATEWAY (\S+) ([-\d.]+)$").match, pi.lines) if m}
        for module, (seconds, text) in shown.items():
            print(f"cut -> {module}'s widget shows the link down: {seconds:.2f} s "
                  f"(gateway said down at {gateway[module]:.2f} s; issue's goal "
                  f"{ISSUE_GOAL_S:g} s, asserted {LINK_DOWN_BOUND_S:g} s): {text!r}")
        assert set(shown) == {VICTIM, OTHER}, pi.output()
        assert re.fullmatch(rf"link down for {AGE}; module last heard \w+", shown[OTHER][1]), \
            shown
        assert re.fullmatch(rf"link down for {AGE}; module silent since before the cut "
                            r"\(last: \w+\)", shown[VICTIM][1]), shown
        for module, (seconds, _) in shown.items():
            assert seconds <= LINK_DOWN_BOUND_S, \
                f"{module}'s widget showed the link down {seconds:.2f} s after the cut"

        into_cut = float(step(pi, r"STEP every tab read, ([\d.]+) s", 60).split()[4])
        every_tab_says_the_link_is_down(pi.lines, into_cut)

        emulated_link.blackout(False)
        pi.send("restored\n")
        step(pi, "DONE", 120)
        back = pi.wait_for(r"STEP link back: (.*)", 1).group(1)
        assert back.startswith("'not running (last: "), back
    finally:
        shutil.copytree(out, REPO / "out" / "pilot-link-down", dirs_exist_ok=True)
