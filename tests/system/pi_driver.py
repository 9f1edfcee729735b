"""Drive a real Pilot Interface by clicking its widgets (QTest), as a pilot would.

Run by tests/system/test_pilot_gui.py as its own process (rospy allows one node per
process, and the recovery test kills a PI for real):

    python tests/system/pi_driver.py PHASE OUTDIR

Phases: ``first`` (start gaze_control, the valve task up to ``reached``, then waits
to be killed), ``second`` (a new PI: the current state shown at once, the rest of the
task, a cancelled timed turn, the 3-D view checked, STOP ALL and release clicked), ``latency COUNT`` (for
bench/bench_pilot.py: COUNT clicks on gaze_control's look_at, 4 a second, each
with a new target, printing ``CLICKED i wall-time look_at x y``), ``peer OTHER X``
(one of two PIs: sends ``look_at X`` once the test says ``go`` on stdin, sees the
other PI's command in its log; with a 3-D view, a dragged marker moves the valve's
pose fields, and after the test says ``restarted`` (roscore and bridge restarted
under it) the PI shows the module again, librviz takes the new bridge's cloud,
the PI sends ``look_at X+0.1`` and draws the robot), ``camera`` (the camera tab in
the lab, no bridge: frames with a black sky and a cloud without depth there read
100 %, nothing hatched),
``terrain [camera]`` (the rough-ground course by walking's clicks and two footsteps placed
and dragged in the 3-D view; ``camera``: the rest of the way on footsteps from the head
camera's cloud), ``ramp up|down`` (the ramp by walking's clicks, the footsteps onto the slope
and off it dragged in the 3-D view where the test says), ``valve COUNT`` (for bench/bench_valve_topologies.py: the
whole valve task COUNT times by clicks, printing ``TIMED run command state click-time
shown-time`` per step and ``SHOWN time state stamp`` for every status the task widget
showed, ``stamp`` the gateway's receipt; after each run but the last it waits for the
bench to say ``next``), ``task MODULE COUNT`` (the same for any task module, by its
``TASK_STEPS``), ``tasks MODULE...`` (each task once, after the test said ``go
MODULE``: the README's "every DRC task in one session"; drc_drive's wheel also steered by
its slider; a screenshot ``MODULE-done.png`` as each task ends).  ``PI_NAME`` and
``PI_LAYOUT`` choose the PI's name and layout (``PI_LAYOUTS`` the file of layouts).  Each step prints ``STEP
name``; failures print ``FAIL why`` and exit 1.  Screenshots go to OUTDIR.
"""

from __future__ import annotations

import math
import os
import queue
import sys
import threading
import time
from pathlib import Path
from typing import Any, Callable, Dict, List, Optional, Sequence

import numpy as np
from python_qt_binding.QtCore import Qt
from python_qt_binding.QtTest import QTest
from python_qt_binding.QtWidgets import QApplication, QPushButton

from pilot.app import PilotWindow, configured_modules
from pilot.layouts import DEFAULT_LAYOUTS, load_layout
from pilot.link import CLOUD_TOPIC, IMAGE_TOPIC
from pilot.widgets.camera import percent
from walkman import MODELS_DIR

OUT = Path(sys.argv[2])


def say(text: str) -> None:
    print(text, flush=True)


def fail(text: str) -> None:
    say(f"FAIL {text}")
    if not window.screenshot(OUT / "failure.png"):
        say(f"(the failure's screenshot could not be saved in {OUT})")
    # Closed as the PI closes on its way out (pilot.app.main): exiting with the link's
    # threads still posting to the window crashed the interpreter's teardown (SIGSEGV in a
    # port's reader, fc14 of 2026-11-28), which hid the failure's cause behind a crash.
    window.close_link()
    sys.exit(1)


def widget_state(owner) -> str:
    """What a module widget shows and knows, for a failure's message."""
    from pilot.catalogue import legal_switches

    catalogue = getattr(owner, "catalogue", None)
    legal = catalogue.legal(owner.state or "") if catalogue is not None else []
    age = owner.age
    return (f"state {owner.state!r}, presence {owner.presence}, heard "
            f"{'never' if age is None else f'{age:.1f} s ago'}, status label "
            f"{owner.status_label.text()!r}, legal commands {sorted(legal)}, switches "
            f"{sorted(legal_switches(owner.state))}, link down since {owner.link_down_at}")


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
    """The module's task widget, else its Generic Widget."""
    widgets = window.module_widgets[module]
    return next((w for w in widgets if w.objectName() == f"task_{module}"), widgets[0])


STDIN: "queue.Queue[str]" = queue.Queue()


def read_stdin() -> None:
    for line in sys.stdin:
        STDIN.put(line.strip())


