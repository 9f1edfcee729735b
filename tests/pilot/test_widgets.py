"""The Pilot Interface's widgets fed events directly (Qt offscreen, no ROS).

What each widget shows for what it is told: lifecycle buttons and command
refusals of the Generic Widget, the timed button's countdown, the camera's
hatching of lost tiles, the link widget's figures, the status tab.
"""

from __future__ import annotations

import math
import re
import time
from typing import List, Tuple

import numpy as np
import pytest

pytestmark = pytest.mark.requires("xvfb")


@pytest.fixture(scope="module")
def qt():
    """Qt's offscreen platform, asked on its command line: QT_QPA_PLATFORM in os.environ
    would reach the PIs the GUI tests start later in this process, and librviz cannot draw
    offscreen (it aborted them)."""
    from python_qt_binding.QtWidgets import QApplication

    app = QApplication.instance() or QApplication(["test_widgets", "-platform", "offscreen"])
    return app


class Recorder:
    """Stands in for the window: what the widgets send (the PI's own ROS link aside)."""

    def __init__(self, problem: str = "") -> None:
        self.sent: List[Tuple] = []
        self.problem = problem

    def command(self, module, name, numbers=(), dangerous=False) -> str:
        self.sent.append((module, name, list(numbers), dangerous))
        return self.problem

    def switch(self, module, word) -> str:
        self.sent.append((module, word))
        return self.problem


def status(module: str, state: str, age: float = 0.0):
    from pilot.link import StatusEvent

    return StatusEvent(module, state, "", (), 7, time.time() - age)


def enabled(buttons) -> List[str]:
    return [name for name, button in buttons.items() if button.isEnabled()]


def warnings(widget) -> List[str]:
    return [widget.warnings.item(i).text() for i in range(widget.warnings.count())]


def test_the_generic_widget_enables_what_the_lifecycle_allows_and_greys_a_stale_module(qt):
    from pilot.catalogue import catalogue_of
    from pilot.widgets.generic import ABSENT_S, STALE_S, GenericWidget

    widget = GenericWidget(catalogue_of("temperature"), Recorder())
    assert widget.presence == "absent" and widget.status_label.text() == \
        "not launched on the robot (walkman-module temperature starts it)"
    assert enabled(widget.switch_buttons) == []     # nobody launched it: nothing to start
    assert widget.body.isHidden()                   # nor any button shown that cannot work
    widget.on_status(status("temperature", "ready"))
    assert widget.presence == "running" and not widget.body.isHidden()
    assert enabled(widget.switch_buttons) == ["pause", "stop", "quit"]
    widget.on_status(status("temperature", "paused"))
    assert enabled(widget.switch_buttons) == ["resume", "stop", "quit"]
    widget.on_status(status("temperature", "ready", age=STALE_S + 1))
    assert widget.presence == "stale" and "#909090" in widget.status_label.styleSheet()
    widget.on_status(status("temperature", "ready", age=ABSENT_S + 1))
    widget.tick()
    assert widget.status_label.text() == "not running (last: ready)"
    assert enabled(widget.switch_buttons) == []


def test_a_silent_module_behind_a_broken_link_reads_link_down_not_dead(qt):
    from pilot.catalogue import catalogue_of
    from pilot.link import LinkEvent
    from pilot.widgets.generic import ABSENT_S, LINK_DOWN_COLOUR, GenericWidget

    widget = GenericWidget(catalogue_of("gaze_control"), Recorder())
    widget.on_status(status("gaze_control", "tracking", age=ABSENT_S + 2))
    widget.on_link(LinkEvent("down", "the robot's bridge silent for 1.6 s", 12.2, 0))
    assert widget.presence == "link_down"
    assert widget.status_label.text() == "link down for 12 s; module last heard tracking"
    assert LINK_DOWN_COLOUR in widget.led.styleSheet()
    # The buttons the last known state allows: a start would queue behind a running module.
    assert enabled(widget.switch_buttons) == ["pause", "stop", "quit"]
    widget.on_link(LinkEvent("up", "", 0.0, 0))
    assert widget.presence == "stale"        # its age counts again from the link's return
    widget.on_status(status("gaze_control", "tracking"))
    assert widget.presence == "running"
    # A module silent while the link is up is not running: that is not the link's fault.
    widget.on_status(status("gaze_control", "tracking", age=ABSENT_S + 1))
    widget.tick()
    assert widget.status_label.text() == "not running (last: tracking)"


def test_the_link_down_shows_at_once_and_a_module_silent_before_the_cut_stays_silent(qt):
    """Issue 33: the widget shows the link down as soon as it is told, not once the
    module's last status is stale (3 s later: the PI said "tracking" in green for seconds
    after the cut); a module already silent when the link went says so, and reads "not
    running" again as soon as the link is back (not "ready" in grey for 7 s)."""
    from pilot.catalogue import catalogue_of
    from pilot.link import LinkEvent
    from pilot.widgets.generic import ABSENT_S, LINK_DOWN_COLOUR, GenericWidget

    live = GenericWidget(catalogue_of("gaze_control"), Recorder())
    dead = GenericWidget(catalogue_of("temperature"), Recorder())
    live.on_status(status("gaze_control", "tracking", age=0.2))
    dead.on_status(status("temperature", "ready", age=ABSENT_S + 5))
    dead.tick()
    assert dead.status_label.text() == "not running (last: ready)"
    for widget in (live, dead):
        widget.on_link(LinkEvent("down", "the robot's bridge silent for 1.6 s", 0.0, 0))
        assert widget.presence == "link_down"
        assert LINK_DOWN_COLOUR in widget.status_label.styleSheet()
        assert "start" not in enabled(widget.switch_buttons)   # nothing invites a queued start
    assert re.fullmatch(r"link down for 0\.\d s; module last heard tracking",
                        live.status_label.text()), live.status_label.text()
    assert re.fullmatch(r"link down for 0\.\d s; module silent since before the cut "
                        r"\(last: ready\)", dead.status_label.text()), dead.status_label.text()
    for widget in (live, dead):
        widget.on_link(LinkEvent("up", "", 0.0, 0))
    assert live.presence == "running" and live.status_label.text() == "tracking"
    assert dead.presence == "absent" and dead.status_label.text() == "not running (last: ready)"


