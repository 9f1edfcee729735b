"""nodekit.link_watch: the pilot bridge's status reduced to what a pilot must read."""

from __future__ import annotations

from nodekit.link_watch import BRIDGE_QUIET, DIRECT, DOWN, SILENT_DOWN, UNKNOWN, UP, LinkWatch


def status(link: str = "up", silent: float = 0.2, queued: int = 0, rtt: float = 40.0) -> dict:
    return {"link": link, "silent_s": silent, "queued_commands": queued, "round_trip_ms": rtt}


def test_the_lab_is_direct_whatever_comes():
    watch = LinkWatch(direct=True, now=0.0)
    assert watch.state.state == DIRECT
    assert watch.on_status(status("down"), 1.0) is None
    assert watch.tick(100.0) is None and watch.state.state == DIRECT


def test_unknown_until_the_bridge_speaks_then_up():
    watch = LinkWatch(direct=False, now=0.0)
    assert watch.state.state == UNKNOWN
    assert watch.tick(60.0) is None          # no bridge ever heard: still unknown, not down
    changed = watch.on_status(status(), 61.0)
    assert changed.state == UP and changed.since == 61.0 and changed.round_trip_ms == 40.0
    assert watch.on_status(status(rtt=55.0), 61.5) is None   # nothing a pilot must see
    assert watch.state.round_trip_ms == 55.0


def test_a_silent_robot_bridge_is_a_link_down_long_before_the_channel_drops():
    watch = LinkWatch(direct=False, now=0.0)
    watch.on_status(status(), 1.0)
    assert watch.on_status(status(silent=SILENT_DOWN - 0.1), 2.0) is None
    down = watch.on_status(status(silent=SILENT_DOWN + 0.1, queued=1), 2.5)
    assert down.state == DOWN and "silent for 1.6 s" in down.reason and down.queued == 1
    more = watch.on_status(status(link="down", queued=2), 4.0)   # still down: queue grew
    assert more.state == DOWN and more.queued == 2 and more.since == 2.5
    assert watch.on_status(status(), 9.0).state == UP


def test_a_pilot_bridge_gone_quiet_is_a_link_down():
    watch = LinkWatch(direct=False, now=0.0)
    watch.on_status(status(), 1.0)
    assert watch.tick(1.0 + BRIDGE_QUIET - 0.1) is None
    down = watch.tick(1.0 + BRIDGE_QUIET + 0.5)
    assert down.state == DOWN and "no status from the pilot bridge" in down.reason
    assert watch.tick(10.0) is None          # said once


def test_garbage_in_a_status_is_read_as_nothing_known():
    watch = LinkWatch(direct=False, now=0.0)
    changed = watch.on_status({"link": "up", "silent_s": "x", "queued_commands": None}, 1.0)
    assert changed.state == UP and changed.queued == 0