def wait_word(word: str, timeout: float) -> None:
    """Pump the GUI until the test writes ``word`` on our stdin."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        QApplication.processEvents()
        try:
            if STDIN.get(timeout=0.05) == word:
                return
        except queue.Empty:
            pass
    fail(f"the test never said {word!r}")


#: s a click waits for its disabled button to be enabled (a module's status comes every 0.5 s)
ENABLE_WAIT_S = 10.0


def click(button: QPushButton, what: str, owner=None) -> None:
    """Click; with ``owner`` (the button's module widget), a refusal it shows fails.

    A disabled button is waited for, as a pilot would (at most :data:`ENABLE_WAIT_S`), and
    the wait is printed with what the widget showed meanwhile: a PI whose GUI thread fell
    behind shows the statuses it takes late as old, their module absent, until the next.
    """
    if not button.isEnabled():
        before = widget_state(owner) if owner is not None else ""
        start = time.monotonic()
        end = start + ENABLE_WAIT_S
        while not button.isEnabled() and time.monotonic() < end:
            QApplication.processEvents()
            time.sleep(0.05)
        if not button.isEnabled():
            fail(f"{what} is disabled" + (f" ({before}; {ENABLE_WAIT_S:g} s later: "
                                          f"{widget_state(owner)})" if owner else ""))
        say(f"WAITED {time.monotonic() - start:.1f} s for {what} to be enabled ({before})")
    shown = owner.warnings.count() if owner is not None else 0
    QTest.mouseClick(button, Qt.LeftButton)
    say(f"CLICK {what}")
    if owner is not None and owner.warnings.count() > shown \
            and "not sent:" in owner.warnings.item(0).text():
        fail(f"{what} was refused: {owner.warnings.item(0).text()}")


def wait_sendable(module: str) -> None:
    """Until the gateway's subscribers hear this PI (what the PI publishes before is refused,
    ROS would drop it): a pilot would see "not sent" and click again, the test waits."""
    wait(lambda: not window.link.cannot_send(module), 30,
         f"the gateway's subscriptions to our {module} commands")


def do(module: str, command: str, state: str, timeout: float = 60.0) -> None:
    task = widget(module)
    click(task.buttons[command], f"{module} {command}", task)
    wait(lambda: task.state == state, timeout, f"{module} {state} after {command}")
    say(f"STEP {module} {command} -> {state}")


def view_pixels(disable: str = "") -> int:
    """Pixels of the 3-D view that differ from its background (a display switched off).
    The view is librviz's window, drawn by its own process and embedded in ours."""
    view = window.view3d
    wait(lambda: view.container is not None, 60, "the 3-D view's window embedded")
    if disable:
        view.set_display_enabled(disable, False)
        wait(view.applied(), 30, f"the 3-D view's process to switch {disable} off")
    pump(1.5)                                 # librviz draws at 15 Hz
    container = view.container
    top_left = container.mapToGlobal(container.rect().topLeft())
    image = QApplication.primaryScreen().grabWindow(0, top_left.x(), top_left.y() + 40,
                                                    container.width(), container.height() - 70)
    image.save(str(OUT / f"view3d{'-without-' + disable if disable else ''}.png"))
    if disable:
        view.set_display_enabled(disable, True)
        wait(view.applied(), 30, f"the 3-D view's process to switch {disable} on")
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
    wait_sendable("gaze_control")
    click(gaze.switch_buttons["start"], "gaze_control start", gaze)
    wait(lambda: gaze.state == "ready", 30, "gaze_control ready")
    say("STEP gaze_control started")
    valve = widget("drc_valve")
    wait(lambda: valve.state is not None, 60, "drc_valve's status")
    if valve.switch_buttons["pause"].isEnabled() or valve.switch_buttons["resume"].isEnabled():
        fail("pause/resume enabled before the module runs")
    wait_sendable("drc_valve")
    click(valve.switch_buttons["start"], "drc_valve start", valve)
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
    wait_sendable("drc_valve")
    do("drc_valve", "approach", "approached")
    do("drc_valve", "grasp", "grasped")
    turn = valve.buttons["turn"]
    click(turn, "drc_valve turn (first click)", valve)
    wait(lambda: turn.waiting, 10, "the turn's countdown")
    # At once: the cancel must reach the gateway within its 3 s countdown (a screenshot
    # taken here first made a loaded CI's cancel arrive after the turn had left).
    click(turn, "drc_valve turn (second click: cancel)", valve)
    wait(lambda: not turn.waiting and "cancelled" in turn.text(), 10, "the cancel")
    pump(4.0)                                   # past the countdown: nothing may leave
    if valve.state != "grasped":
        fail(f"the cancelled turn moved the module to {valve.state}")
    say("STEP cancelled turn never sent")
    click(turn, "drc_valve turn", valve)
    wait(lambda: turn.waiting, 10, "the turn's countdown")
    pump(0.6)
    window.screenshot(OUT / "countdown.png")     # this one runs out: the turn leaves
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
    view = window.camera
    wait(lambda: view.report_for(IMAGE_TOPIC) is not None and
         view.report_for(CLOUD_TOPIC) is not None, 30,
         "the pilot bridge's reports on the image and cloud shown")
    image, cloud = view.report_for(IMAGE_TOPIC), view.report_for(CLOUD_TOPIC)
    caption = view.caption.text()     # (the scene has red of its own: no pixel count here)
    say(f"CAMERA {caption} | bridge image {image.fraction:.4f} {len(image.missing)} regions, "
        f"cloud {cloud.fraction:.4f}")
    if f"image {percent(image.fraction)} arrived | cloud {percent(cloud.fraction)} of points" \
            not in caption or ("red: tiles" in caption) != bool(image.missing):
        fail(f"the camera says {caption!r}, the bridge {image}, {cloud}")
    say("STEP camera shows the bridge's reports")
    camera_under_control()
    # The robot's battery: HAL -> walkman-joint-state -> /battery -> the bridge -> this PI.
    wait(lambda: window.status.battery.reading is not None, 60, "the robot's battery")
    say(f"STEP battery shown: {window.status.battery.text()}")
    window.tabs.setCurrentIndex(next(i for i in range(window.tabs.count())
                                     if window.status.isAncestorOf(window.tabs.widget(i))
                                     or window.tabs.widget(i).isAncestorOf(window.status)))
    pump(0.5)
    window.screenshot(OUT / "status.png")
    window.tabs.setCurrentIndex(0)
    click(window.stop_button, "STOP ALL")
    wait(lambda: "HAL held" in window.banner.text(), 20, "the robot's answer to STOP ALL")
    wait(lambda: valve.state == "paused", 20, "drc_valve paused by the stop-all")
    window.screenshot(OUT / "stop-all.png")
    say(f"STEP stop all: {window.banner.text()}")
    click(window.release_button, "release")
    wait(lambda: "HAL free" in window.banner.text(), 20, "the release")
    say("STEP released")
    say("DONE")


def frames_stop(view, what: str) -> None:
    """No new picture once a frame on its way has come (the topology's camera: 1 Hz)."""
    pump(1.5)
    shown = view.frames
    pump(3.0)                   # the thing under test: three frame periods pass, nothing comes
    if view.frames != shown:
        fail(f"{view.frames - shown} camera frames came after {what}")


def frames_come(view, what: str) -> None:
    shown = view.frames
    wait(lambda: view.frames >= shown + 2, 30, f"camera frames after {what}")


def camera_under_control() -> None:
    """The head camera is a GYM module (issue 32): from its Generic Widget the pilot pauses
    and resumes it, and sets its rate to 0 (running, no pictures) and to 2 Hz again."""
    camera, view = widget("perception"), window.camera
    perception(pause=True)
    frames_stop(view, "the pause")
    perception(pause=False)
    frames_come(view, "the resume")
    say("STEP camera paused and resumed from its widget")
    shown = ""

    def says(state: str, rate: float) -> bool:
        nonlocal shown
        text = camera.status_label.text()    # read once: a link event may change it next
        if camera.state == state and f"{rate:g} Hz" in text:
            shown = text
        return bool(shown)

    for rate, state in ((0.0, "idle"), (2.0, "streaming")):
        camera.command_box.setCurrentText("set_rate")
        camera.number_fields[0].setValue(rate)
        shown = ""
        click(camera.send_button, f"perception set_rate {rate:g}", camera)
        wait(lambda: says(state, rate), 20, f"perception {state} at {rate:g} Hz")
        if rate == 0:
            frames_stop(view, "set_rate 0")
        else:
            frames_come(view, "set_rate 2")
    say(f"STEP camera rate 0 then 2 Hz from its widget: {shown}")