def test_queued_commands_are_listed_with_a_cancel_and_their_end_is_told(qt):
    from pilot.catalogue import catalogue_of
    from pilot.link import CommandStateEvent
    from pilot.widgets.generic import GenericWidget

    recorder = Recorder()
    recorder.cancel = lambda module, seq=0: recorder.sent.append((module, "cancel", seq)) or ""
    widget = GenericWidget(catalogue_of("gaze_control"), recorder)
    state = lambda seq, text, word, why="": CommandStateEvent(  # noqa: E731
        "gaze_control", "command", seq, text, "me", 1, word, why, time.time())
    assert widget.cancel_button.isHidden() and widget.queued_label.text() == ""
    widget.on_command_state(state(42, "look_at 1.0 0.4 0.1", "queued"))
    widget.on_command_state(state(43, "home", "queued"))
    widget.on_command_state(CommandStateEvent("other", "command", 7, "x", "", 0, "queued",
                                              "", 0.0))           # another module's: not here
    assert widget.queued_label.text() == "queued for the link: `look_at 1.0 0.4 0.1`, `home`"
    widget.cancel_button.click()
    assert recorder.sent == [("gaze_control", "cancel", 0)]
    widget.on_command_state(state(42, "look_at 1.0 0.4 0.1", "cancelled", "by a pilot"))
    widget.on_command_state(state(43, "home", "delivered"))
    widget.on_command_state(state(43, "home", "expired", "too old"))
    assert widget.cancel_button.isHidden()
    assert warnings(widget)[0].endswith("`home` expired: too old")
    widget.on_command_state(state(44, "look_at 0 0 1", "accepted"))
    widget.on_command_state(state(44, "look_at 0 0 1", "interrupted", "its process died"))
    assert warnings(widget)[0].endswith("`look_at 0 0 1` interrupted: its process died")


def test_the_log_says_when_the_link_goes_and_comes_back(qt):
    from pilot.link import CommandStateEvent, LinkEvent
    from pilot.widgets.log import LogView

    log = LogView("me")
    for word in ("sent", "queued", "delivered", "expired"):
        log.on_command_state(CommandStateEvent("drc_valve", "command", 42, "turn 1.57",
                                               "pi_2", 2, word, "too old" * (word == "expired"),
                                               time.time()))
    log.on_link(LinkEvent("up", "", 5.0, 0))
    log.on_link(LinkEvent("down", "the robot's bridge silent for 1.6 s", 0.5, 0))
    log.on_link(LinkEvent("down", "the robot's bridge silent for 1.6 s", 3.0, 1))
    log.on_link(LinkEvent("up", "", 0.0, 0))
    text = log.toPlainText()
    assert "LINK DOWN (the robot's bridge silent for 1.6 s)" in text
    assert "1 command(s) wait for it" in text and text.rstrip().endswith("link up again")
    assert "/drc_valve/command `turn 1.57` queued (from pi_2)" in text
    assert "/drc_valve/command `turn 1.57` expired: too old (from pi_2)" in text
    assert "delivered" not in text and " sent" not in text   # what a pilot must know, only


def test_a_command_the_state_refuses_is_not_sent_and_the_reason_is_shown_in_red(qt):
    from pilot.catalogue import catalogue_of
    from pilot.widgets.tasks import TaskWidget

    sender = Recorder()
    valve = TaskWidget(catalogue_of("drc_valve"), sender)
    valve.on_status(status("drc_valve", "idle"))
    assert enabled(valve.buttons) == ["valvedatasent"]
    assert not valve.send("turn", [1.0])
    assert sender.sent == []
    assert "not sent: turn is not accepted in state idle (now: valvedatasent)" in warnings(valve)[0]
    assert valve.warnings.item(0).foreground().color().name() == "#d00000"
    assert not valve.send("valvedatasent", [1.0, 2.0])
    assert "takes 7 numbers" in warnings(valve)[0]
    valve.on_status(status("drc_valve", "grasped"))
    valve.buttons["turn"].click()
    assert sender.sent == [("drc_valve", "turn", [pytest.approx(np.pi / 2, abs=1e-3)], True)]
    # The link's own refusal (not connected yet) is shown too.
    refusing = TaskWidget(catalogue_of("drc_valve"), Recorder("the PI is not connected"))
    refusing.on_status(status("drc_valve", "idle"))
    refusing.buttons["valvedatasent"].click()
    assert warnings(refusing)[0].endswith("not sent: the PI is not connected")


@pytest.mark.parametrize("module", ["drc_valve", "drc_drive", "drc_door", "drc_plug",
                                    "drc_wall"])
def test_a_task_widget_sends_the_pilots_estimate_of_the_whole_pose(qt, module):
    """Every field of a pose command starts at the pilots' estimate of the scene: the drive
    widget's pedal fields (optional in the command) started at 0 and sent the pedal to the
    pelvis, and the module refused the wheel (found by bench_valve_topologies --task
    drc_drive)."""
    from pilot.catalogue import catalogue_of
    from pilot.widgets.tasks import TaskWidget, pose_command
    from walkman.model.mjcf import PILOT_POSES

    sender = Recorder()
    widget = TaskWidget(catalogue_of(module), sender)
    widget.on_status(status(module, "idle"))
    command = next(name for name in widget.buttons if pose_command(name))
    widget.buttons[command].click()
    estimate = next(pose.split() for pose in PILOT_POSES.values() if pose.startswith(command))
    assert sender.sent == [(module, command, [pytest.approx(float(v), abs=5e-4)   # 3 decimals
                                              for v in estimate[1:]],
                            False)]
    assert len(estimate) - 1 == catalogue_of(module).commands[command].most


def test_a_task_widgets_numbers_start_at_the_modules_own_defaults(qt):
    """The door widget's fields said turn 0.6 and open 0.5 where drc_door takes 0.9 and 0.7
    when told nothing: clicked through with them, the door opened 28 degrees, short of the
    30 the module's own test asks (the PI's one-session test of 2026-11-28).  The module's
    defaults now fill the fields; the widget's table only has what no module knows."""
    from pilot.catalogue import catalogue_of
    from pilot.widgets.tasks import TaskWidget

    door = TaskWidget(catalogue_of("drc_door"), Recorder())
    assert door.numbers("turn") == [pytest.approx(0.9)]
    assert door.numbers("open") == [pytest.approx(0.7)]
    drive = TaskWidget(catalogue_of("drc_drive"), Recorder())
    assert drive.numbers("turn_left") == drive.numbers("turn_right") == [pytest.approx(0.5)]
    assert drive.numbers("accelerate") == [pytest.approx(1.0), pytest.approx(1.0)]
    # A number without a default (how high the kerb is) is the pilot's: from the table.
    assert catalogue_of("walking").commands["step_up"].defaults == ()
    walking = TaskWidget(catalogue_of("walking"), Recorder())
    assert walking.numbers("step_up") == [pytest.approx(0.05), pytest.approx(0.33)]


