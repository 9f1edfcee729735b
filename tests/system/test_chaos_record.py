"""What a chaos run reads from the programs (system/chaos_record.py), on lines they print."""

from __future__ import annotations

import json

from system.chaos_record import (Record, cancelled_by_bridge, expired_at_module,
                                 seqs_of_numbers, sent_commands)


def test_the_pilots_lines_fill_the_record():
    record = Record(statuses={"counter": []})
    lines = [
        {"ev": "status", "t": 1.0, "module": "counter", "seq": 3, "state": "idle", "values": []},
        {"ev": "sent", "t": 2.0, "n": 5, "seq": 50, "validity": 3.0, "cancel": False},
        {"ev": "sent", "t": 2.5, "n": 7, "seq": 70, "validity": 0.0, "cancel": True},
        {"ev": "cancel", "t": 2.6, "n": 7, "seq": 70, "ok": True, "cancelled": [70],
         "message": "cancelled 70"},
        {"ev": "state", "t": 3.0, "seq": 50, "state": "delivered", "reason": ""},
        {"ev": "state", "t": 3.1, "seq": 50, "state": "expired", "reason": "too old"},
        {"ev": "state", "t": 3.2, "seq": 90, "state": "cancelled", "reason": "by a pilot"},
        {"ev": "refused", "t": 4.0, "n": 8, "message": "no module"},
        {"ev": "drained", "t": 5.0, "next": 8},
    ]
    for line in lines:
        record.take_pilot_event(json.loads(json.dumps(line)))
    assert [a["seq"] for a in record.accepted] == [50, 70]
    assert record.statuses["counter"][0]["state"] == "idle"
    assert record.expired() == {50}
    assert record.cancelled() == {70, 90}    # the gateway's answer, or the state heard
    assert record.pilot_errors == [{"ev": "refused", "t": 4.0, "n": 8, "message": "no module"}]
    assert record.drained


def test_the_gateways_bridges_and_witness_logs_name_their_commands():
    gateway = ["12:00:01 [INFO] gateway: sent to /counter/command:i: (count 17.0) 123 "
               "(from service)",
               "12:00:02 [INFO] gateway: sent to /gaze_control/command:i: (home) 124 (from x)",
               "12:00:03 [INFO] gateway: sent to /counter/switch:i: start 125 (from service)"]
    assert sent_commands(gateway) == [(17, 123)]
    bridge = ["12:00:04 [INFO] cancelled counter's command 126 before it left",
              "12:00:04 [INFO] cancelled gaze_control's command 127 before it left"]
    assert cancelled_by_bridge(bridge) == {126}
    module = ["12:00:05 [WARNING] witness: `count 18.0` expired after 4 s in the queue "
              "(valid 3 s); not run"]
    assert expired_at_module(module) == [18]


def test_a_number_maps_to_its_one_unrun_seq_and_never_guesses():
    sent = [(1, 10), (2, 20), (2, 21), (3, 30), (3, 31)]
    # 2 was sent twice (a retry) and 21 ran: 20 is the one; 3 twice, neither ran: ambiguous
    assert seqs_of_numbers([1, 2, 3, 9], sent, ran={21}) == {10, 20}