def red_pixels() -> int:
    """Pixels of the camera picture hatched red (scaled smoothly: near the hatch colour)."""
    image = window.camera.picture.pixmap().toImage()
    colours = [image.pixelColor(x, y) for x in range(0, image.width(), 2)
               for y in range(0, image.height(), 2)]
    return sum(1 for c in colours if c.red() > 140 and c.green() < 90 and c.blue() < 90)


def camera() -> None:
    view = window.camera
    window.tabs.setCurrentIndex(1)
    wait(lambda: view.frames >= 3 and view.cloud is not None, 60, "camera frames and a cloud")
    pump(1.0)
    window.screenshot(OUT / "camera-lab.png")
    caption, red = view.caption.text(), red_pixels()
    black = float((view.image.rgb.max(axis=2) == 0).mean())
    say(f"CAMERA {caption} | red {red} | black {black:.2f}")
    if black < 0.3:
        fail(f"the frame shown is {black:.0%} black: not the black sky the test publishes")
    if "image 100% arrived | cloud 100% of points" not in caption or red:
        fail(f"in the lab the camera says {caption!r} with {red} red pixels")
    say("DONE")


def start_gaze():
    gaze = widget("gaze_control")
    wait(lambda: gaze.presence == "running", 60, "gaze_control's status")
    wait_sendable("gaze_control")
    if gaze.state != "ready" and gaze.switch_buttons["start"].isEnabled():
        click(gaze.switch_buttons["start"], "gaze_control start", gaze)
    wait(lambda: gaze.state == "ready", 30, "gaze_control ready")
    return gaze


def send_look_at(gaze, x: float) -> None:
    """By the task widget's button, or the Generic Widget's command entry."""
    if hasattr(gaze, "buttons"):
        for field, value in zip(gaze.fields["look_at"], (x, 0.2, 0.1)):
            field.setValue(value)
        click(gaze.buttons["look_at"], f"look_at {x:.3f}", gaze)
        return
    gaze.command_box.setCurrentText("look_at")
    pump(0.1)
    for field, value in zip(gaze.number_fields, (x, 0.2, 0.1)):
        field.setValue(value)
    click(gaze.send_button, f"send look_at {x:.3f}", gaze)


def drag(marker: str, position, yaw: float, followed, what: str, roll: float = 0.0,
         pitch: float = 0.0) -> None:
    """What RViz sends while the pilot drags ``marker`` to ``position`` turned ``yaw`` (and
    ``roll``, ``pitch``: its rotate rings; pelvis frame): pose updates to the PI's marker
    server until ``followed()`` says the PI took it."""

    import rospy
    from visualization_msgs.msg import InteractiveMarkerFeedback

    from pilot.view3d_child import rpy_to_quaternion

    topic = rospy.Publisher(f"{window.view3d.markers_topic}/feedback", InteractiveMarkerFeedback,
                            queue_size=5)
    wait(lambda: topic.get_num_connections() > 0, 60, "the marker server's feedback subscriber")
    feedback = InteractiveMarkerFeedback(client_id="/rviz/Markers", marker_name=marker,
                                         control_name="move_x",
                                         event_type=InteractiveMarkerFeedback.POSE_UPDATE)
    feedback.header.frame_id = "pelvis"
    (feedback.pose.position.x, feedback.pose.position.y,
     feedback.pose.position.z) = position
    (feedback.pose.orientation.x, feedback.pose.orientation.y, feedback.pose.orientation.z,
     feedback.pose.orientation.w) = rpy_to_quaternion(roll, pitch, yaw)
    say(f"STEP dragging {what} from {time.time():.3f}")
    # A drag is a stream of pose updates.  The marker server lives in the render process:
    # if librviz takes it down meanwhile (its own crash, which the PI survives), the PI
    # starts another and the drag goes on once the new one listens -- as a pilot would
    # drag again when the view is back.
    end, next_update = time.monotonic() + 90, 0.0
    while not followed() and time.monotonic() < end:
        if time.monotonic() >= next_update and topic.get_num_connections() > 0:
            topic.publish(feedback)
            next_update = time.monotonic() + 0.3
        pump(0.02)
    if not followed():
        view = window.view3d
        fail(f"{what} did not follow the marker (the PI's markers "
             f"{ {n: m.pose for n, m in view.markers.items()} }, render process "
             f"{view.embedded_pid}, its deaths {view.deaths})")


def drag_marker() -> None:
    """What RViz sends while the pilot drags the valve's marker: the fields follow."""

    valve = widget("drc_valve")
    fields = valve.fields["valvedatasent"]
    drag("drc_valve", (0.61, -0.12, 0.05), math.pi / 2,
         lambda: abs(fields[0].value() - 0.61) < 1e-3, "the valve")
    followed = time.time()      # the fields follow and the scene edit leaves in one step
    values = [round(f.value(), 3) for f in fields[:6]]
    say(f"STEP the valve's fields followed at {followed:.3f}")
    if values[:3] != [0.61, -0.12, 0.05] or abs(values[5] - 1.571) > 2e-3:
        fail(f"the valve's pose fields show {values} after the drag")
    say(f"STEP marker dragged: valve pose {values}")


def walk(command: str, fields=(), expected: str = "") -> None:
    """A walking command by clicks: its fields typed, the timed button counted down, then
    the walk until the module is idle again (the robot standing).  ``expected``: the walk
    must end in a foothold warning containing it (a landing put back), else in none."""
    walking = widget("walking")

    def warnings() -> List[str]:
        return [walking.warnings.item(i).text() for i in range(walking.warnings.count())]

    before = set(warnings())        # (each line has its time: a new one is a new line)
    for field, value in zip(walking.fields.get(command, []), fields):
        field.setValue(value)
    click(walking.buttons[command], f"walking {command}", walking)
    wait(lambda: walking.state not in ("idle", None), 60, f"walking to start {command}")
    wait(lambda: walking.state == "idle", 120, f"walking idle after {command}")
    shown = [text for text in warnings() if text not in before]
    # the guard tripped (the walk was cut) or a landing was put back (walking.foothold)
    if any("balance" in text for text in shown) or \
            [text for text in shown if "foothold" in text and
             (not expected or expected not in text)] or \
            (expected and not any(expected in text for text in shown)):
        fail(f"walking {command}: {shown}" + (f" (expected {expected!r})" if expected else ""))
    say(f"STEP walking {command} {' '.join(map(str, fields))} done".replace("  ", " ") +
        (f" with the warning {expected!r}" if expected else ""))


