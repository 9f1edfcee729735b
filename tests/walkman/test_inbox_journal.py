"""The command journal a module's next process reads: pure parsing, then the file layer."""

from __future__ import annotations

from pathlib import Path
from typing import Dict, List, Tuple

from hypothesis import given, strategies as st

from walkman.gym.command_life import CommandState
from walkman.gym.inbox_journal import (ARRIVED, ENDED, REMEMBERED, TAKEN, InboxJournal,
                                       interruptions, journal_path, line, parse)
from walkman.gym.interfaces import PilotCommand, _Inbox, decode_command
from yarp_lite.bottle import Bottle


def journal_text(*entries: Tuple[str, int, str]) -> str:
    return b"".join(line(kind, seq, text) for kind, seq, text in entries).decode()


def test_a_command_that_arrived_and_ended_is_not_unfinished():
    before = parse(journal_text((ARRIVED, 5, "turn 1.57"), (TAKEN, 5, ""), (ENDED, 5, "")))
    assert before.unfinished == [] and before.seen == [5]


def test_taken_and_only_arrived_commands_are_unfinished_in_arrival_order():
    before = parse(journal_text((ARRIVED, 7, "walk 2"), (ARRIVED, 8, "turn 1"), (TAKEN, 7, ""),
                                (ARRIVED, 9, "stop_walk"), (ENDED, 8, "")))
    assert [(h.seq, h.text, h.taken) for h in before.unfinished] == \
        [(7, "walk 2", True), (9, "stop_walk", False)]
    assert sorted(before.seen) == [7, 8, 9]


def test_malformed_lines_are_named_and_skipped():
    text = "a 3 ok\nx 4 what\na four\n\nt\ne 3\n"
    before = parse(text)
    assert before.unfinished == [] and before.seen == [3]
    assert [m.split(":")[0] for m in before.malformed] == ["line 2", "line 3", "line 5"]
    assert "is not 'a|t|e SEQ [TEXT]'" in before.malformed[0]


def test_a_command_text_with_a_newline_stays_on_its_line():
    assert line(ARRIVED, 1, "say \"two\nlines\"") == b'a 1 say "two lines"\n'
    assert parse(line(ARRIVED, 1, "x\ny").decode()).unfinished[0].text == "x y"


def test_only_the_latest_seqs_are_remembered():
    text = journal_text(*((ENDED, seq, "") for seq in range(REMEMBERED + 50)))
    assert parse(text).seen == list(range(50, REMEMBERED + 50))


events = st.lists(st.tuples(st.sampled_from([ARRIVED, TAKEN, ENDED]),
                            st.integers(min_value=0, max_value=20)), max_size=60)


@given(events)
def test_unfinished_is_what_arrived_or_was_taken_and_has_not_ended_since(steps):
    text = journal_text(*((kind, seq, f"cmd{seq}" if kind == ARRIVED else "")
                          for kind, seq in steps))
    model: Dict[int, bool] = {}
    for kind, seq in steps:
        if kind == ARRIVED:
            model[seq] = False
        elif kind == TAKEN:
            model[seq] = True
        else:
            model.pop(seq, None)
    assert {h.seq: h.taken for h in parse(text).unfinished} == model


@given(st.binary(max_size=300))
def test_any_bytes_parse_without_raising(data):
    parse(data.decode("utf-8", "replace"))


def test_interruptions_say_whether_the_command_may_have_begun():
    taken, queued = interruptions(parse(journal_text(
        (ARRIVED, 1, "hang"), (TAKEN, 1, ""), (ARRIVED, 2, "idle 1"))).unfinished, "witness")
    assert taken.state is queued.state is CommandState.INTERRUPTED
    assert taken.reason == ("witness's previous process ended during the tick that took "
                            "`hang` (it may have begun); not run again")
    assert queued.reason == "witness's previous process ended before taking `idle 1`; not run"


def test_the_path_names_the_module_and_its_name_server(tmp_path):
    assert journal_path("/drc/valve", "10.0.0.2:10000", str(tmp_path)) == \
        tmp_path / "walkman-modules" / "drc_valve@10.0.0.2_10000.inbox"


def test_a_new_process_takes_over_then_starts_the_file_with_the_seqs_only(tmp_path: Path):
    path = tmp_path / "m.inbox"
    first = InboxJournal(path)
    assert first.take_over().unfinished == []
    first.write(ARRIVED, 11, "walk 1")
    first.write(TAKEN, 11)
    first.write(ARRIVED, 12, "turn 2")
    # killed here: nothing closes the file; the lines are already in it
    second = InboxJournal(path)
    before = second.take_over()
    assert [(h.seq, h.taken) for h in before.unfinished] == [(11, True), (12, False)]
    assert path.read_text() == "e 11\ne 12\n"
    second.close()
    assert InboxJournal(path).take_over().unfinished == []


def inbox_with_journal(path: Path) -> Tuple[_Inbox, List]:
    inbox = _Inbox(decode_command)
    receipts: List = []
    inbox.on_receipt = receipts.append
    inbox.journal = InboxJournal(path)
    inbox.journal.take_over()
    return inbox, receipts


def test_the_inbox_writes_arrival_take_and_the_end_of_the_tick(tmp_path: Path):
    path = tmp_path / "m.inbox"
    inbox, receipts = inbox_with_journal(path)
    inbox.feed(Bottle(["walk", 3]))
    inbox.feed(Bottle([Bottle(["turn", 1.5]), 4]))
    assert path.read_text() == "a 3 walk\na 4 turn 1.5\n"
    command = inbox.get()
    assert isinstance(command, PilotCommand) and command.seq == 3
    assert path.read_text().endswith("t 3\n") and receipts[-1].state is CommandState.ACCEPTED
    inbox.settle()
    assert path.read_text().endswith("e 3\n")
    assert [(h.seq, h.taken) for h in parse(path.read_text()).unfinished] == [(4, False)]


def test_a_seq_a_previous_process_saw_is_dropped_as_a_resend(tmp_path: Path):
    path = tmp_path / "m.inbox"
    path.write_text("a 3 walk\nt 3\n")
    inbox, _ = inbox_with_journal(path)
    inbox.remember(parse("e 3\n").seen)
    inbox.feed(Bottle(["walk", 3]))
    inbox.feed(Bottle(["walk", 5]))
    taken = inbox.get()
    assert taken is not None and taken.seq == 5 and inbox.get() is None
