"""walkman.gym.interfaces: the inbox refuses what waited past its validity, says so, runs none."""

from __future__ import annotations

import math

from walkman.gym.interfaces import (PilotCommand, _Inbox, decode_command, encode_command,
                                    readable)
from walkman.gym.validity import Lifetime, stamp
from yarp_lite.bottle import Bottle
from yarp_lite.bottle_text import parse
from harness import ManualClock as Clock


def inbox(validity: float = 10.0) -> "tuple[_Inbox, Clock]":
    clock = Clock()
    return _Inbox(decode_command, validity, clock), clock


def test_a_command_within_its_validity_starts_with_its_lifetime():
    box, clock = inbox()
    box.feed(stamp(parse("(turn 1.57) 42"), Lifetime(3.0, 20.0)))
    clock.now += 16.9                                  # 3 + 16.9 < 20
    command = box.get()
    assert command == PilotCommand("turn", (1.57,), 42, Lifetime(3.0, 20.0))
    assert box.take_rejections() == [] and box.expired == 0


def test_one_that_waited_too_long_is_refused_as_expired_and_the_next_one_starts():
    box, clock = inbox()
    box.feed(stamp(parse("(turn 1.57) 42"), Lifetime(23.0, None)))   # the queue
    box.feed(parse("start 43"))              # bare: age 0 here, default validity
    assert box.get() == PilotCommand("start", (), 43)
    assert box.take_rejections() == [
        "`turn 1.57` expired after 23 s in the queue (valid 10 s); not run"]
    assert box.expired == 1


def test_the_wait_in_the_module_counts_until_the_command_would_start():
    box, clock = inbox(validity=5.0)
    box.feed(parse("go 7"))                   # arrives fresh...
    clock.now += 6.0                                    # ... but the module is busy
    assert box.get() is None
    assert box.take_rejections() == ["`go` expired after 6 s in the queue (valid 5 s); not run"]


def test_a_malformed_lifetime_is_refused_with_its_reason():
    box, _ = inbox()
    box.feed(parse("(turn 1) 4 (age soon)"))
    assert box.get() is None
    assert box.take_rejections() == ["age must be a finite number of seconds >= 0, not 'soon'"]


def test_encoding_a_command_with_a_lifetime_carries_it():
    bottle = encode_command(PilotCommand("look_at", (1.0, 0.5), 9, Lifetime(0.0, 30.0)))
    assert readable(bottle) == "(look_at 1.0 0.5) 9 (age 0.0 valid 30.0)"


def test_floats_read_as_a_pilot_typed_them_and_the_rest_as_yarp_writes_it():
    bottle = Bottle([Bottle(["look_at", 1.45, 0.2, 3.0, math.pi / 2, "two words", 7]), 655722274])
    assert Bottle([1.45]).to_text() != "1.45"          # YARP's own text: every digit
    assert readable(bottle) == '(look_at 1.45 0.2 3.0 1.570796327 "two words" 7) 655722274'
    assert readable(Bottle(["start", 12])) == "start 12"
    assert readable(Bottle([float("nan"), 1e-9])) == f"{Bottle([float('nan')]).to_text()} 1e-09"


def test_the_inbox_says_what_became_of_each_numbered_command():
    from walkman.gym.command_life import CommandState, Receipt

    box, clock = inbox(validity=5.0)
    said = []
    box.on_receipt = said.append
    box.feed(parse("(turn 1.5) 42"))
    box.feed(parse("go"))                        # no number: nothing to name
    box.feed(stamp(parse("(turn 2.0) 43"), Lifetime(9.0, None)))
    assert box.get() == PilotCommand("turn", (1.5,), 42)
    assert box.get() == PilotCommand("go")
    assert box.get() is None
    assert said == [Receipt(42, CommandState.ACCEPTED),
                    Receipt(43, CommandState.EXPIRED,
                            "`turn 2.0` expired after 9 s in the queue (valid 5 s); not run")]


