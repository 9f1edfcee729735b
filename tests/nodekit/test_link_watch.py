"""nodekit.link_watch: a side's bridge status reduced to what its readers must know.

The pilot gateway reads the pilot bridge's (``/bridge/link``), the robot's modules the
robot bridge's (their link-loss policy).
"""

from __future__ import annotations

import pytest

from bridge import status as bridge_status
from nodekit.link_watch import (BRIDGE_QUIET, DIRECT, DOWN, SILENT_DOWN, UNKNOWN, UP, LinkWatch,
                                status_fields)
from yarp_lite.bottle import Bottle


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


def test_on_the_robot_the_bridges_are_named_the_other_way_round():
    watch = LinkWatch(direct=False, now=0.0, side="robot")
    assert watch.state.reason == "no word from the robot bridge yet"
    assert watch.tick(60.0) is None          # the lab: no bridge, never down
    watch.on_status(status(), 61.0)
    down = watch.on_status(status(silent=SILENT_DOWN + 0.1), 62.0)
    assert down.state == DOWN and down.reason == "the pilot's bridge silent for 1.6 s"
    watch.on_status(status(), 63.0)
    gone = watch.tick(63.0 + BRIDGE_QUIET + 1.0)
    assert gone.state == DOWN and gone.reason == "no status from the robot bridge for 3 s"
    with pytest.raises(ValueError, match="side must be one of pilot, robot"):
        LinkWatch(direct=False, now=0.0, side="moon")


def test_the_fields_of_a_bridge_status_bottle_are_what_the_bridge_wrote():
    written = {"side": "robot", "link": "up", "silent_s": 0.3, "queued_commands": 2,
               "tcp": {"frames": 4}, "modules_here": ["counter"]}
    fields = status_fields(bridge_status.to_bottle(written))
    assert {key: fields[key] for key in ("side", "link", "silent_s", "queued_commands")} == \
        {"side": "robot", "link": "up", "silent_s": 0.3, "queued_commands": 2}
    assert LinkWatch(direct=False, now=0.0, side="robot").on_status(fields, 1.0).state == UP
    assert status_fields(Bottle()) == {}


@pytest.mark.parametrize("garbage", [Bottle(["link", "up"]), Bottle([Bottle(["link"])]),
                                     Bottle([Bottle([3, "up"])]), Bottle([1.5])])
def test_anything_else_on_the_status_port_is_refused(garbage):
    with pytest.raises(ValueError, match="not a bridge status"):
        status_fields(garbage)