def test_the_timed_button_shows_the_gateways_countdown_and_stays_clickable_to_cancel(qt):
    from pilot.catalogue import catalogue_of
    from pilot.link import CountdownEvent
    from pilot.widgets.tasks import TaskWidget

    valve = TaskWidget(catalogue_of("drc_valve"), Recorder())
    valve.on_status(status("drc_valve", "grasped"))
    turn = valve.buttons["turn"]
    valve.on_countdown(CountdownEvent("drc_valve", "(turn 1.57)", 2.4, "waiting", "pi_a"))
    assert turn.waiting and turn.text() == "turn  2.4 s - click to cancel"
    valve.on_status(status("drc_valve", "turning"))   # turn is not legal now: still cancellable
    assert turn.isEnabled()
    valve.on_countdown(CountdownEvent("drc_valve", "(turn 1.57)", 1.1, "cancelled", "pi_a"))
    assert not turn.waiting and turn.text() == "turn (cancelled)" and not turn.isEnabled()


def red_pixels(view) -> int:
    """Hatching drawn in the camera view: reddish pixels of the picture as shown (scaled
    smoothly, so near the hatch colour rather than exactly it)."""
    image = view.picture.pixmap().toImage()
    colours = [image.pixelColor(x, y) for x in range(0, image.width(), 2)
               for y in range(0, image.height(), 2)]
    return sum(1 for c in colours if c.red() > 140 and c.green() < 90 and c.blue() < 90)


def test_the_camera_hatches_exactly_the_tiles_the_bridge_reports_lost(qt, tmp_path):
    from pilot.link import CLOUD_TOPIC, IMAGE_TOPIC, ArrivalEvent, CloudEvent, ImageEvent
    from pilot.widgets.camera import MISSING_COLOUR, CameraView, marked

    rgb = np.full((48, 64, 3), 90, np.uint8)
    rgb[0:16] = 0                                       # a black sky: content, not loss
    rgb[8:24, 16:40] = 0                                # and the lost tile, filled black
    view = CameraView()
    view.resize(400, 320)
    lost = ArrivalEvent(IMAGE_TOPIC, 5, 48, 64, 1 - 16 * 24 / (48 * 64), ((16, 8, 24, 16),))
    view.on_arrival(lost)                               # the report before its frame
    view.on_image(ImageEvent(rgb, 5))
    assert view.frames == 1 and not view.picture.pixmap().isNull()
    caption = view.caption.text()
    assert caption.startswith("frame 1 | image 87% arrived") and "cloud" not in caption
    assert "red: tiles that did not arrive" in caption
    view.grab().save(str(tmp_path / "camera-lost-tile.png"))
    assert red_pixels(view) > 50
    shown = marked(rgb, np.pad(np.ones((16, 24), bool), ((8, 24), (16, 24))))
    hatched = (shown == MISSING_COLOUR).all(axis=2)
    assert hatched[8:24, 16:40].mean() > 0.25 and hatched.sum() == hatched[8:24, 16:40].sum()
    # The cloud's report after its cloud: the caption follows.
    view.on_cloud(CloudEvent(4800, 9))
    assert "cloud 100% of points" in view.caption.text()
    view.on_arrival(ArrivalEvent(CLOUD_TOPIC, 9, 60, 80, 0.75, ((0, 0, 40, 60),)))
    assert "cloud 75% of points" in view.caption.text()
    # The next frame came whole (its report says so) and the one after without any report.
    view.on_image(ImageEvent(rgb, 6))
    view.on_arrival(ArrivalEvent(IMAGE_TOPIC, 6, 48, 64, 1.0, ()))
    assert "image 100% arrived" in view.caption.text() and red_pixels(view) == 0
    view.on_image(ImageEvent(rgb, 7))
    assert "image 100% arrived" in view.caption.text() and "red" not in view.caption.text()
    # A report that comes after its frame hatches it then; one for another frame does not.
    view.on_arrival(ArrivalEvent(IMAGE_TOPIC, 5, 48, 64, 0.5, ((0, 0, 32, 48),)))
    assert "image 100% arrived" in view.caption.text() and red_pixels(view) == 0
    view.on_arrival(ArrivalEvent(IMAGE_TOPIC, 7, 48, 64, 0.5, ((0, 0, 32, 48),)))
    assert "image 50% arrived" in view.caption.text() and red_pixels(view) > 50


def test_in_the_lab_a_black_image_and_a_cloud_without_depth_are_whole(qt, tmp_path):
    """No bridge, no report: what the pilot PC's roscore carries is all there was."""
    from sensor_msgs.msg import Image, PointCloud2

    from pilot.link import PilotLink
    from pilot.widgets.camera import CameraView

    view = CameraView()
    view.resize(400, 320)
    link = PilotLink("pi_test", [], post=lambda event: getattr(
        view, {"ImageEvent": "on_image", "CloudEvent": "on_cloud"}[type(event).__name__])(event))
    image = Image(height=240, width=320, encoding="rgb8", step=960, data=bytes(240 * 960))
    cloud = PointCloud2(height=60, width=80, point_step=16, row_step=1280,
                        data=np.full(60 * 80 * 4, np.nan, np.float32).tobytes())
    for msg in (image, cloud):
        msg.header.stamp.secs = 1700000000
        link._on_image(msg) if msg is image else link._on_cloud(msg)
    assert view.caption.text() == "frame 1 | image 100% arrived | cloud 100% of points"
    view.grab().save(str(tmp_path / "camera-lab-black.png"))
    assert red_pixels(view) == 0


def test_a_share_is_rounded_down_so_100_percent_means_all():
    from pilot.widgets.camera import percent

    assert [percent(x) for x in (1.0, 0.9999, np.float32(0.7), 0.0)] == \
        ["100%", "99%", "70%", "0%"]


