"""Drive a real Pilot Interface by clicking its widgets (QTest), as a pilot would.

Run by tests/system/test_pilot_gui.py as its own process (rospy allows one node per
process, and the recovery test kills a PI for real):

    python tests/system/pi_driver.py PHASE OUTDIR

Phases: ``first`` (start gaze_control, the valve task up to ``reached``, then waits
to be killed), ``second`` (a new PI: the current state shown at once, the rest of the
task, a cancelled timed turn, the 3-D view checked).  Each step prints ``STEP name``;
failures print ``FAIL why`` and exit 1.  Screenshots go to OUTDIR.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

from python_qt_binding.QtCore import Qt
from python_qt_binding.QtTest import QTest
from python_qt_binding.QtWidgets import QApplication, QPushButton

from pilot.app import PilotWindow, configured_modules
from pilot.layouts import load_layout

OUT = Path(sys.argv[2])


def say(text: str) -> None:
    print(text, flush=True)


def fail(text: str) -> None:
    say(f"FAIL {text}")
    window.screenshot(OUT / "failure.png")
    sys.exit(1)


def pump(seconds: float) -> None:
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        QApplication.processEvents()
        time.sleep(0.02)


def wait(predicate, timeout: float, what: str) -> None:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        QApplication.processEvents()
        if predicate():
            return
        time.sleep(0.05)
    fail(f"timed out ({timeout:g} s) waiting for {what}")


def widget(module: str):
    return next(w for w in window.module_widgets[module] if w.objectName() == f"task_{module}")


def click(button: QPushButton, what: str) -> None:
    if not button.isEnabled():
        fail(f"{what} is disabled")
    QTest.mouseClick(button, Qt.LeftButton)
    say(f"CLICK {what}")


def do(module: str, command: str, state: str, timeout: float = 60.0) -> None:
    task = widget(module)
    click(task.buttons[command], f"{module} {command}")
    wait(lambda: task.state == state, timeout, f"{module} {state} after {command}")
    say(f"STEP {module} {command} -> {state}")


def view_pixels(disable: str = "") -> int:
    """Pixels of the 3-D view that differ from its background (a display switched off)."""
    frame = window.view3d.frame
    manager = frame.getManager()
    group = manager.getRootDisplayGroup()
    displays = {group.getDisplayAt(i).getName(): group.getDisplayAt(i)
                for i in range(group.numDisplays())}
    if disable:
        displays[disable].setEnabled(False)
    pump(1.5)
    top_left = frame.mapToGlobal(frame.rect().topLeft())
    image = QApplication.primaryScreen().grabWindow(0, top_left.x(), top_left.y() + 40,
                                                    frame.width(), frame.height() - 70)
    image.save(str(OUT / f"view3d{'-without-' + disable if disable else ''}.png"))
    if disable:
        displays[disable].setEnabled(True)
    image = image.toImage()
    background = image.pixelColor(3, 3)       # the scene's background colour
    count = 0
    for y in range(0, image.height(), 2):
        for x in range(0, image.width(), 2):
            colour = image.pixelColor(x, y)
            if abs(colour.red() - background.red()) + abs(colour.green() - background.green()) \
                    + abs(colour.blue() - background.blue()) > 60:
                count += 1
    return count


def first() -> None:
    gaze = next(w for w in window.module_widgets["gaze_control"])
    wait(lambda: gaze.state is not None, 60, "gaze_control's status")
    click(gaze.switch_buttons["start"], "gaze_control start")
    wait(lambda: gaze.state == "ready", 30, "gaze_control ready")
    say("STEP gaze_control started")
    valve = widget("drc_valve")
    wait(lambda: valve.state is not None, 60, "drc_valve's status")
    if valve.switch_buttons["pause"].isEnabled() or valve.switch_buttons["resume"].isEnabled():
        fail("pause/resume enabled before the module runs")
    click(valve.switch_buttons["start"], "drc_valve start")
    wait(lambda: valve.state == "idle", 30, "drc_valve idle")
    if valve.switch_buttons["start"].isEnabled():
        fail("start still enabled while the module runs")
    illegal = [name for name in ("reach", "grasp", "turn", "home")
               if valve.buttons[name].isEnabled()]
    if illegal:
        fail(f"illegal commands enabled in idle: {illegal}")
    say("STEP illegal buttons disabled")
    window.screenshot(OUT / "first-idle.png")
    do("drc_valve", "valvedatasent", "ready")
    do("drc_valve", "reach", "reached")
    window.screenshot(OUT / "first-reached.png")
    say("READY to be killed")
    pump(600)


def second() -> None:
    valve = widget("drc_valve")
    # A new PI shows the current state at once (latched status), not "not running".
    wait(lambda: valve.state == "reached", 15, "the restarted PI to show reached")
    say("STEP restarted PI shows reached")
    do("drc_valve", "approach", "approached")
    do("drc_valve", "grasp", "grasped")
    turn = valve.buttons["turn"]
    click(turn, "drc_valve turn (first click)")
    wait(lambda: turn.waiting, 10, "the turn's countdown")
    pump(0.6)
    window.screenshot(OUT / "countdown.png")
    click(turn, "drc_valve turn (second click: cancel)")
    wait(lambda: not turn.waiting and "cancelled" in turn.text(), 10, "the cancel")
    pump(4.0)                                   # past the countdown: nothing may leave
    if valve.state != "grasped":
        fail(f"the cancelled turn moved the module to {valve.state}")
    say("STEP cancelled turn never sent")
    click(turn, "drc_valve turn")
    wait(lambda: valve.state == "turning", 15, "turning after the countdown")
    wait(lambda: valve.state == "grasped", 60, "the turn to end")
    say("STEP drc_valve turn -> grasped")
    for command, state in (("ungrasp", "ungrasped"), ("move_away", "moved_away"),
                           ("home", "idle")):
        do("drc_valve", command, state)
    window.tabs.setCurrentIndex(0)
    window.screenshot(OUT / "pilot-interface.png")
    with_all = view_pixels()
    without_robot = view_pixels("Robot")
    without_cloud = view_pixels("Cloud")
    say(f"PIXELS all {with_all} without_robot {without_robot} without_cloud {without_cloud}")
    if with_all - without_robot < 300:
        fail(f"the robot model draws {with_all - without_robot} pixels (under 300)")
    if with_all - without_cloud < 100:
        fail(f"the point cloud draws {with_all - without_cloud} pixels (under 100)")
    say("STEP 3-D view draws the robot and the cloud")
    window.tabs.setCurrentIndex(1)
    pump(1.0)
    window.screenshot(OUT / "camera.png")
    if window.camera.frames == 0:
        fail("no camera frame shown")
    say("STEP camera shown")
    say("DONE")


if __name__ == "__main__":
    app = QApplication(sys.argv[:1])
    modules = configured_modules(Path(__file__).resolve().parents[2] / "models" / "bridge_drc.xml")
    layout = load_layout("main-pilot", modules=list(modules))
    window = PilotWindow(layout, modules, f"pi_test_{sys.argv[1]}")
    window.show()
    window.start()
    wait(lambda: window.ros_up, 60, "the PI's ROS node")
    say(f"UP after {window.ready_after:.2f} s")
    {"first": first, "second": second}[sys.argv[1]]()
    window.close_link()
