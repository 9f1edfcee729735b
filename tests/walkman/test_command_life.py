"""walkman.gym.command_life: a command's life moves only forward, whatever order receipts take."""

from __future__ import annotations

from dataclasses import replace

import pytest
from hypothesis import given, strategies as st

from walkman.gym.command_life import (RANK, TERMINAL, CommandLife, CommandState as S, Ledger,
                                      Receipt, ReceiptError, decode_receipt, describe,
                                      encode_receipt)
from yarp_lite.bottle_text import parse

TURN = CommandLife("drc_valve", "command", 42, "turn 1.57", "pi_main", 1)


def test_a_receipt_round_trips_as_yarp_text():
    receipt = Receipt(42, S.EXPIRED, "`turn 1.57` expired after 23 s in the queue")
    bottle = encode_receipt(receipt)
    assert bottle.to_text() == '42 expired "`turn 1.57` expired after 23 s in the queue"'
    assert decode_receipt(parse(bottle.to_text())) == receipt
    assert decode_receipt(parse("7 accepted")) == Receipt(7, S.ACCEPTED)


@pytest.mark.parametrize("text, problem", [
    ("", "a receipt is seq state"), ("42", "a receipt is seq state"),
    ("x accepted", "a receipt is seq state"), ("42 flew", "unknown command state 'flew'"),
    ("42 refused 7", "reason is text"), ("42 accepted a b", "a receipt is seq state"),
])
def test_a_malformed_receipt_is_refused_with_what_is_wrong(text, problem):
    with pytest.raises(ReceiptError, match=problem):
        decode_receipt(parse(text))


def test_the_usual_life_through_a_blackout():
    ledger = Ledger()
    assert [l.state for l in ledger.sent(TURN)] == [S.SENT]
    assert [l.state for l in ledger.link_down()] == [S.QUEUED]
    assert ledger.link_down() == []                         # said once
    assert [l.state for l in ledger.receipt("drc_valve", Receipt(42, S.DELIVERED))] == \
        [S.DELIVERED]
    expired = ledger.receipt("drc_valve", Receipt(42, S.EXPIRED, "too old"))
    assert expired[0].state is S.EXPIRED and expired[0].reason == "too old"
    assert describe(expired[0]) == "`turn 1.57` (seq 42) to drc_valve: expired: too old"


def test_a_receipt_that_beats_its_commands_record_is_kept_for_it():
    """The lab's main job: the module answered before the gateway's send returned, so the
    receipts came before the ledger heard the command was sent ("temperature start" had no
    receipt in its report)."""
    ledger = Ledger()
    assert ledger.receipt("drc_valve", Receipt(42, S.DELIVERED)) == []
    assert ledger.receipt("drc_valve", Receipt(42, S.ACCEPTED)) == []
    assert [l.state for l in ledger.sent(TURN)] == [S.SENT, S.DELIVERED, S.ACCEPTED]
    assert ledger.get("drc_valve", 42).state is S.ACCEPTED
    assert ledger.sent(TURN) == []                          # and only once


def test_early_receipts_are_bounded_too():
    ledger = Ledger(limit=3)
    for seq in range(10):
        ledger.receipt("drc_valve", Receipt(seq, S.ACCEPTED))
    assert [l.state for l in ledger.sent(replace(TURN, seq=9))] == [S.SENT, S.ACCEPTED]
    assert [l.state for l in ledger.sent(replace(TURN, seq=0))] == [S.SENT]   # forgotten


def test_receipts_out_of_order_never_move_a_command_back_nor_past_its_end():
    ledger = Ledger()
    ledger.sent(TURN, link_down=True)
    assert ledger.get("drc_valve", 42).state is S.QUEUED
    assert ledger.receipt("drc_valve", Receipt(42, S.ACCEPTED))[0].state is S.ACCEPTED
    assert ledger.receipt("drc_valve", Receipt(42, S.DELIVERED)) == []   # late, behind
    assert ledger.receipt("drc_valve", Receipt(42, S.EXPIRED)) == []     # after its end
    assert ledger.receipt("drc_valve", Receipt(43, S.ACCEPTED)) == []    # never heard of
    assert ledger.receipt("gaze_control", Receipt(42, S.ACCEPTED)) == []  # another module's
    assert ledger.sent(TURN) == []             # our own echoed by another station: once


def test_an_accepted_command_whose_module_died_ends_interrupted_and_nothing_after():
    ledger = Ledger()
    ledger.sent(TURN)
    ledger.receipt("drc_valve", Receipt(42, S.ACCEPTED))
    why = "drc_valve's previous process ended during the tick that took `turn 1.57`"
    assert ledger.receipt("drc_valve", Receipt(42, S.INTERRUPTED, why))[0].reason == why
    assert ledger.receipt("drc_valve", Receipt(42, S.EXPIRED)) == []
    refused = CommandLife("m", "command", 1, "go", state=S.REFUSED)
    assert refused.moved(S.INTERRUPTED) is None       # a command that ended stays ended
    assert S.ACCEPTED not in TERMINAL and S.INTERRUPTED in TERMINAL


def test_the_ledger_is_bounded_and_knows_what_a_cancel_could_catch():
    ledger = Ledger(limit=3)
    for seq in range(1, 6):
        ledger.sent(CommandLife("m", "command", seq, f"go {seq}"))
    assert ledger.get("m", 1) is None and ledger.get("m", 5) is not None
    ledger.receipt("m", Receipt(4, S.DELIVERED))
    assert [l.seq for l in ledger.waiting("m")] == [3, 5]


@given(st.lists(st.sampled_from(list(S)), max_size=12))
def test_any_order_of_receipts_only_moves_forward_and_ends_once(states):
    ledger = Ledger()
    ledger.sent(TURN)
    seen = [S.SENT]
    for state in states:
        for life in ledger.receipt("drc_valve", Receipt(42, state)):
            assert RANK[life.state] > RANK[seen[-1]] and seen[-1] not in TERMINAL
            seen.append(life.state)
    assert sum(state in TERMINAL for state in seen) <= 1