def test_the_link_widget_shows_the_bridge_status_and_bit_rates_per_id(qt):
    from pilot.link import BridgeEvent, LinkEvent
    from pilot.widgets import link as link_widget

    from bridge import config as bridge_config
    from walkman import MODELS_DIR

    names = bridge_config.load(MODELS_DIR / "bridge_drc.xml").id_names()
    assert names[2] == "drc_valve" and names[20] == "walkman state" and \
        names[31] == "/multisense/points" and names[250] == "stop all"
    widget = link_widget.LinkWidget({3: "counter", 20: "walkman state"})
    assert widget.summary.text().startswith("no bridge: the lab topology has none")
    first = {"link": "up", "link_since_s": 12, "round_trip_ms": 41.5, "queued_commands": 0,
             "refused": 1, "dropped": {"stale": 2},
             "tcp": {"bytes_by_id": {"3": 1000, "17": 50}},
             "udp": {"flows": {"/multisense/points": {"mean_completeness": 0.93}}}}
    second = dict(first, tcp={"bytes_by_id": {"3": 1600, "17": 50, "20": 125}})
    widget.on_bridge(BridgeEvent(first, 100.0))
    assert widget.summary.text().startswith("link state not yet heard (/bridge/link) | "
                                            "no round trip yet | queued commands 0")
    widget.on_link(LinkEvent("up", "", 30.0, 0))
    assert widget.summary.text().startswith("link up for 30 s | round trip 41.5 ms")
    assert "#10a010" in widget.summary.styleSheet()
    # Up or down is /bridge/link's, as every other widget reads it; the bridge's own channel
    # phase ("up" here, as it says until its TCP channel gives up) is not read.
    widget.on_link(LinkEvent("down", "no frame for 2 s", 12.0, 0))
    widget.on_bridge(BridgeEvent(second, 102.0))
    text = widget.summary.text()
    assert text.startswith("link down for 12 s | no round trip while down"), text
    assert "refused 1 | dropped 2 (stale 2)" in text
    assert "#d00000" in widget.summary.styleSheet()
    rows = {widget.rates.item(r, 0).text(): (widget.rates.item(r, 1).text(),
                                              widget.rates.item(r, 2).text())
            for r in range(widget.rates.rowCount())}
    assert rows == {"3": ("counter", "2,400"), "17": ("", "0"), "20": ("walkman state", "500")}
    assert widget.flows.text() == "perception: /multisense/points 93% complete"
    widget.heard -= link_widget.SILENT_S + 1
    widget.tick()
    assert "the bridge is silent" in widget.summary.text()


def test_the_status_tab_shows_module_states_temperatures_and_torques(qt):
    from pilot.link import JointsEvent, StatusEvent, TemperaturesEvent
    from pilot.widgets.status import StatusTab

    tab = StatusTab(["drc_valve", "walking"])
    tab.on_status(status("walking", "walking"))
    tab.tick()
    assert tab.table.item(1, 1).text() == "walking"
    assert tab.table.item(0, 1).text() == "not running" and tab.table.item(0, 2).text() == "never"
    assert tab.table.item(1, 2).text().endswith("s ago")
    names = ("LHipSag", "RKneeSag")
    tab.on_temperatures(TemperaturesEvent(names, np.array([41.0, 75.0]), time.time()))
    tab.on_joints(JointsEvent(names, np.zeros(2), np.array([12.0, -80.0]), time.time()))
    assert list(tab.temperatures.values) == [41.0, 75.0]
    assert list(tab.torques.values) == [12.0, -80.0]
    # Drawn: a blue bar for the cool joint, a red one for the one over HOT_C.
    image = tab.temperatures.grab().toImage()
    colours = {image.pixelColor(x, y).name() for x in range(0, image.width(), 2)
               for y in range(0, image.height(), 2)}
    assert {"#40a0e0", "#d03030"} <= colours
    # Read at a glance: the peak is named, each bar is a joint, the state has its numbers.
    assert tab.temperatures.peak() == (75.0, "RKneeSag")
    assert tab.torques.peak() == (80.0, "RKneeSag")
    plot = tab.temperatures
    assert [plot.joint_at(plot.AXIS_W + (i + 0.5) * plot._bar_width()) for i in range(2)] == \
        [0, 1]
    assert plot.joint_at(plot.AXIS_W - 1) is None
    tab.on_status(StatusEvent("drc_valve", "idle", "0.66 0.25 0.08", (0.66, 0.25, 0.08), 4,
                              time.time()))
    assert tab.table.item(0, 1).text() == "idle  valve at (0.66, 0.25, 0.08) m"


def wheel(widget, notches: int) -> bool:
    """Turn the mouse wheel over ``widget``'s middle as Qt delivers it; True if it took it."""
    from python_qt_binding.QtCore import QPoint, QPointF, Qt
    from python_qt_binding.QtGui import QWheelEvent
    from python_qt_binding.QtWidgets import QApplication

    middle = QPointF(widget.width() / 2, widget.height() / 2)
    event = QWheelEvent(middle, QPointF(widget.mapToGlobal(middle.toPoint())), QPoint(0, 0),
                        QPoint(0, -120 * notches), Qt.NoButton, Qt.NoModifier,
                        Qt.NoScrollPhase, False)
    QApplication.sendEvent(widget, event)
    return event.isAccepted()


