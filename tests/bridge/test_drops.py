"""The drop ledger: counts by reason, one log line per burst, the shared decisions."""

from __future__ import annotations

import logging

from bridge.errors import BridgeProtocolError
from bridge.transport import drops
from bridge.transport.drops import DropLedger, Reason
from bridge.wire.link import AuthenticationFailed, ForgedInput, ReplayedInput
from harness import ManualClock


def test_a_flood_is_logged_by_the_burst_rule_with_its_counts(caplog):
    clock = ManualClock(0.0)
    ledger = DropLedger("UDP channel", logging.getLogger("test.drops"), clock)
    with caplog.at_level(logging.INFO, logger="test.drops"):
        for _ in range(500):
            ledger.drop(Reason.FORGED, "datagram from 10.0.0.9")
            clock.now += 0.01
        clock.now += 60
        ledger.drop(Reason.FORGED, "again")
    lines = [r.getMessage() for r in caplog.records]
    assert len(lines) == 4   # the 1st, 10th and 100th of the flood, then a new burst
    assert "dropped forged -- datagram from 10.0.0.9 (1 in this burst, 1 in all)" in lines[0]
    assert "(100 in this burst, 100 in all)" in lines[2]
    assert "again (1 in this burst, 501 in all)" in lines[3]
    assert ledger.get(Reason.FORGED) == 501 and ledger.get(Reason.STALE) == 0


def test_peer_errors_map_to_their_reasons():
    ledger = DropLedger("TCP channel", logging.getLogger("test.drops"))
    for error, reason in ((AuthenticationFailed("x"), Reason.UNAUTHENTICATED),
                          (ForgedInput("x"), Reason.FORGED),
                          (ReplayedInput("x"), Reason.REPLAYED),
                          (BridgeProtocolError("x"), Reason.MALFORMED)):
        assert ledger.peer_error(error, "frame") is reason
    assert ledger.last_error == "malformed: frame: x"


def test_the_shared_decisions():
    assert drops.from_peer("10.0.0.1", ["10.0.0.1"]) and drops.from_peer("1.2.3.4", [])
    assert not drops.from_peer("10.0.0.9", ["10.0.0.1"])
    assert drops.is_newer(0, (1 << 32) - 1) and not drops.is_newer(5, 5)
    assert drops.is_newer(1, None) and not drops.is_newer(4, 5)
    assert drops.hold_back(drops.BACKLOG_LIMIT + 1) and not drops.hold_back(0)
