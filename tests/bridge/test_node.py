"""The bridge node's own decisions: status events without sockets, the stand-ins against a
``yarp-lite server`` (the whole wiring is tested as processes)."""

from __future__ import annotations

import pytest

from bridge.node import COMMAND_WINDOW, StatusEvents
from harness import free_port, wait_until
from harness import ManualClock as Clock
from yarp_lite.bottle import Bottle


def status(seq: int, state: str, *data) -> Bottle:
    return Bottle([seq, state, *data])


def test_a_new_state_is_an_event_and_a_repeated_status_is_not():
    events = StatusEvents(Clock())
    assert not events.is_event(7, status(2, "idle"))  # the first one: nothing to compare
    assert not events.is_event(7, status(3, "idle"))  # only the message counter moved
    assert events.is_event(7, status(4, "running"))
    assert not events.is_event(7, status(5, "running"))


def test_changing_data_is_an_event_only_right_after_a_command():
    clock = Clock()
    events = StatusEvents(clock)
    events.is_event(3, status(2, "running", 40.0))
    assert not events.is_event(3, status(3, "running", 40.5))  # drifting by itself
    events.commanded(3)
    clock.now += COMMAND_WINDOW / 2
    assert events.is_event(3, status(4, "running", 12.0))       # the command's effect
    clock.now += COMMAND_WINDOW
    assert not events.is_event(3, status(5, "running", 12.5))
    assert not events.is_event(4, status(2, "running", 1.0))    # modules are apart


def test_the_status_answering_a_command_is_told_apart_from_later_ones():
    """The first change after a command, and a new state, also go as datagram copies
    (bridge.copies); later changes within the window are events by TCP only."""
    clock = Clock()
    events = StatusEvents(clock)
    events.classify(3, status(2, "running", 40.0))
    events.commanded(3)
    assert events.classify(3, status(3, "running", 41.0)) == "first answer"
    assert events.classify(3, status(4, "running", 42.0)) == "answer"
    assert events.classify(3, status(5, "running", 42.0)) is None   # nothing changed
    events.commanded(3)
    assert events.classify(3, status(6, "reached", 42.0)) == "state"
    assert events.classify(3, status(7, "reached", 43.0)) == "answer"  # answered by the state


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
    from bridge import compact
    from yarp_lite.bottle import Bottle

    everything = frozenset((7, kind) for kind in range(4))
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
    pilot_bridge.stand_ins.on_peer(frozenset({(7, 0), (7, 2)}))
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
    assert again.stand_ins.peer == {(7, 0), (7, 2)}   # a restart in an outage shows them
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