def start_walking():
    """walking's widget, once walking is started from it and the knees are bent."""
    walking = widget("walking")
    wait(lambda: walking.state is not None, 60, "walking's status")
    wait_sendable("walking")
    click(walking.switch_buttons["start"], "walking start", walking)
    wait(lambda: walking.state == "idle", 30, "walking idle")
    pump(2.0)                                      # the knees bend (CROUCH_TIME 1.5 s)
    return walking


def terrain(on_camera: bool) -> None:
    """The rough-ground course by clicks (issue 32): start walking, go to the step, step up,
    two footsteps placed in the 3-D view (the second dragged beside the first), on to the
    far edge and step down -- or (``on_camera``) along the kerb and down its far side on
    footsteps from the camera's cloud, the head bent down, perception paused but for the
    look."""
    walking = start_walking()
    say("STEP walking started")
    if on_camera:
        perception(pause=True)        # not needed until the look from the kerb's top
    walk("go_straight", [0.12])
    walk("step_up", [0.05, 0.33])
    if os.environ.get("PI_STEP_DOWN_EARLY"):
        # sent before the far edge: the sole comes down on the kerb it leaves, goes back
        # (not in the suite's run: the put-back tripped the balance guard in 2 of 5 runs at
        # load 14-29 on 2 cores; offline, tests/modules/test_walking.py checks it)
        walk("step_down", [0.05, 0.33], expected="met ground on its way 5 cm down")
        pump(1.0)
        window.screenshot(OUT / "terrain-step-down-put-back.png")
    wait(lambda: window.soles() is not None, 30, "the robot's joint state")
    for _ in range(2):
        click(walking.add_button, "add footstep", walking)
    if walking.ordered() != ["footstep_1", "footstep_2"] or \
            not {"footstep_1", "footstep_2"} <= set(window.view3d.markers):
        fail(f"footsteps {walking.footsteps}, markers {list(window.view3d.markers)}")
    first, second = walking.footsteps["footstep_1"], walking.footsteps["footstep_2"]
    say(f"STEP footsteps placed {first[:3]} {second[:3]}")
    # the second one (right foot, a stride ahead) dragged back beside the first: the feet
    # end side by side
    beside = (first[0], second[1], second[2])
    drag("footstep_2", beside, second[5],
         lambda: abs(walking.footsteps["footstep_2"][0] - first[0]) < 1e-3, "footstep_2")
    pump(1.0)
    window.screenshot(OUT / "terrain-footsteps.png")
    walk("footsteps")
    # on along the kerb and down its far side on footsteps placed from the head camera's
    # cloud: the head bent down by gaze_control, a leg to the far edge, a look again, down
    if on_camera:
        # on to the far edge on footsteps from the head camera's cloud (beside two burners
        # the walk tripped the balance guard in 2 of 7 runs, ZMP 0.4-0.6 cm from the feet's
        # edge on the kerb's flat top, while perception rendered beside the walking loop)
        perception(pause=False)
        look_down(start_gaze())
        finer_ground()
        # along the kerb and down its far side, placed by one look from the kerb's top
        # (from the far edge itself the body hides the floor for 10 cm past the toes)
        camera_leg(0.6)
    else:
        # the toes to 1 cm from the far edge: the 0.33-m step down then lands its heel 6 cm
        # past it (from 4 cm short, 3 cm past: fc21 of 2026-11-28 under load, the heel
        # caught the edge on its way down, the foot was put back)
        walk("go_straight", [0.36])
        walk("step_down", [0.05, 0.33])
    say("DONE")


#: go_straight before each pair of footsteps: up from station ``ramp`` (to the ramp's foot,
#: then up the slope to its top), down from ``ramp_top`` (to the landing's edge, then down
#: the slope to its foot) -- walkman/courses.py's ramp courses.
RAMP_LEGS = {"up": (0.20, 0.36), "down": (0.08, 0.22)}


def ramp(way: str) -> None:
    """The ramp course by clicks (issue 32), ``up`` or ``down``: start walking, to the
    slope's edge, two footsteps dragged in the 3-D view onto the 10-degree slope and pitched
    like it (turned on the marker's pitch ring), along the slope, two more onto the level
    ground at its end.  Where each footstep goes the test reads on the ramp's surface in the
    world -- what the perception pilot shows -- and says ``footsteps X Y Z ROLL PITCH YAW
    ...``."""
    walking = start_walking()
    say("STEP walking started")
    listen()
    for leg, distance in enumerate(RAMP_LEGS[way], 1):
        walk("go_straight", [distance])
        say(f"STEP footsteps wanted for leg {leg}")
        values = [float(word) for word in said("footsteps", 120).split()]
        place_footsteps(walking, [values[i:i + 6] for i in range(0, len(values), 6)])
        pump(1.0)
        window.screenshot(OUT / f"ramp-{way}-footsteps-{leg}.png")
        walk("footsteps")
    say("DONE")


def place_footsteps(walking, poses: Sequence[Sequence[float]]) -> None:
    """Clear the footsteps, add one per pose and drag each onto its pose in the 3-D view."""
    click(walking.clear_button, "clear footsteps", walking)
    for _ in poses:
        click(walking.add_button, "add footstep", walking)
    names = walking.ordered()
    if len(names) != len(poses) or not set(names) <= set(window.view3d.markers):
        fail(f"footsteps {walking.footsteps}, markers {list(window.view3d.markers)}")
    for name, pose in zip(names, poses):
        def followed(name=name, pose=pose) -> bool:
            return all(abs(a - b) < 1e-3 for a, b in zip(walking.footsteps[name], pose))
        drag(name, pose[:3], pose[5], followed, name, roll=pose[3], pitch=pose[4])
    say(f"STEP footsteps placed {[[round(v, 3) for v in walking.footsteps[n]] for n in names]}")


#: The cloud :func:`finer_ground` asks for: 80 x 30 points of the picture's lower half.
FINER_POINTS = 80 * 30


