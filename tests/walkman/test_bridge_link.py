"""walkman.gym.bridge_link: a module hears its robot bridge's status on its own port.

A yarp-lite name server; this test plays the robot bridge (a port named
``/bridge/robot/status:o`` writing what bridge.status writes), started after the
module as on the robot, then going quiet.  The waits are on the link's state.
"""

from __future__ import annotations

import logging
import time

import pytest

from bridge import status as bridge_status
from harness import wait_until
from walkman.gym.bridge_link import ROBOT_BRIDGE_STATUS, BridgeLink
from yarp_lite.bottle import Bottle
from yarp_lite.nameclient import NameClient
from yarp_lite.port import Port

TIMEOUT = 20.0


@pytest.fixture
def module_link(lite_world):
    link = BridgeLink("m")
    link.open(NameClient(), "/m/bridge:i")
    yield link
    link.close()


def state(link: BridgeLink) -> str:
    return link.state(time.monotonic()).state


def test_the_bridge_found_later_is_heard_and_its_silence_too(module_link, caplog):
    caplog.set_level(logging.INFO, logger="walkman.gym")
    assert state(module_link) == "unknown"             # no bridge yet: not down
    bridge = Port(nameclient=NameClient()).open(ROBOT_BRIDGE_STATUS)
    try:
        up = bridge_status.to_bottle({"side": "robot", "link": "up", "silent_s": 0.2,
                                      "tcp": {"frames": 3}})
        wait_until(lambda: bridge.write(up) and state(module_link) == "up", TIMEOUT,
                   message="the keeper connecting the bridge's status to the module")
        silent = bridge_status.to_bottle({"link": "up", "silent_s": 1.7})
        wait_until(lambda: bridge.write(silent) and state(module_link) == "down", TIMEOUT,
                   message="the pilot's bridge silent: down")
        assert "the link to the pilot is down (the pilot's bridge silent for 1.7 s)" in \
            caplog.text
        bridge.write(up)
        wait_until(lambda: state(module_link) == "up", TIMEOUT, message="up again")
    finally:
        bridge.close()
    wait_until(lambda: state(module_link) == "down", TIMEOUT,
               message="the robot bridge gone quiet: down")
    assert "no status from the robot bridge" in caplog.text


def test_something_else_on_the_port_changes_nothing_and_is_told_once(module_link, caplog):
    bridge = Port(nameclient=NameClient()).open(ROBOT_BRIDGE_STATUS)
    try:
        wait_until(lambda: bool(bridge.output_routes()), TIMEOUT, message="connected")
        for _ in range(3):
            assert bridge.write(Bottle(["link", "down"]))
        wait_until(lambda: "ignored a message on /m/bridge:i" in caplog.text, TIMEOUT,
                   message="the refusal in the log")
        assert caplog.text.count("not a bridge status: 'link down'") == 1
        assert state(module_link) == "unknown"
    finally:
        bridge.close()