def test_scrolling_over_a_tab_changes_no_field_the_pilot_did_not_choose(qt):
    """Issue 32: the mouse wheel over a pose field scrolled it (drc_drive's roll to -1.35)
    instead of the page.  A field takes the wheel only once clicked or tabbed into."""
    from python_qt_binding.QtTest import QTest
    from python_qt_binding.QtCore import Qt
    from python_qt_binding.QtWidgets import QScrollArea

    from pilot.catalogue import catalogue_of
    from pilot.widgets.tasks import DriveWidget

    widget = DriveWidget(catalogue_of("drc_drive"), Recorder())
    widget.on_status(status("drc_drive", "idle"))          # launched: its fields are shown
    area = QScrollArea()
    area.setWidget(widget)
    area.resize(360, 160)                                  # smaller than the widget: it scrolls
    area.show()
    area.activateWindow()
    qt.processEvents()
    fields = [field for fields in widget.fields.values() for field in fields]
    # (the steering slider, as the generic row's command box was before the task widget
    # hid that row: a wheel-hungry widget that Qt gives the focus first)
    combo = widget.slider
    combo.setFocus(Qt.ActiveWindowFocusReason)    # as Qt gives the first widget of a window
    qt.processEvents()
    assert combo.hasFocus() and not combo.chosen
    before = [field.value() for field in fields]
    for field in fields:
        area.ensureWidgetVisible(field)
        qt.processEvents()
        assert not wheel(field, 3), f"{field.objectName()} took the wheel while not chosen"
    assert not wheel(combo, 2)
    assert [field.value() for field in fields] == before
    assert combo.value() == 0
    # What a field ignores, Qt hands to its parents (for a real wheel; a sent event stops at
    # its receiver, so here the page gets it directly): the page scrolls.
    bar = area.verticalScrollBar()
    bar.setValue(0)
    assert wheel(area.viewport(), 1) and bar.value() > 0
    # A field the pilot chose takes the wheel, as before.
    chosen = fields[0]
    area.ensureWidgetVisible(chosen)
    QTest.mouseClick(chosen, Qt.LeftButton)
    qt.processEvents()
    assert chosen.hasFocus() and chosen.chosen
    assert wheel(chosen, 1)
    assert chosen.value() != before[0]
    area.close()


def test_a_status_reads_with_names_and_units_not_raw_numbers(qt):
    """Issue 32: "tracking 0.36208946309668233 0.8348273937608888" and "monitoring 26 300
    27 300" told a pilot nothing; each module's class says what its numbers are."""
    from pilot.catalogue import catalogue_of
    from pilot.link import StatusEvent
    from pilot.widgets.generic import GenericWidget
    from walkman.modules.temperature import joint_names

    def shown(module: str, state: str, *values) -> str:
        widget = GenericWidget(catalogue_of(module), Recorder())
        data = " ".join(str(v) for v in values)
        widget.on_status(StatusEvent(module, state, data, tuple(map(float, values)), 3,
                                     time.time()))
        return widget.status_label.text()

    assert shown("gaze_control", "tracking", 0.36208946309668233, 0.8348273937608888) == \
        "tracking  neck yaw 0.36 rad, pitch 0.83 rad"
    assert shown("gaze_control", "unreachable", 3.0, -1.0, 0.5) == \
        "unreachable  target (3.00, -1.00, 0.50) m"
    names = joint_names()
    assert shown("temperature", "monitoring", 26, 300, 27, 315) == \
        f"monitoring  {names[26]} 30.0 C, {names[27]} 31.5 C"
    assert shown("drc_valve", "idle", 0.66, 0.25, 0.08) == "idle  valve at (0.66, 0.25, 0.08) m"
    assert shown("walking", "idle", 0.45, 0, 0, 0.121, 0.002) == (
        "idle  walked 0.45 m ahead, 0.00 m left, turned 0\u00b0; ZMP 12.1 cm inside the feet, "
        "torso 0.1\u00b0 off vertical")
    assert "no foot on the floor" in shown("walking", "walking", 0.1, 0, 0, math.nan, 0.01)
    # Numbers of another shape than declared are shown as they came, never dropped.
    assert shown("temperature", "monitoring", 26, 300, 99) == "monitoring  26 300 99"
    assert shown("gaze_control", "tracking", 0.5) == "tracking  0.5"


def test_the_drive_widget_steers_to_the_sliders_angle_from_the_measured_one(qt):
    """Issue 32, Fig. 14: a steering slider; ``steer`` sends the turn that takes the wheel
    from the angle the robot measures (the module's status) to the slider's."""
    import math

    from python_qt_binding.QtCore import Qt
    from python_qt_binding.QtTest import QTest

    from pilot.catalogue import catalogue_of
    from pilot.link import StatusEvent
    from pilot.widgets.tasks import DriveWidget, task_widget_class

    assert task_widget_class("drc_drive") is DriveWidget
    sent = Recorder()
    widget = DriveWidget(catalogue_of("drc_drive"), sent)
    assert not widget.steer_button.isEnabled()              # not driving yet
    assert not widget.steer()                               # and nothing measured
    assert sent.sent == [] and "not known yet" in warnings(widget)[0]

    def drive_status(measured: float) -> None:
        values = (0.55, 0.1, 0.03, 0.2, measured)
        widget.on_status(StatusEvent("drc_drive", "drive", " ".join(map(str, values)), values,
                                     9, time.time()))

    drive_status(0.0)
    assert widget.steer_button.isEnabled()
    assert widget.measured_label.text() == "measured: +0\u00b0"
    widget.slider.setValue(30)
    QTest.mouseClick(widget.steer_button, Qt.LeftButton)
    module, name, numbers, dangerous = sent.sent[-1]
    assert (module, name, dangerous) == ("drc_drive", "turn_left", False)
    assert numbers[0] == pytest.approx(math.radians(30))
    drive_status(0.6)                                        # the wheel went further
    widget.slider.setValue(-30)
    assert widget.steer()
    assert sent.sent[-1][1:3] == ("turn_right", [pytest.approx(0.6 + math.radians(30))])
    # The throttle: accelerate's time and amount, counted down as a dangerous command.
    assert [f.objectName() for f in widget.fields["accelerate"]] == \
        ["accelerate_SECONDS", "accelerate_AMOUNT"]
    assert [f.value() for f in widget.fields["accelerate"]] == [1.0, 1.0]


class Scene(Recorder):
    """The window's side of footsteps: where the soles are, and the scene edits it tells."""

    def __init__(self, soles=None) -> None:
        super().__init__()
        self.placed: List[Tuple] = []
        self._soles = soles

    def soles(self):
        return self._soles

    def place(self, name, kind, pose, removed=False) -> str:
        self.placed.append((name, kind, [round(v, 3) for v in pose], removed))
        return ""