def finer_ground(finer: bool = True) -> None:
    """The cloud the DRC link carries is 40 x 30 points: rows 6 cm apart on the kerb, too
    coarse to place a sole by.  The pilot asks perception for twice the resolution, and only
    the picture's lower half (the ground ahead): 80 x 30 points, rows 3 cm apart, on the
    link's budget -- and (``finer=False``) for the usual picture again before walking: a
    640 x 480 render costs the robot's CPU four times a 320 x 240 one."""
    camera = widget("perception")
    wait(lambda: camera.state == "streaming", 60, "perception streaming")
    wait_sendable("perception")
    asks = ((("set_resolution", (640, 480)), ("set_region", (0, 240, 640, 240))) if finer
            else (("set_resolution", (320, 240)),))
    for command, numbers in asks:
        camera.command_box.setCurrentText(command)
        pump(0.1)
        for field, value in zip(camera.number_fields, numbers):
            field.setValue(value)
        click(camera.send_button, f"perception {command} {numbers}", camera)
        wait(lambda: f"{numbers[-2]}x{numbers[-1]}" in camera.status_label.text() or
             f"{numbers[-2]} {numbers[-1]}" in camera.status_label.text(), 30,
             f"perception says {command} {numbers}")


def perception(pause: bool) -> None:
    """Pause (or resume) perception from its widget, as a pilot does while the robot walks:
    a camera render costs the robot PC's CPU what its walking loop needs."""
    camera = widget("perception")
    wait(lambda: camera.state == ("streaming" if pause else "paused"), 60,
         f"perception {'streaming' if pause else 'paused'}")
    wait_sendable("perception")
    verb = "pause" if pause else "resume"
    click(camera.switch_buttons[verb], f"perception {verb}", camera)
    wait(lambda: camera.state == ("paused" if pause else "streaming"), 20,
         f"perception {verb}d")
    say(f"STEP perception {verb}d")


def look_down(gaze) -> None:
    """gaze_control aims the camera at the ground 1.25 m ahead: the neck bends nearly all
    the way (0.985 rad), and the camera sees from 0.2-0.4 m ahead of the toes."""
    for field, value in zip(gaze.fields["look_at"], (1.25, 0.0, -1.0)):
        field.setValue(value)
    click(gaze.buttons["look_at"], "look_at 1.25 0 -1 (the ground ahead)", gaze)
    wait(lambda: gaze.state == "tracking", 30, "gaze_control looking at the ground")


def footsteps_from_the_camera(distance: float, refusal_expected: bool = False) -> Any:
    """Click walking's "footsteps from the camera" for ``distance`` m, on a cloud taken after
    the head and the feet came to rest (saved beside the screenshots, for a look at why):
    the widget.  A refusal fails, unless expected."""
    walking = widget("walking")
    # clouds rendered before perception took the finer ground's settings are still on their
    # way over the slow link (one arrived 1.3 s after it was taken, 40 x 30 points: its
    # coarse rows refused the ground as sloping 5 degrees); then one taken while the head
    # may still have been moving, and a new one
    for _ in range(2):
        seen = window.cloud.stamp_ns if window.cloud is not None else 0
        wait(lambda: window.cloud is not None and window.cloud.stamp_ns > seen and
             window.cloud.points == FINER_POINTS, 30,
             f"a new cloud of {FINER_POINTS} points from the head camera")
    walking.camera_distance.setValue(distance)
    np.savez(OUT / f"camera-leg-{distance}.npz", xyz=window.cloud.xyz,
             posture=np.asarray(window.preview.posture, float))
    click(walking.camera_button, f"footsteps from the camera ({distance} m)",
          None if refusal_expected else walking)
    return walking


def camera_leg(distance: float) -> None:
    """Footsteps from the camera (walking's widget), then sent: the leg to where the feet
    next stand together."""
    walking = footsteps_from_the_camera(distance)
    if not walking.footsteps:
        fail("no footsteps from the camera, and no word why")
    placed = [[round(v, 3) for v in walking.footsteps[name][:3]] for name in walking.ordered()]
    say(f"STEP footsteps from the camera {distance}: {placed}")
    perception(pause=True)      # its renders and the cloud's sending off the walking loop's CPU
    walk("footsteps")
    perception(pause=False)


def debris() -> None:
    """Footsteps from the camera refused (issue 32): at station ``debris`` a 4-cm block lies
    in the right foot's lane.  The pilot starts walking, bends the head down, asks for the
    finer ground and clicks: no footstep is placed, walking's warnings say which footstep
    and why, and nothing is sent."""
    start_walking()
    look_down(start_gaze())
    finer_ground()
    walking = footsteps_from_the_camera(0.6, refusal_expected=True)

    def shown() -> List[str]:
        return [walking.warnings.item(k).text() for k in range(walking.warnings.count())]

    def refusal() -> str:
        """walking's warning why (a warning the robot sent since may stand above it)."""
        return next((text for text in shown() if "no footsteps from the camera" in text), "")

    try:
        wait(lambda: walking.footsteps or refusal(), 10,
             "walking's warning why the camera's footsteps were refused")
    finally:
        say("WARNINGS " + " | ".join(shown()))
    placed = [name for name in window.view3d.markers if name.startswith("footstep")]
    if walking.footsteps or placed:
        fail(f"footsteps placed although refused: {walking.footsteps} {placed}")
    say(f"STEP refused: {refusal()}")
    screenshot_of("terrain-camera-refused.png", walking)
    finer_ground(False)
    say("DONE")


def scene_follows() -> None:
    """The other pilot's drag of the valve, through both gateways: our 3-D view has the
    valve (drawn as a valve, no task widget of ours owns it) where they put it."""
    markers = window.view3d.markers
    wait(lambda: "drc_valve" in markers and abs(markers["drc_valve"].pose[0] - 0.61) < 1e-3,
         60, "the other pilot's valve in the shared scene")
    shown = time.time()
    wait(window.view3d.applied(), 90, "the render process to draw the valve")
    window.raise_()                           # the other PI's window is on the same display
    window.activateWindow()
    pump(1.0)                                 # librviz draws at 15 Hz
    window.screenshot(OUT / f"{window.name}-scene.png")
    say(f"STEP scene: drc_valve {markers['drc_valve'].kind} at "
        f"{[round(v, 3) for v in markers['drc_valve'].pose]} shown at {shown:.3f}")


def cloud_connected(uri: str) -> bool:
    """That node takes the cloud from its publisher of now (a link to a dead one stays
    listed while roscpp retries it): its slave API's bus info against the master."""
    from xmlrpc.client import ServerProxy

    import rosgraph
    from pilot.link import CLOUD_TOPIC

    master = rosgraph.Master("/driver")
    publishers = next((nodes for topic, nodes in master.getSystemState()[0]
                       if topic == CLOUD_TOPIC), [])
    uris = {master.lookupNode(node) for node in publishers}
    try:
        connections = ServerProxy(uri).getBusInfo("/driver")[2]
    except OSError:      # that render process died (librviz's own crash): not connected
        return False
    return any(c[2] == "i" and c[4] == CLOUD_TOPIC and c[1] in uris for c in connections)


