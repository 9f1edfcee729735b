"""A module's receipts and warnings reach a reader that connects after they were written.

Issue 33: in a 100-round ``walkman-chaos`` run four expirations never reached
``/pilot/command_states``: the robot bridge had been killed, and the module wrote
those receipts before the restarted bridge connected to ``/M/receipt:o`` -- a YARP
output with no reader drops what it writes.  The module's reliable outputs now hold
their recent messages for a reader that connects later (:mod:`yarp_lite.held`).

A real module process (the witness) on a yarp_lite name server; the reader a plain
yarp_lite port in this process, connected as the robot bridge connects: with
``[add]`` on the module's port.  The bridge itself, killed and restarted, is in
``tests/bridge/test_bridge_processes.py``.
"""

from __future__ import annotations

import sys

from harness import wait_until
from walkman.gym.command_life import CommandState, decode_receipt
from yarp_lite import network
from yarp_lite.port import Port

PYTHON = sys.executable


def test_a_receipt_and_a_warning_written_with_no_reader_reach_the_one_that_connects(
        lite_world, lite, tmp_path, monkeypatch):
    monkeypatch.setenv("COUNTER_LOG", str(tmp_path / "executed.log"))
    module = lite_world.start([PYTHON, "-m", "walkman.gym.supervisor", "witness",
                               "--name", "/counter"], "witness")
    module.wait_for("ready for the pilot", timeout=60)
    # A switch that waited longer than its validity: the module refuses it as expired,
    # on its receipt and warning ports, while nobody reads them.
    written = lite_world.run_tool(lite, "write", "/test/switch", "/counter/switch:i",
                                  input_text="start 5 (age 100 valid 5)\n")
    assert written.returncode == 0, written.stdout + written.stderr
    module.wait_for(r"`start` expired after 100 s in the queue \(valid 5 s\); not run", 20)
    assert not network.is_connected("/counter/receipt:o", "/test/receipts")

    receipts, warnings = [], []
    readers = [Port("/test/receipts", reader=receipts.append),
               Port("/test/warnings", reader=warnings.append)]
    try:
        assert network.connect("/counter/receipt:o", "/test/receipts").ok
        assert network.connect("/counter/warning:o", "/test/warnings").ok
        wait_until(lambda: receipts and warnings, 10,
                   message=f"the receipt and warning written before (got {receipts} "
                           f"{warnings})")
        receipt = decode_receipt(receipts[0])
        assert (receipt.seq, receipt.state) == (5, CommandState.EXPIRED)
        assert "expired after 100 s" in receipt.reason
        assert any("`start` expired after 100 s" in str(w) for w in warnings), warnings
    finally:
        for port in readers:
            port.close()