def test_the_walking_widget_places_footsteps_and_sends_them_in_order(qt):
    """Issue 32, rough ground: footsteps a pilot places in the shared scene (the first a bit
    ahead of the left sole, then a stride per foot), dragged by any pilot, sent in their
    order as a pose (X Y Z ROLL PITCH YAW) of each sole in the pelvis frame."""
    from python_qt_binding.QtCore import Qt
    from python_qt_binding.QtTest import QTest

    from pilot.catalogue import catalogue_of
    from pilot.widgets.tasks import WalkingWidget, task_widget_class

    assert task_widget_class("walking") is WalkingWidget
    window = Scene()
    widget = WalkingWidget(catalogue_of("walking"), window, advanced=lambda: True)
    assert "footsteps" in widget.buttons and widget.fields["footsteps"] == []  # no 40 fields
    assert [f.value() for f in widget.fields["step_up"]] == [0.05, 0.33]
    QTest.mouseClick(widget.add_button, Qt.LeftButton)       # no joint state yet
    assert window.placed == [] and "not known yet" in warnings(widget)[0]
    assert not widget.do("footsteps") and "no footsteps placed" in warnings(widget)[0]
    window._soles = {"left": (0.0, 0.11, -1.03, 0.0, 0.0, 0.0),
                     "right": (0.0, -0.11, -1.03, 0.0, 0.0, 0.0)}
    for _ in range(3):
        QTest.mouseClick(widget.add_button, Qt.LeftButton)
    assert window.placed == [
        ("footstep_1", "footstep", [0.15, 0.11, -1.03, 0.0, 0.0, 0.0], False),
        ("footstep_2", "footstep", [0.30, -0.11, -1.03, 0.0, 0.0, 0.0], False),
        ("footstep_3", "footstep", [0.45, 0.11, -1.03, 0.0, 0.0, 0.0], False)]
    assert widget.footsteps_label.text() == "3 footsteps placed"
    # another pilot drags the second one up a 5-cm step; a tenth comes after the ninth
    widget.footstep_moved("footstep_2", [0.33, -0.11, -0.98, 0.0, 0.0, 0.1])
    widget.footstep_moved("footstep_10", [0.5, -0.11, -0.98, 0.0, 0.0, 0.0])
    widget.footstep_moved("footstep_9", [0.5, 0.11, -0.98, 0.0, 0.0, 0.0])
    assert widget.ordered() == ["footstep_1", "footstep_2", "footstep_3", "footstep_9",
                                "footstep_10"]
    widget.footstep_moved("footstep_9", None)                 # removed by its pilot
    widget.footstep_moved("footstep_10", None)
    assert widget.do("footsteps")
    module, name, numbers, dangerous = window.sent[-1]
    assert (module, name, dangerous) == ("walking", "footsteps", True)
    assert numbers == pytest.approx([0.15, 0.11, -1.03, 0, 0, 0, 0.33, -0.11, -0.98, 0, 0, 0.1,
                                     0.45, 0.11, -1.03, 0, 0, 0])
    QTest.mouseClick(widget.clear_button, Qt.LeftButton)
    assert [p[0] for p in window.placed[-3:]] == ["footstep_1", "footstep_2", "footstep_3"]
    assert all(p[3] for p in window.placed[-3:]) and widget.footsteps == {}
    assert widget.footsteps_label.text() == "0 footsteps placed"


def test_footsteps_from_the_camera_replace_the_placed_ones_to_the_next_edge(qt):
    """Issue 32, footsteps from the perception cloud: the window places them on what the
    camera sees (walkman.control.ground_ahead); the widget puts the leg to where the feet
    next stand together into the shared scene, the ones placed before cleared."""
    from python_qt_binding.QtCore import Qt
    from python_qt_binding.QtTest import QTest

    from pilot.catalogue import catalogue_of
    from pilot.widgets.tasks import WalkingWidget

    window = Scene()
    asked: List[float] = []
    plan: List[tuple] = [(0.18, 0.11, -1.03, 0, 0, 0), (0.18, -0.11, -1.03, 0, 0, 0),
                         (0.48, 0.11, -0.98, 0, 0, 0), (0.48, -0.11, -0.98, 0, 0, 0)]
    answer = ([], "no footsteps from the camera: an edge 12 cm up 0.30 m ahead")
    window.footsteps_from_camera = lambda distance: asked.append(distance) or answer
    widget = WalkingWidget(catalogue_of("walking"), window, advanced=lambda: True)
    widget.footstep_moved("footstep_1", [0.15, 0.11, -1.03, 0.0, 0.0, 0.0])  # by hand
    widget.camera_distance.setValue(0.8)
    QTest.mouseClick(widget.camera_button, Qt.LeftButton)
    assert asked == [0.8] and "an edge 12 cm up" in warnings(widget)[0]
    assert list(widget.footsteps) == ["footstep_1"]            # refused: nothing changed
    answer = (plan, "")
    QTest.mouseClick(widget.camera_button, Qt.LeftButton)
    assert window.placed[0] == ("footstep_1", "footstep", [0.15, 0.11, -1.03, 0, 0, 0], True)
    assert window.placed[1:] == [("footstep_1", "footstep", [0.18, 0.11, -1.03, 0, 0, 0], False),
                                 ("footstep_2", "footstep", [0.18, -0.11, -1.03, 0, 0, 0], False)]
    assert widget.footsteps_label.text() == "2 footsteps placed"   # to the edge, not over
    answer = ([(0.1 * k, 0.11 * (-1) ** k, -1.03, 0, 0, 0) for k in range(1, 14)]
              + [(1.3, 0.11, -1.03, 0, 0, 0)], "")
    QTest.mouseClick(widget.camera_button, Qt.LeftButton)
    assert widget.footsteps_label.text() == "10 footsteps placed"
    assert "14 footsteps to the next edge or the goal: the first 10 placed" in warnings(widget)[0]


def test_a_command_s_number_field_takes_pixels_not_only_a_hundred(qt):
    """perception's ``set_resolution 640 480`` from its Generic Widget: the fields held
    -100..100 and sent ``set_resolution 100 100`` without a word (2026-11-28)."""
    from pilot.catalogue import catalogue_of
    from pilot.widgets.generic import GenericWidget

    recorder = Recorder()
    widget = GenericWidget(catalogue_of("perception"), recorder, advanced=lambda: True)
    widget.command_box.setCurrentText("set_resolution")
    for field, value in zip(widget.number_fields, (640, 480)):
        field.setValue(value)
    widget.send_button.click()
    assert recorder.sent[-1][:3] == ("perception", "set_resolution", [640.0, 480.0])


