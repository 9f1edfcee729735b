"""The journal: numbered, durable, acknowledged; duplicates refused; limits enforced."""

from __future__ import annotations

import multiprocessing
import os
import signal

import pytest

from bridge.errors import BridgeProtocolError
from bridge.flows import FlowKey
from bridge.transport.journal import Journal, QueueFull


def test_messages_are_numbered_and_survive_a_reopen(tmp_path):
    journal = Journal(tmp_path)
    session = journal.session
    assert [journal.append(7, 0, b"start"), journal.append(7, 1, b"go")] == [1, 2]
    journal.close()
    again = Journal(tmp_path)
    assert again.session == session
    assert [(q.seq, q.payload) for q in again.unacknowledged()] == [(1, b"start"), (2, b"go")]
    assert again.append(7, 0, b"stop") == 3


def test_acknowledged_messages_are_forgotten_but_numbers_keep_growing(tmp_path):
    journal = Journal(tmp_path)
    for text in (b"a", b"b", b"c"):
        journal.append(1, 0, text)
    assert journal.acknowledge(2) == 2
    assert [q.seq for q in journal.unacknowledged()] == [3]
    journal.acknowledge(3)
    assert journal.append(1, 0, b"d") == 4
    with pytest.raises(BridgeProtocolError, match="only 4 were ever sent"):
        journal.acknowledge(9)


def test_the_inbox_refuses_repeats_and_gaps(tmp_path):
    inbox = Journal(tmp_path)
    assert inbox.accept(42, 1, 7, 0, b"start")
    assert not inbox.accept(42, 1, 7, 0, b"start")
    assert inbox.accept(42, 2, 7, 1, b"go")
    with pytest.raises(BridgeProtocolError, match="missing"):
        inbox.accept(42, 5, 7, 1, b"late")
    assert inbox.accepted(42) == 2
    rows = inbox.undelivered()
    assert [message.payload for message in rows] == [b"start", b"go"]
    inbox.delivered(rows[0].row)
    assert [message.payload for message in inbox.undelivered()] == [b"go"]


def test_a_new_peer_session_starts_from_any_number(tmp_path):
    inbox = Journal(tmp_path)
    assert inbox.accept(1, 17, 7, 0, b"x")  # the peer's queue was already partly acked
    assert inbox.accepted(1) == 17


def test_the_queue_is_bounded_with_a_clear_error(tmp_path):
    journal = Journal(tmp_path, limit=2)
    journal.append(1, 0, b"a")
    journal.append(1, 0, b"b")
    with pytest.raises(QueueFull, match="2 reliable messages wait"):
        journal.append(1, 0, b"c")


def _append_then_die(path, count):
    journal = Journal(path)
    for index in range(count):
        journal.append(1, 0, str(index).encode())
    os.kill(os.getpid(), signal.SIGKILL)


def test_an_append_that_returned_survives_sigkill(tmp_path):
    process = multiprocessing.get_context("fork").Process(target=_append_then_die,
                                                          args=(tmp_path, 25))
    process.start()
    process.join(10)
    assert process.exitcode == -signal.SIGKILL
    assert len(Journal(tmp_path).unacknowledged()) == 25


def test_a_message_no_frame_claimed_can_be_cancelled_one_claimed_never(tmp_path):
    from bridge.transport.journal import TOMBSTONE, is_tombstone
    from bridge.wire import compact

    journal = Journal(tmp_path)
    first = journal.append(7, 1, compact.encode(["go", 1]))
    journal.append(7, 1, compact.encode(["go", 2]))
    journal.append(7, 0, compact.encode(["start", 3]))
    assert [q.seq for q in journal.unacknowledged(limit=1)] == [first]      # a frame took #1
    every = lambda payload: True  # noqa: E731
    cancelled, too_late = journal.cancel({FlowKey(7, 1)}, every)
    assert [compact.decode(p) for p in cancelled] == [["go", 2]]
    assert [compact.decode(p) for p in too_late] == [["go", 1]]
    assert [q.payload for q in journal.unacknowledged(claim=False)] == [
        compact.encode(["go", 1]), TOMBSTONE, compact.encode(["start", 3])]   # numbers kept
    assert is_tombstone(compact.decode(TOMBSTONE))
    assert journal.cancel({FlowKey(7, 1)}, every) == ([], [compact.encode(["go", 1])])  # once
    journal.close()
    again = Journal(tmp_path)                 # the claim survives a restart of the bridge
    assert again.cancel({FlowKey(7, 0), FlowKey(7, 1)}, every) == ([compact.encode(["start", 3])],
                                                      [compact.encode(["go", 1])])