def test_the_standard_ports_are_named_in_one_place_in_the_bridges_kind_order():
    from walkman.gym.interfaces import GYM_PORTS, RECEIPT, SWITCH

    assert [p.suffix for p in GYM_PORTS] == ["switch:i", "command:i", "status:o", "warning:o",
                                             "receipt:o"]
    assert SWITCH.of("gaze_control") == "/gaze_control/switch:i"
    assert RECEIPT.of("/a/b") == "/a/b/receipt:o"


def test_a_status_reader_held_up_neither_holds_the_sender_nor_silences_the_others(lite_world):
    """The watchdog that sends the status also carries out ``stop``: a reader that stops
    reading (a ``yarp read`` on a loaded laptop) must not hold it."""
    import threading
    import time

    from harness import wait_until
    from walkman.gym.interfaces import PilotInterfaces
    from yarp_lite import network
    from yarp_lite.port import Port

    held, heard = threading.Event(), []

    def stall(bottle) -> None:
        held.wait(30)

    interfaces = PilotInterfaces("/held_up", statuses=["ok"])
    interfaces.open(wait=10)
    stalled = Port(reader=stall).open("/test/stalled:i")
    listening = Port(reader=heard.append).open("/test/heard:i")
    try:
        for reader in (stalled, listening):
            assert network.connect("/held_up/status:o", reader.name).ok
        sent = 0
        deadline = time.monotonic() + 10
        while len(heard) < 5 and time.monotonic() < deadline:
            interfaces.set_status("ok", [sent])
            interfaces.send_status()          # returns at once: the stalled one is skipped
            sent += 1
            time.sleep(0.05)
        wait_until(lambda: len(heard) >= 5, 5,
                   message=f"statuses while another reader is stalled (had {len(heard)})")
    finally:
        held.set()
        stalled.close()
        listening.close()
        interfaces.close()


def test_a_warning_reader_held_up_holds_neither_the_watchdog_nor_a_warning(lite_world):
    """Warnings and receipts say something once, so none is skipped; but the watchdog that
    writes them must not wait for a reader's acknowledgement either.  drc_door warned the
    pilot of a flood of "may not command" through a robot bridge whose link was down: the
    bridge held its acknowledgements, the watchdog's heartbeat stopped for 5 s and the
    supervisor killed the module as hung.  Now each is queued, and sent in order once the
    reader takes them."""
    import threading

    from harness import wait_until
    from walkman.gym.command_life import CommandState, Receipt
    from walkman.gym.interfaces import PilotInterfaces
    from yarp_lite import network
    from yarp_lite.port import Port

    held, warnings, receipts = threading.Event(), [], []

    def stall_then(into: list):
        def take(bottle) -> None:
            held.wait(30)
            into.append(bottle)
        return take

    interfaces = PilotInterfaces("/held_up", statuses=["ok"])
    interfaces.open(wait=10)
    warning_reader = Port(reader=stall_then(warnings)).open("/test/warnings:i")
    receipt_reader = Port(reader=stall_then(receipts)).open("/test/receipts:i")
    try:
        assert network.connect("/held_up/warning:o", warning_reader.name).ok
        assert network.connect("/held_up/receipt:o", receipt_reader.name).ok

        def watchdog() -> None:
            for index in range(5):
                interfaces.warn(f"warning {index}")
                interfaces.receipt(Receipt(index, CommandState.ACCEPTED))
        writing = threading.Thread(target=watchdog, daemon=True)
        writing.start()
        writing.join(20)              # (the port's own timeout would have ended it later)
        assert not writing.is_alive(), "the watchdog waited on a reader held up"
        assert not warnings and not receipts          # the readers still hold the first
        held.set()
        wait_until(lambda: len(warnings) == 5 and len(receipts) == 5, 20,
                   message=f"every warning and receipt ({len(warnings)}, {len(receipts)})")
        assert [bottle[1] for bottle in warnings] == [f"warning {i}" for i in range(5)]
    finally:
        held.set()
        warning_reader.close()
        receipt_reader.close()
        interfaces.close()