def peer() -> None:
    other, x = sys.argv[3], float(sys.argv[4])
    listen()
    gaze = start_gaze()
    # every pilot's commands reach our log from here (fc3: the PI counted its subscription
    # a second before the loaded gateway took it, and both look_ats went out meanwhile)
    wait(window.link.hears_every_pilot, 30, "the gateway's record of every pilot's commands")
    say("STEP ready")
    wait_word("go", 120)
    send_look_at(gaze, x)
    def others_look_at() -> str:
        return next((line for line in window.log.toPlainText().splitlines()
                     if other in line and "look_at" in line), "")

    end = time.monotonic() + 30
    while not others_look_at() and time.monotonic() < end:
        pump(0.05)
    if not others_look_at():
        shown = window.log.toPlainText().splitlines()
        fail(f"timed out (30 s) waiting for {other}'s look_at in the log; its last "
             f"{min(len(shown), 15)} of {len(shown)} lines:\n    " + "\n    ".join(shown[-15:]))
    line = others_look_at()
    say(f"STEP saw {line}")
    if window.view3d is None:
        say("DONE")
        return
    if not window.module_widgets.get("drc_valve"):
        scene_follows()                     # a PI without the valve's task: it sees the scene
        say("DONE")
        return
    drag_marker()
    # librviz's roscpp node lives in the 3-D view's render process, which says its name
    wait(lambda: window.view3d.ros_nodes, 30, "the 3-D view's librviz node")
    librviz = dict(window.view3d.ros_nodes)
    if len(librviz) != 1:
        fail(f"expected one librviz roscpp node in the 3-D view's process, found {librviz}")
    say("STEP waiting for the restarts")
    wait_word("restarted", 300)
    restarted = time.monotonic()
    wait(lambda: gaze.heard_at is not None and gaze.heard_at > restarted, 60,
         "gaze_control's status after the restarts")
    # librviz (roscpp) takes the cloud from the restarted bridge: registered again for it --
    # the render process's own, or a new one's if librviz crashed meanwhile (the PI lives on).
    wait(lambda: any(cloud_connected(uri) for uri in window.view3d.ros_nodes.values()), 60,
         "librviz's subscription to the restarted bridge's cloud")
    say("STEP librviz connected to the restarted bridge")
    wait_sendable("gaze_control")           # the gateway subscribes again on the new roscore
    send_look_at(gaze, x + 0.1)
    say("STEP sent after the restarts")
    pump(8.0)                               # librviz's new frame, the robot's TF
    with_all, without_robot = view_pixels(), view_pixels("Robot")
    say(f"PIXELS after restarts all {with_all} without_robot {without_robot}")
    if with_all - without_robot < 300:
        fail(f"after the restarts the robot draws {with_all - without_robot} pixels")
    window.screenshot(OUT / f"{window.name}-after-restarts.png")
    say("DONE")