def test_the_generic_entry_of_a_repeated_group_holds_one_group():
    """``footsteps`` takes 6 to 60 numbers, a pose per sole: the Generic Widget's entry has
    six fields (one footstep), not sixty."""
    from pilot.catalogue import catalogue_of

    spec = catalogue_of("walking").commands["footsteps"]
    assert spec.fields == ["X", "Y", "Z", "ROLL", "PITCH", "YAW"]
    assert spec.check([0.1] * 6) is None and "takes 6 to 60 numbers" in spec.check([0.1] * 3)


def test_the_battery_bar_and_the_log_say_the_charge_and_each_level_once(qt):
    """Figure 15's battery bar: green, orange under 20 %, red under 10 %; the log says each
    level the charge falls under once."""
    from pilot.link import BatteryEvent
    from pilot.widgets.log import LogView
    from pilot.widgets.status import StatusTab

    tab = StatusTab(["temperature"])
    assert tab.battery.text() == "battery: no reading yet"
    log = LogView("pi_test")
    colours = []
    for percent in (64.0, 21.0, 19.5, 19.0, 9.0, 8.5, 4.0):
        event = BatteryEvent(percent, 46.0, 12.5, time.time())
        tab.on_battery(event)
        log.on_battery(event)
        colours.append(tab.battery.colour())
    assert tab.battery.text() == "battery 4 %   46.0 V   12.5 A"
    assert colours == ["#30a040", "#30a040", "#e0a020", "#e0a020", "#d03030", "#d03030",
                       "#d03030"]
    said = [line for line in log.toPlainText().splitlines() if "BATTERY" in line]
    assert [line.split("BATTERY ")[1].split(":")[0] for line in said] == \
        ["below 20 %", "below 10 %", "below 5 %"]
    image = tab.battery.grab().toImage()
    assert image.pixelColor(3, image.height() // 2).name() == "#d03030"   # the bar is drawn
    assert image.pixelColor(image.width() - 3, image.height() // 2).name() == "#20242c"


def test_the_history_line_stays_in_its_own_strip_after_a_past_peak(qt):
    """A torque peak gone from the bars still draws inside the history strip, not over them."""
    from python_qt_binding.QtGui import QColor

    from pilot.widgets.status import JointPlot

    plot = JointPlot("torques", "N\u00b7m", None)
    plot.resize(400, 360)
    names = ("LHipSag", "RKneeSag")
    for value in (5.0, 300.0, 5.0, 5.0):              # a peak, then small torques again
        plot.update_values(names, np.array([value, 1.0]))
        plot.history[-1] = (plot.history[-1][0] + len(plot.history), plot.history[-1][1])
    image = plot.grab().toImage()
    strip_top = int(plot._bars_bottom() + plot.NAMES_H + 18)
    yellow = [(x, y) for x in range(image.width()) for y in range(image.height())
              if image.pixelColor(x, y).red() > 200 and image.pixelColor(x, y).green() > 150
              and image.pixelColor(x, y).blue() < 120]
    assert yellow and all(y >= strip_top - 2 for _, y in yellow), min(y for _, y in yellow)


def test_the_window_opens_whole_on_a_laptop_screen(qt):
    """Issue 32: the PI opened at 1400x900 on a 1366x768 screen, its right and bottom cut off."""
    from python_qt_binding.QtCore import QRect

    from pilot.app import window_size

    assert window_size(QRect(0, 0, 1366, 740)) == (1366, 740)     # a laptop, minus its panel
    assert window_size(QRect(0, 0, 1920, 1050)) == (1400, 900)


def test_the_status_tab_lists_every_modules_warnings_with_filters(qt):
    """Fig. 15 (A): the warnings of every module, newest first, filtered by module and words."""
    from pilot.link import WarningEvent
    from pilot.widgets.status import StatusTab

    tab = StatusTab(["temperature", "drc_valve"])
    for module, text in (("temperature", "LKneeSag at 71.0 C (limit 70 C)"),
                         ("drc_valve", "not sent: turn is not legal in idle"),
                         ("temperature", "RKneeSag at 72.5 C (limit 70 C)")):
        tab.on_warning(WarningEvent(module, text, time.time()))
    lines = [tab.warnings.list.item(i).text() for i in range(tab.warnings.list.count())]
    assert [line.split("  ", 1)[1] for line in lines] == [
        "/temperature  RKneeSag at 72.5 C (limit 70 C)",
        "/drc_valve  not sent: turn is not legal in idle",
        "/temperature  LKneeSag at 71.0 C (limit 70 C)"]
    tab.warnings.module_filter.setCurrentText("drc_valve")
    assert [w.text for w in tab.warnings.shown()] == ["not sent: turn is not legal in idle"]
    assert tab.warnings.list.count() == 1
    tab.warnings.module_filter.setCurrentText("all modules")
    tab.warnings.text_filter.setText("lknee")
    assert [w.text for w in tab.warnings.shown()] == ["LKneeSag at 71.0 C (limit 70 C)"]


def test_the_body_views_colour_each_joint_where_it_is_on_the_robot(qt):
    """Fig. 15 (B): two figures of the robot, each joint coloured by its temperature/torque."""
    from pilot.widgets.status import StatusTab, body_layout
    from pilot.link import TemperaturesEvent
    from walkman.modules.temperature import joint_names

    places, bones = body_layout()
    names = joint_names()
    assert set(places) == set(names) and len(bones) >= len(names) - 6
    assert places["NeckYawj"][1] > places["WaistLat"][1] > places["LAnkSag"][1]   # head up
    assert places["LShSag"][0] > 0 > places["RShSag"][0]                         # left is +y
    tab = StatusTab(["temperature"])
    body = tab.temperature_body
    body.resize(300, 320)
    celsius = np.full(len(names), 35.0)
    celsius[names.index("RKneeSag")] = 75.0
    tab.on_temperatures(TemperaturesEvent(tuple(names), celsius, time.time()))
    image = body.grab().toImage()                      # (the layout may size it first)
    knee = body._points()["RKneeSag"]
    assert body.joint_at(knee.x(), knee.y()) == "RKneeSag"
    hot = image.pixelColor(int(knee.x()), int(knee.y()))
    cool = image.pixelColor(*map(int, (body._points()["LKneeSag"].x(),
                                       body._points()["LKneeSag"].y())))
    assert hot.red() > 200 and hot.blue() < 80          # the hot knee is red
    assert cool.blue() > 200 and cool.red() < 80        # the others are blue


def test_during_a_cut_the_status_tab_and_the_camera_say_how_old_what_they_show_is(qt):
    """Issue 66: a 20 s cut showed "initializing, 17.3 s ago", live-looking charts and
    "frame 46 | image 73% arrived" with no word of the link.  Each now says the link is
    down, for how long, and how old what it shows is; and nothing of it once the link is
    back."""
    from pilot.link import ImageEvent, JointsEvent, LinkEvent, TemperaturesEvent
    from pilot.link_cut import LinkCut
    from pilot.widgets.camera import CameraView
    from pilot.widgets.status import StatusTab

    class Clock:
        now = 1000.0

        def __call__(self) -> float:
            return self.now

    clock = Clock()
    tab, view = StatusTab(["drc_valve", "walking"]), CameraView()
    tab.cut, view.cut = LinkCut(clock), LinkCut(clock)
    tab.on_status(status("drc_valve", "initializing"))
    names = ("LHipSag",)
    tab.on_temperatures(TemperaturesEvent(names, np.array([41.0]), time.time()))
    tab.on_joints(JointsEvent(names, np.zeros(1), np.array([12.0]), time.time()))
    view.on_image(ImageEvent(np.zeros((24, 32, 3), np.uint8), 5))
    tab.charts_at = view.last_frame = clock.now - 3.0      # the robot's last, 3 s before now
    tab.tick()
    assert not tab.link_banner.isVisible() and "link" not in view.caption.text()
    assert "link" not in tab.table.item(0, 2).text()

    for widget in (tab, view):
        widget.on_link(LinkEvent("down", "no frame for 2 s", 18.0, 0))
    assert tab.link_banner.text() == \
        "link down for 18 s: the states, charts and battery below as of 3.0 s ago"
    assert not tab.link_banner.isHidden()
    assert tab.table.item(0, 2).text().endswith("(link down 18 s)")
    assert tab.table.item(1, 1).text() == "unknown: never heard, link down"   # not "not running"
    assert view.caption.text().startswith("link down for 18 s: frame 1 as of 3.0 s ago"), \
        view.caption.text()
    clock.now += 60                                        # a minute later, still down
    tab.tick()
    view.tick()
    assert tab.link_banner.text().startswith("link down for 78 s:") and \
        tab.link_banner.text().endswith("as of 63 s ago")
    assert view.caption.text().startswith("link down for 78 s: frame 1 as of 63 s ago")

    for widget in (tab, view):
        widget.on_link(LinkEvent("up", "", 0.5, 0))
    assert tab.link_banner.isHidden() and tab.link_banner.text() == ""
    assert tab.table.item(1, 1).text() == "not running"
    assert view.caption.text().startswith("frame 1")


def test_during_a_cut_the_3d_view_says_how_old_its_robot_and_cloud_are(qt):
    """Issue 66: librviz draws the last robot pose and cloud as if they were now.  While the
    link is down a banner above the view says so, each with its own age; not before, and not
    once the link is back.  (No render process: the banner is the PI's, not librviz's.)"""
    from pilot.link import CloudEvent, JointsEvent, LinkEvent
    from pilot.link_cut import LinkCut
    from pilot.widgets.view3d import View3D

    class Clock:
        now = 500.0

        def __call__(self) -> float:
            return self.now

    clock = Clock()
    view = View3D("pi_test")
    view.cut = LinkCut(clock)
    view.on_link(LinkEvent("down", "no frame for 2 s", 4.0, 0))
    assert view.link_banner.text() == ("link down for 4.0 s: the robot: nothing received yet, "
                                       "the cloud: nothing received yet")
    view.on_link(LinkEvent("up", "", 0.5, 0))
    view.on_joints(JointsEvent(("LHipSag",), np.zeros(1), np.zeros(1), time.time()))
    clock.now += 2.0
    view.on_cloud(CloudEvent(1200, 7))
    view.tick()
    assert view.link_banner.isHidden() and view.link_banner.text() == ""

    clock.now += 1.0
    view.on_link(LinkEvent("down", "no frame for 2 s", 18.0, 0))
    assert view.link_banner.text() == \
        "link down for 18 s: the robot as of 3.0 s ago, the cloud as of 1.0 s ago"
    assert not view.link_banner.isHidden()
    clock.now += 60
    view.tick()
    assert view.link_banner.text() == \
        "link down for 78 s: the robot as of 63 s ago, the cloud as of 61 s ago"
    view.on_link(LinkEvent("up", "", 0.5, 0))
    assert view.link_banner.isHidden() and view.link_banner.text() == ""


@pytest.mark.parametrize("module", ["drc_valve", "drc_door", "drc_drive", "drc_plug", "drc_wall",
                                    "walking", "gaze_control"])
def test_a_task_widget_shows_each_command_once_with_the_scenes_values(qt, module):
    """Issue 66: the valve's own row (x 0.660 ...) sat above the generic row for the same
    command, all zeros, and either could be sent.  One command, one row: the task's."""
    from python_qt_binding.QtWidgets import QDoubleSpinBox, QPushButton

    from pilot.catalogue import catalogue_of
    from pilot.widgets.tasks import STARTING_VALUES, TaskWidget, task_widget_class

    widget = task_widget_class(module)(catalogue_of(module), Recorder())
    assert isinstance(widget, TaskWidget)
    widget.on_status(status(module, "idle"))
    widget.resize(900, 1200)
    widget.show()
    qt.processEvents()
    shown = [b.text() for b in widget.findChildren(QPushButton) if b.isVisibleTo(widget)]
    for name in widget.catalogue.commands:
        assert shown.count(name) == 1, (name, shown)
    assert not any(b.text().startswith("send") for b in widget.findChildren(QPushButton)
                   if b.isVisibleTo(widget)), "the generic row's send is still shown"
    assert not widget.command_entry.isVisibleTo(widget)
    shown_fields = [f for f in widget.findChildren(QDoubleSpinBox) if f.isVisibleTo(widget)]
    for fields in widget.fields.values():
        assert all(f in shown_fields for f in fields)
    for name, values in STARTING_VALUES[module].items():
        assert [f.value() for f in widget.fields[name]][:len(values)] == \
            pytest.approx(values, abs=1e-3), name
    widget.close()
