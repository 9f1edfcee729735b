"""The 3-D view's process layer with a stand-in child (tests/pilot/fake_view3d_child.py).

Qt offscreen, no ROS, no librviz: a child comes up, is told markers and answers
with drags; killed, it is started again at once and the next one is told the
dead one's ROS nodes; a deaf child is killed as hung; a child that cannot
start is retried later and later; a crash keeps its stacks, a kill keeps
nothing.  Every wait is for a condition.
"""

from __future__ import annotations

import logging
import os
import signal
import time
from typing import Callable, List, Tuple

import pytest

from pilot.view3d_process import (KEEP_CRASHES, ChildExit, CrashFolders, RenderSupervisor,
                                  RestartPolicy)
from pilot.view3d_protocol import AddMarker, MarkerMoved, RosNodes

FAKE = "tests.pilot.fake_view3d_child"


# -- pure parts -----------------------------------------------------------------------------

def test_a_view_that_was_up_restarts_at_once_one_that_cannot_start_waits_longer_each_time():
    policy = RestartPolicy()
    assert [policy.died(None) for _ in range(9)] == [0, 1, 2, 4, 8, 16, 30, 30, 30]
    assert policy.died(RestartPolicy.MIN_UP) == 0          # up long enough: the count resets
    assert policy.died(0.5) == 0                             # the first quick death: at once
    assert policy.died(0.5) == 1
    assert policy.died(60.0) == 0 and policy.died(None) == 0


def test_crash_folders_keep_evidence_remove_the_rest_and_prune_the_oldest(tmp_path):
    folders = CrashFolders(tmp_path)
    clean = folders.named_for(folders.new(), 100)
    (clean / "stacks.txt").write_text("")                    # faulthandler had nothing to say
    assert not folders.settle(clean) and not clean.exists()
    kept = []
    for pid in range(KEEP_CRASHES + 2):
        folder = folders.named_for(folders.new(), 200 + pid)
        (folder / "stacks.txt").write_text("Fatal Python error: Segmentation fault\n")
        if pid == 0:
            (folder / "core").write_bytes(b"\x7fELF")
            assert folders.evidence(folder) == [folder / "stacks.txt", folder / "core"]
        os.utime(folder, (1000 + pid, 1000 + pid))          # oldest first, whatever the clock
        assert folders.settle(folder)
        kept.append(folder)
    assert sorted(p for p in tmp_path.iterdir()) == sorted(kept[-KEEP_CRASHES:])


# -- the supervisor with a stand-in child ---------------------------------------------------

@pytest.fixture(scope="module")
def qt():
    from python_qt_binding.QtWidgets import QApplication

    return QApplication.instance() or QApplication(["test_view3d", "-platform", "offscreen"])


def wait_until(qt, predicate: Callable[[], object], timeout: float, what: str) -> None:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        qt.processEvents()
        if predicate():
            return
        time.sleep(0.01)
    raise AssertionError(f"timed out ({timeout:g} s) waiting for {what}")


class Watch:
    """What a supervisor said, in order."""

    def __init__(self, supervisor: RenderSupervisor) -> None:
        self.ups: List[Tuple[int, int]] = []
        self.downs: List[Tuple[ChildExit, float]] = []
        self.messages: List[object] = []
        supervisor.up.connect(lambda window, pid: self.ups.append((window, pid)))
        supervisor.down.connect(lambda exit, delay: self.downs.append((exit, delay)))
        supervisor.message.connect(self.messages.append)


@pytest.fixture
def supervisor(qt, tmp_path, monkeypatch):
    made = []

    def make(mode: str = "ok", standby: bool = False) -> Tuple[RenderSupervisor, Watch]:
        monkeypatch.setenv("FAKE_VIEW3D", mode)
        sup = RenderSupervisor("pi_t", "/pilot_markers/pi_t", CrashFolders(tmp_path / "crash"),
                               child_module=FAKE, standby=standby)
        made.append(sup)
        return sup, Watch(sup)

    yield make
    for sup in made:
        sup.close()