def latency() -> None:
    count = int(sys.argv[3])
    gaze = start_gaze()
    x_field, y_field, z_field = gaze.fields["look_at"]
    for index in range(count):
        x, y = 1.0 + 0.001 * (index % 400), 0.2 + 0.001 * (index // 400)
        x_field.setValue(x)
        y_field.setValue(y)
        z_field.setValue(0.1)
        pump(0.25)
        # Greyed out while the module's status is late (over 10 s on a lossy link): a click
        # then sends nothing, and counting it would blame the link for it.
        wait(lambda: gaze.buttons["look_at"].isEnabled(), 60, "look_at enabled")
        at = time.time()
        QTest.mouseClick(gaze.buttons["look_at"], Qt.LeftButton)
        say(f"CLICKED {index} {at:.6f} look_at {x:.3f} {y:.3f}")
    say("DONE")


def listen() -> None:
    """Read the test's words from stdin (once, whichever phases ask)."""
    global LISTENING
    if not LISTENING:
        LISTENING = True
        threading.Thread(target=read_stdin, daemon=True).start()


LISTENING = False


def ghost_drawn() -> bool:
    """The 3-D view (if the layout has one) draws the preview's ghost."""
    return window.view3d is not None and bool(window.view3d.displays.get("Preview"))


class TaskRun:
    """One task module driven by its buttons: the pose (the fields' values), then the
    module's ``TASK_STEPS``; each step timed from its click to the widget showing the state
    it ends in (a timed one through its countdown and the motion it starts).  Every status
    the widget shows is printed ``SHOWN time state stamp`` (``stamp``: the gateway's
    receipt)."""

    def __init__(self, module: str) -> None:
        from importlib import import_module

        from walkman.gym.runner import load_module_class

        self.module = module
        self.task = widget(module)
        self.dangerous = load_module_class(module).dangerous
        pose = next(name for name in self.task.buttons if name.endswith("datasent"))
        self.steps = [(pose, "ready")] + [
            (command.split()[0], state)
            for command, state in import_module(f"walkman.modules.{module}").TASK_STEPS]
        self.seen: List = []                      # (when shown, state), every status
        shown = self.task.on_status               # the window routes statuses by this name

        def on_status(event) -> None:
            shown(event)
            self.seen.append((time.time(), event.state))
            say(f"SHOWN {self.seen[-1][0]:.6f} {event.state} {event.stamp:.6f}")

        self.task.on_status = on_status

    def reached(self, state: str, before: str, after: float):
        """When ``state`` was shown after ``after`` -- past a state other than ``before``
        first when the step ends where it began (the valve's turn: grasped to grasped)."""
        later = [(when, said) for when, said in self.seen if when >= after]
        if state == before:
            moved = next((i for i, (_, said) in enumerate(later) if said != before), None)
            later = [] if moved is None else later[moved:]
        return next((when for when, said in later if said == state), None)

    def start(self) -> None:
        """The module's status seen, the PI heard by the gateway, the module started."""
        module, task = self.module, self.task
        wait(lambda: task.state is not None, 60, f"{module}'s status")
        wait_sendable(module)
        if task.state != "idle":
            click(task.switch_buttons["start"], f"{module} start", task)
            wait(lambda: task.state == "idle", 60, f"{module} idle")

    def step(self, run: int, command: str, state: str) -> None:
        task = self.task
        button = task.buttons[command]
        wait(button.isEnabled, 60, f"{command} enabled")
        before, at = task.state, time.time()
        ghosts = window.ghosts_shown
        click(button, f"{self.module} {command}", task)
        # A dangerous command that moves an arm is worked out on this PC as it is clicked,
        # and its ghost shown in the 3-D view while it counts down (pilot/preview.py).
        previewed = window.ghosts_shown == ghosts + 1
        if previewed:
            say(f"STEP preview of {command} shown, worked out in "
                f"{window.preview.last_ms:.1f} ms")
            if ghost_drawn():
                pump(1.0)                                # librviz draws at 15 Hz
                window.screenshot(OUT / f"{self.module}-preview-{command}.png")
        since = at
        if command in self.dangerous:             # the motion starts after the countdown
            # A state other than the one clicked in: the motion's, or already its end.
            # (Not "its end state shown": for a step that ends where it began -- the
            # valve's turn, grasped to grasped -- the 2 Hz status of the state it counts
            # down in is that, and the next() below found no change: StopIteration.)
            wait(lambda: any(when >= at and said != before for when, said in self.seen), 60,
                 f"{command} started after its countdown")
            since = next(when for when, said in self.seen if when >= at and said != before)
        wait(lambda: self.reached(state, before, since) is not None, 180,
             f"{self.module} {state} after {command}")
        if previewed and (window.ghost is not None or ghost_drawn()):
            fail(f"the ghost of {command} is still shown after its countdown")
        say(f"TIMED {run} {command} {state} {at:.6f} {self.reached(state, before, since):.6f}")

    def run(self, run: int = 0,
            after: Optional[Dict[str, Callable[["TaskRun"], None]]] = None) -> None:
        """Every step once; ``after[command](self)`` is called once that step is done."""
        for command, state in self.steps:
            self.step(run, command, state)
            if after and command in after:
                after[command](self)
        say(f"RUN {run} done")


def task_runs(module: str, count: int) -> None:
    """A task COUNT times by its buttons (:class:`TaskRun`); after each run but the last
    it waits for the test to say ``next`` (the bench reads the scene)."""
    listen()
    task = TaskRun(module)
    task.start()
    for run in range(count):
        task.run(run)
        if run + 1 < count:
            wait_word("next", 300)
    say("DONE")


def steer_by_slider(run: TaskRun, degrees: int) -> None:
    """drc_drive's steering slider (Figure 14) set and ``steer`` clicked: the wheel turns
    from where the module measures it to the slider's angle, and is measured there; then
    the test, told so, reads the wheel in the world and says ``looked``."""
    drive = run.task
    wait(lambda: drive.measured is not None, 30, "the wheel's measured angle")
    drive.slider.setValue(degrees)
    at = time.time()
    click(drive.steer_button, f"steer to {degrees:+d} degrees", drive)
    wait(lambda: run.reached("drive", "drive", at) is not None, 120,
         "drc_drive turning the wheel, then driving again")
    wait(lambda: abs(math.degrees(drive.measured) - degrees) < 5, 10,
         f"the wheel measured within 5 degrees of {degrees:+d}")
    say(f"STEP steered by the slider to {degrees:+d} degrees, measured "
        f"{math.degrees(drive.measured):+.1f}")
    wait_word("looked", 120)              # the test reads the wheel in the world meanwhile


#: What the pilot does beside a task's steps, after the step named (module -> command -> do).
BESIDE_STEPS: Dict[str, Dict[str, Callable[[TaskRun], None]]] = {
    "drc_drive": {"turn_right": lambda run: steer_by_slider(run, 25)},
}


def tasks_in_turn(modules: Sequence[str]) -> None:
    """``tasks MODULE...``: the README's "every DRC task in one session": each task once by
    its buttons, after the test said ``go MODULE`` (the robot taken to its station), the
    module stopped, then ``TASK MODULE done``."""
    listen()
    for module in modules:
        wait_word(f"go {module}", 300)
        task = TaskRun(module)
        task.start()
        task.run(after=BESIDE_STEPS.get(module))
        screenshot_of(f"{module}-done.png", task.task)   # and the robot in the 3-D view
        # "stop when done, then the next station": its joints are the next task's
        click(task.task.switch_buttons["stop"], f"{module} stop", task.task)
        wait(lambda: task.task.state == "stopped", 60, f"{module} stopped")
        say(f"TASK {module} done")
    say("DONE")


def unsupported(module: str) -> None:
    """``unsupported MODULE``: a task with the harness off, as the paper's robot did it --
    walking started and paused (it balances the legs, standing, and stays so), then the
    task by its buttons (:class:`TaskRun`)."""
    walking = start_walking()
    click(walking.switch_buttons["pause"], "walking pause", walking)
    wait(lambda: walking.state == "paused", 30, "walking paused")
    say("STEP walking balancing, paused")
    listen()
    task = TaskRun(module)
    task.start()
    # the robot crouched where walking left it: the pilot places the object where the 3-D
    # view shows it from there (the test reads it in the world and says ``pose ...``)
    pose = task.steps[0][0]
    values = [float(word) for word in said("pose", 120).split()]
    for field, value in zip(task.task.fields[pose], values):
        field.setValue(value)
    say(f"STEP {pose} set to {values}")
    task.run()
    say(f"STEP {module} done standing unsupported")
    say("DONE")


def said(word: str, timeout: float) -> str:
    """Pump the GUI until the test writes a line starting with ``word``; the rest of it."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        QApplication.processEvents()
        try:
            line = STDIN.get(timeout=0.02)
        except queue.Empty:
            continue
        if line.split()[:1] == [word]:
            return line[len(word):].strip()
    fail(f"the test never said {word!r}")
    return ""


def screenshot_of(name: str, *shown) -> None:
    """The window once it has drawn what it shows now, scrolled to the widgets ``shown``
    (their status lines: a layout's column is often wider and taller than the window)."""
    from python_qt_binding.QtWidgets import QScrollArea

    for index in range(window.tabs.count()):       # the tab that holds them, on screen
        if window.tabs.widget(index).isAncestorOf(shown[0]):
            window.tabs.setCurrentIndex(index)
    area = shown[0].parentWidget()
    while area is not None and not isinstance(area, QScrollArea):
        area = area.parentWidget()
    if area is not None:
        for each in shown:
            area.ensureWidgetVisible(each.status_label)
        area.horizontalScrollBar().setValue(0)
    pump(0.3)
    window.screenshot(OUT / name)


#: How old the cut is when every tab is read: what is shown then must be at least as old.
READ_CUT_AT_S = 6.0


def every_tab_during_a_cut() -> None:
    """Each tab on screen in turn (a screenshot each: ``link-down-TITLE.png``), then a
    ``TEXT where | text`` line for every line of the window that shows what the robot sent:
    the Status tab's banner and each module's "heard", the camera's caption, the 3-D view's
    banner, the link's summary and every module widget's line ("(hidden)" when hidden)."""
    for index in range(window.tabs.count()):
        window.tabs.setCurrentIndex(index)
        pump(0.6)                   # the window's timer (0.5 s) ticks every widget once
        window.screenshot(OUT / f"link-down-{window.tabs.tabText(index).lower()}.png")
    texts = []

    def shown(where: str, label) -> None:
        texts.append((where, label.text() + (" (hidden)" if label.isHidden() else "")))

    if window.status is not None:
        shown("status banner", window.status.link_banner)
        for module, row in window.status.rows.items():
            texts.append((f"status state {module}", window.status.table.item(row, 1).text()))
            texts.append((f"status heard {module}", window.status.table.item(row, 2).text()))
    if window.camera is not None:
        shown("camera caption", window.camera.caption)
    if window.view3d is not None:
        shown("3-D view banner", window.view3d.link_banner)
    if window.link_widget is not None:
        shown("link summary", window.link_widget.summary)
    for widgets in window.module_widgets.values():
        for each in widgets:
            shown(each.objectName(), each.status_label)
    for where, text in texts:
        say(f"TEXT {where} | {text}")


def link_down() -> None:
    """``link VICTIM OTHER``, for tests/system/test_pilot_link_down.py: start both modules
    by clicks; after the test says ``killed`` (VICTIM kill -9'd, link up) VICTIM's widget
    reads "not running" while OTHER's never stops showing its state; after ``cut TIME``
    (the link's blackout began at wall time TIME) print ``LINKDOWN module seconds text``
    when each module widget first shows "link down" (the label polled every 10 ms), and
    ``GATEWAY module seconds`` when the gateway said so; no widget says "not running",
    neither module's start is enabled; once the cut is :data:`READ_CUT_AT_S` old, every
    tab's text (:func:`every_tab_during_a_cut`); after ``restored`` OTHER shows its state
    again and VICTIM "not running".  Screenshots: module-dead, link-down, a link-down one per
    tab, link-back."""
    from pilot.widgets.generic import ABSENT_S
    from walkman.gym.lifecycle import State, lifecycle_of_status

    names = sys.argv[3:5]
    listen()
    victim, other = (widget(name) for name in names)
    for name, shown in zip(names, (victim, other)):
        wait(lambda: shown.presence == "running", 60, f"{name}'s status")
        wait_sendable(name)
        if lifecycle_of_status(shown.state) != State.RUNNING:
            click(shown.switch_buttons["start"], f"{name} start", shown)
        wait(lambda: lifecycle_of_status(shown.state) == State.RUNNING, 60, f"{name} running")
    say(f"STEP both running: {victim.status_label.text()!r}, {other.status_label.text()!r}")
    said("killed", 120)

    def victim_dead() -> bool:
        # A late status greys OTHER (stale); "not running" or "link down" would be a lie.
        if other.presence not in ("running", "stale"):
            fail(f"{names[1]} reads {other.status_label.text()!r} ({other.presence}) while "
                 f"only {names[0]} died")
        return victim.status_label.text().startswith("not running")

    wait(victim_dead, ABSENT_S + 30, f"{names[0]}'s widget to say not running")
    screenshot_of("module-dead.png", victim, other)
    say(f"STEP {names[0]} dead: {victim.status_label.text()!r}; {names[1]} "
        f"{other.presence}: {other.status_label.text()!r}")

    cut = float(said("cut", 120))
    every = [w for widgets in window.module_widgets.values() for w in widgets]
    shown_at = {}
    end = time.monotonic() + 30
    while len(shown_at) < len(every):
        QApplication.processEvents()
        for w in every:
            if w not in shown_at and w.status_label.text().startswith("link down for"):
                shown_at[w] = time.time()
        if time.monotonic() > end:
            fail(f"after 30 s: {[w.status_label.text() for w in every if w not in shown_at]}")
        time.sleep(0.01)
    screenshot_of("link-down.png", victim, other)
    for name, shown in zip(names, (victim, other)):
        gateway = time.time() - (time.monotonic() - shown.link_down_at)
        say(f"GATEWAY {name} {gateway - cut:.3f}")
        say(f"LINKDOWN {name} {shown_at[shown] - cut:.3f} {shown.status_label.text()}")
        if shown.switch_buttons["start"].isEnabled():
            fail(f"{name}'s start is enabled while the link is down (it would be queued)")
    dead = [w.status_label.text() for w in every if "not running" in w.status_label.text()]
    if dead:
        fail(f"widgets say not running while only the link is down: {dead}")
    say("STEP link down shown")
    pump(max(0.0, READ_CUT_AT_S - (time.time() - cut)))
    began = time.time() - cut
    every_tab_during_a_cut()
    say(f"STEP every tab read, {began:.1f} s into the cut")

    said("restored", 120)
    wait(lambda: other.presence == "running" and
         not other.status_label.text().startswith("link down"), 60,
         f"{names[1]}'s state after the link's return")
    wait(lambda: victim.status_label.text().startswith("not running"), 30,
         f"{names[0]} not running after the link's return")
    screenshot_of("link-back.png", victim, other)
    say(f"STEP link back: {victim.status_label.text()!r}, {other.status_label.text()!r}")
    say("DONE")


if __name__ == "__main__":
    app = QApplication(sys.argv[:1])
    modules = configured_modules(MODELS_DIR / "bridge_drc.xml")
    layout = load_layout(os.environ.get("PI_LAYOUT", "main-pilot"), modules=list(modules),
                         path=Path(os.environ.get("PI_LAYOUTS", DEFAULT_LAYOUTS)))
    window = PilotWindow(layout, modules, os.environ.get("PI_NAME", f"pi_test_{sys.argv[1]}"))
    window.show()
    window.start()
    wait(lambda: window.ros_up, 60, "the PI's ROS node")
    say(f"UP after {window.ready_after:.2f} s")
    {"first": first, "second": second, "latency": latency, "peer": peer,
     "camera": camera,
     "terrain": lambda: terrain(sys.argv[3:] == ["camera"]), "debris": debris,
     "ramp": lambda: ramp(sys.argv[3]),
     "valve": lambda: task_runs("drc_valve", int(sys.argv[3])),
     "task": lambda: task_runs(sys.argv[3], int(sys.argv[4])),
     "tasks": lambda: tasks_in_turn(sys.argv[3:]),
     "unsupported": lambda: unsupported(sys.argv[3]),
     "link": link_down}[sys.argv[1]]()
    window.close_link()
