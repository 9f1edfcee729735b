"""The bridge node's stand-ins against a ``yarp-lite server`` (its decisions on messages:
test_core.py; the whole wiring is tested as processes)."""

from __future__ import annotations

import pytest

from bridge.flows import FlowKey
from harness import free_port, wait_until


# -- presence: the pilot's stand-ins, against a yarp-lite server ------------------------------

PRESENCE_CONFIG = """<bridge><modules><module name="gaze_control" id="7"/></modules></bridge>"""


@pytest.fixture
def pilot_bridge(tmp_path, lite_world):
    from bridge import config as bridge_config
    from bridge.node import Bridge
    from nodekit.connections import ConnectionKeeper

    bridge = Bridge(bridge_config.parse(PRESENCE_CONFIG), PRESENCE_CONFIG, side="pilot",
                    peer="127.0.0.1", tcp_port=free_port(), udp_port=free_port(),
                    state_dir=tmp_path / "state")
    bridge.keeper = ConnectionKeeper()       # the endpoints, without the link's threads
    yield bridge
    bridge.stop()


def shown_here() -> set:
    from yarp_lite.nameclient import NameClient

    client = NameClient()
    return {p for p in ("/gaze_control/switch:i", "/gaze_control/command:i",
                        "/gaze_control/status:o", "/gaze_control/warning:o")
            if client.query(p) is not None}


def test_stand_ins_follow_the_word_and_a_closing_one_writes_its_last_warning(pilot_bridge):
    from bridge.wire import compact
    from yarp_lite.bottle import Bottle

    everything = frozenset(FlowKey(7, kind) for kind in range(4))
    pilot_bridge.stand_ins.follow(everything)
    assert shown_here() == {"/gaze_control/switch:i", "/gaze_control/command:i",
                            "/gaze_control/status:o", "/gaze_control/warning:o"}
    assert pilot_bridge.status()["modules_shown"] == ["gaze_control"]
    # The module's last warning arrived with the word that it is gone: the warning port
    # stays until the warning is written, the others close at once.
    pilot_bridge.journal.accept(1, 1, 7, 3, compact.encode(Bottle([1, "overheating"])))
    pilot_bridge.stand_ins.follow(frozenset())
    assert shown_here() == {"/gaze_control/warning:o"}
    pilot_bridge.journal.delivered(pilot_bridge.journal.undelivered()[0].row)
    pilot_bridge.stand_ins.follow(frozenset())
    assert shown_here() == set()
    assert pilot_bridge.status()["modules_shown"] == []


def test_the_presence_thread_follows_the_peer_and_remembers_its_word(pilot_bridge,
                                                                      tmp_path):
    import threading

    from bridge import config as bridge_config
    from bridge.node import Bridge

    # Said while the bridge was still opening its endpoints (before the thread runs).
    pilot_bridge.stand_ins.on_peer(frozenset({FlowKey(7, 0), FlowKey(7, 2)}))
    thread = threading.Thread(target=pilot_bridge.stand_ins.keep, args=(pilot_bridge._stop,),
                              daemon=True)
    thread.start()
    wait_until(lambda: shown_here() == {"/gaze_control/switch:i", "/gaze_control/status:o"},
               5, message="the stand-ins the word names")
    wait_until(lambda: (tmp_path / "state" / "presence.json").exists(), 5,
               message="the word kept")
    pilot_bridge.stop()
    thread.join(5)
    assert not thread.is_alive() and shown_here() == set()
    again = Bridge(bridge_config.parse(PRESENCE_CONFIG), PRESENCE_CONFIG, side="pilot",
                   peer="127.0.0.1", tcp_port=free_port(), udp_port=free_port(),
                   state_dir=tmp_path / "state")
    # A restart in an outage shows them.
    assert again.stand_ins.peer == {FlowKey(7, 0), FlowKey(7, 2)}
    again.journal.close()


def test_a_reader_that_stops_reading_the_status_does_not_silence_it_for_the_others(
        pilot_bridge):
    """Every gateway, PI and GYM module reads its bridge's status to tell the link is down
    after 2 s without one.  One reader held up (a PI busy restarting its 3-D view) held the
    bridge's status writer on its acknowledgement, and both gateways of fc3 said "link down
    (no status from the pilot bridge for 2 s)" with the link up."""
    import threading

    from yarp_lite import network
    from yarp_lite.port import Port

    held, heard = threading.Event(), []

    def stall(bottle) -> None:
        held.wait(30)                 # stuck in its first status until the test ends

    stalled = Port(reader=stall).open("/test/stalled/status:i")
    listening = Port(reader=heard.append).open("/test/heard/status:i")
    try:
        pilot_bridge._open_status_ports()
        for reader in (stalled, listening):
            assert network.connect("/bridge/pilot/status:o", reader.name).ok
        wait_until(lambda: len(heard) >= 4, 10,     # one each 0.5 s (STATUS_PERIOD)
                   message=f"statuses while another reader is stalled (had {len(heard)})")
    finally:
        held.set()
        stalled.close()
        listening.close()


def test_a_name_server_that_fails_while_the_ports_open_is_tried_again_not_given_up(
        tmp_path, lite_world, monkeypatch, caplog):
    """A refusal while the endpoints open (the name server restarting under the bridge) once
    left the bridge without its YARP side for good, its link up.  Now it tries again, opening
    only what the last try did not."""
    from bridge import config as bridge_config
    from bridge import node
    from bridge.node import Bridge
    from yarp_lite.errors import NetworkError

    monkeypatch.setattr(node, "OPEN_RETRY", 0.05)
    opened, refusals = [], [2]
    real_open = Bridge._open_yarp_endpoint

    def refusing_twice(self, channel):
        if refusals[0]:
            refusals[0] -= 1
            raise NetworkError("name server: connection reset (a test's refusal)")
        opened.append(channel.key)
        return real_open(self, channel)

    monkeypatch.setattr(Bridge, "_open_yarp_endpoint", refusing_twice)
    config = PRESENCE_CONFIG
    bridge = Bridge(bridge_config.parse(config), config, side="robot", peer="127.0.0.1",
                    tcp_port=free_port(), udp_port=free_port(), state_dir=tmp_path / "state")
    with caplog.at_level("INFO", logger="bridge"):
        bridge.start()
        try:
            wait_until(lambda: "bridge robot side ready" in caplog.text, 20,
                       message="the bridge ready after the refusals")
        finally:
            bridge.stop()
    assert "cannot open the YARP side (name server: connection reset" in caplog.text
    assert len(opened) == len(set(opened)) > 0, opened      # each endpoint opened once