@pytest.mark.parametrize("standby", [False, True], ids=["new process", "warm spare"])
def test_a_killed_view_comes_back_at_once_and_the_next_is_told_the_dead_ones_nodes(
        qt, supervisor, tmp_path, standby):
    sup, watch = supervisor(standby=standby)
    sup.start()
    wait_until(qt, lambda: watch.ups, 30, "the child's window")
    first = sup.pid
    assert watch.ups == [(4242, first)]
    sup.send(AddMarker("drc_valve", (0.5, 0.1, 0.0, 0.0, 0.0, 1.0)))
    seq = sup.ping()
    wait_until(qt, lambda: sup.answered_seq >= seq, 10, "the child's answer to our ping")
    # one ordered stream: the pong came after everything sent before it was handled
    assert MarkerMoved("drc_valve", (1.5, 0.1, 0.0, 0.0, 0.0, 1.0)) in watch.messages
    wait_until(qt, lambda: sup.nodes is not None, 10, "the child's ROS nodes")
    assert sup.nodes == RosNodes(f"/pi_t_view3d_{first}", {f"/rviz_{first}": "http://127.0.0.1:1/"})
    spare = sup.spare.pid if standby else None
    assert (sup.spare is not None) == standby     # started once the view was up

    os.kill(first, signal.SIGKILL)
    wait_until(qt, lambda: watch.downs, 10, "the death")
    exit, delay = watch.downs[0]
    assert (exit.pid, exit.reason, exit.folder, delay) == \
        (first, "was killed: signal 9 (SIGKILL)", None, 0.0)
    assert sup.forget == [f"/pi_t_view3d_{first}", f"/rviz_{first}"]
    wait_until(qt, lambda: len(watch.ups) == 2, 30, "the next child's window")
    assert watch.ups[1][1] == sup.pid != first
    if standby:
        assert sup.pid == spare and sup.spare is not None and sup.spare.pid != spare
    assert not list((tmp_path / "crash").glob(f"pid{first}-*")), "a kill leaves no evidence"


def test_a_view_that_stops_answering_is_killed_as_hung_and_started_again(qt, supervisor):
    sup, watch = supervisor("deaf")
    sup.ping_every, sup.hang_after = 0.1, 0.5
    sup.start()
    wait_until(qt, lambda: watch.downs, 30, "the hung child killed")
    exit, delay = watch.downs[0]
    assert exit.reason.startswith("hung: no answer for") and exit.returncode == -9, exit
    wait_until(qt, lambda: len(watch.ups) == 2, 30, "its successor")


def test_a_view_that_breaks_the_protocol_is_killed_saying_so(qt, supervisor):
    sup, watch = supervisor("garbage")
    sup.start()
    wait_until(qt, lambda: watch.downs, 30, "the child killed")
    exit, _ = watch.downs[0]
    assert exit.returncode == -9 and exit.reason.startswith(
        "broke the protocol: child -> PI: not a JSON line"), exit


def test_a_view_that_cannot_start_is_tried_again_later_and_later(qt, supervisor):
    sup, watch = supervisor("exit")
    sup.start()
    wait_until(qt, lambda: len(watch.downs) >= 2, 30, "two failed starts")
    assert [(e.reason, e.up_for, delay) for e, delay in watch.downs[:2]] == \
        [("exited: status 3", None, 0.0), ("exited: status 3", None, 1.0)]
    assert not watch.ups


def test_a_crash_keeps_its_stacks_and_the_log_shows_them(qt, supervisor, tmp_path, caplog):
    sup, watch = supervisor("segv")
    with caplog.at_level(logging.WARNING, logger="pilot.view3d"):
        sup.start()
        wait_until(qt, lambda: watch.downs, 30, "the crash")
    exit, _ = watch.downs[0]
    assert exit.reason == "crashed: signal 11 (SIGSEGV)" and exit.folder is not None
    assert "Fatal Python error: Segmentation fault" in (exit.folder / "stacks.txt").read_text()
    text = caplog.text
    assert f"3-D view (pid {exit.pid}) crashed: signal 11 (SIGSEGV)" in text
    assert "kept stacks.txt in" in text and "3-D view's stacks: Fatal Python error" in text


def test_closing_lets_the_view_quit_and_removes_its_folder(qt, supervisor, tmp_path):
    sup, watch = supervisor()
    sup.start()
    wait_until(qt, lambda: watch.ups, 30, "the child's window")
    pid, folder = sup.pid, sup.folder
    sup.close()
    assert not folder.exists()
    with pytest.raises(ProcessLookupError):
        os.kill(pid, 0)                   # reaped, not a zombie
    qt.processEvents()
    assert not watch.downs                # a close is no death to report
