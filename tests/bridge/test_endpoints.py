"""The bridge's YARP endpoints against a ``yarp-lite server``: readiness, and what they watch."""

from __future__ import annotations

import pytest

from bridge.config import PILOT, ROBOT, Transport, YarpChannel
from bridge.endpoints import yarp as endpoints
from bridge.endpoints.yarp import YarpSink, YarpSource
from harness import wait_until
from nodekit.connections import ConnectionKeeper
from yarp_lite.bottle import Bottle
from yarp_lite.nameclient import NameClient
from yarp_lite.port import Port

WARNING = YarpChannel(7, 3, "gaze_control/warning", ROBOT, PILOT, Transport.TCP, True,
                      listen_port="/bridge/robot/gaze_control/warning",
                      feed_port="/gaze_control/warning:o", emit_port="/gaze_control/warning:o")
SWITCH = YarpChannel(7, 0, "gaze_control/switch", PILOT, ROBOT, Transport.TCP, True,
                     listen_port="/gaze_control/switch:i",
                     emit_port="/bridge/robot/gaze_control/switch",
                     deliver_port="/gaze_control/switch:i")


@pytest.fixture
def keeper():
    made = ConnectionKeeper(period=0.1)
    made.start()
    yield made
    made.stop()


def test_a_stand_in_holds_a_reliable_message_for_a_reader_a_while(lite_world, keeper):
    source = YarpSource(WARNING, NameClient(), keeper)   # the pilot's /gaze_control/warning:o
    try:
        assert not source.deliver(Bottle([1, "hot"]))    # nobody reads yet: it waits
        got = []
        reader = Port("/test/warnings", reader=got.append)
        source.port.add_output(reader.name)
        assert source.deliver(Bottle([1, "hot"]))
        wait_until(lambda: got == [Bottle([1, "hot"])], 5, message="the warning read")
        reader.close()
        wait_until(lambda: source.port.output_count == 0, 5, message="the reader gone")
        assert not source.ready
        source._opened -= endpoints.READER_GRACE           # nobody read for the whole grace:
        assert source.ready                                 # written for nobody, as YARP would
        assert source.deliver(Bottle([2, "cold"]))
    finally:
        source.close()
    assert not source.deliver(Bottle([3, "late"]))       # closed: not counted delivered


def test_endpoints_say_whether_the_module_they_connect_to_is_there(lite_world, keeper):
    robot_sink = YarpSink(WARNING, NameClient(), keeper, lambda channel, bottle: None)
    robot_source = YarpSource(SWITCH, NameClient(), keeper)
    try:
        assert not robot_sink.linked and not robot_source.linked
        module = [Port("/gaze_control/warning:o"), Port("/gaze_control/switch:i",
                                                         reader=lambda b: None)]
        wait_until(lambda: robot_sink.linked and robot_source.linked, 5,
                   message="the keeper connecting the module")
        for port in module:
            port.close()
        wait_until(lambda: not robot_sink.linked and not robot_source.linked, 5,
                   message="the module gone")
    finally:
        robot_sink.close()
        robot_source.close()
