"""tests/robot_slots.py: a test alone, free-standing or with two PCs has the machine to itself,
machine-wide; a dead holder frees it; a test that runs no real-time thread holds nothing."""

from __future__ import annotations

import fcntl
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import List, Optional

import pytest

from robot_slots import (NO_REAL_TIME_FOLDERS, Share, arranged, machine_share, machine_to_itself,
                         no_real_time, one_share_per_fixture, share_of)
from walkman.realtime import realtime_refused

TESTS = Path(__file__).resolve().parents[1]
def trying(code: str) -> subprocess.Popen:
    """A child process running ``code``, once it says it is trying for its lock."""
    child = subprocess.Popen([sys.executable, "-c", code], stdin=subprocess.PIPE,
                             stdout=subprocess.PIPE, text=True)
    assert child.stdout.readline().strip() == "trying"
    return child


def blocked_on_a_lock(pid: int) -> bool:
    """/proc/locks lists a process waiting for a lock on a ``->`` line."""
    return any("->" in line and f" {pid} " in f" {line} " for line in
               Path("/proc/locks").read_text().splitlines())


def wait_for(predicate, what: str, timeout: float = 30.0) -> None:
    end = time.monotonic() + timeout
    while not predicate():
        assert time.monotonic() < end, f"{what} not seen in {timeout} s"
        time.sleep(0.01)


def machine_free(folder: Path) -> bool:
    with open(folder / "machine.lock", "a+") as handle:
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            return False
        fcntl.flock(handle, fcntl.LOCK_UN)
        return True


SHARER = """
import sys
sys.path.insert(0, {tests!r})
from pathlib import Path
from robot_slots import machine_share
print("trying", flush=True)
with machine_share({alone!r}, Path({folder!r})):
    print("got", flush=True)
    sys.stdin.readline()          # hold until the test says
"""


def sharer(folder: Path, alone: bool) -> subprocess.Popen:
    return trying(SHARER.format(tests=str(TESTS), folder=str(folder), alone=alone))


def let_go(child: subprocess.Popen) -> None:
    child.stdin.write("\n")
    child.stdin.flush()
    assert child.wait(timeout=30) == 0


def test_a_test_alone_waits_for_the_shared_ones_and_goes_before_any_that_come_later(tmp_path):
    """The ``alone`` mark (tests/conftest.py): the PI's free-standing terrain course has the
    machine to itself; a test on another worker that starts meanwhile waits for it."""
    first = sharer(tmp_path, alone=False)
    second = sharer(tmp_path, alone=False)
    children = [first, second]
    try:
        for child in children:                            # shared: both at once
            assert child.stdout.readline().strip() == "got"
        lonely = sharer(tmp_path, alone=True)
        children.append(lonely)
        wait_for(lambda: blocked_on_a_lock(lonely.pid), "the lonely test waiting")
        later = sharer(tmp_path, alone=False)
        children.append(later)
        wait_for(lambda: blocked_on_a_lock(later.pid), "a later shared test waiting")
        let_go(first)
        let_go(second)
        assert lonely.stdout.readline().strip() == "got"   # before the later one
        wait_for(lambda: blocked_on_a_lock(later.pid), "the later test still waiting")
        let_go(lonely)
        assert later.stdout.readline().strip() == "got"
        let_go(later)
    finally:
        for child in children:
            if child.poll() is None:
                child.kill()



def test_a_killed_holder_frees_the_machine(tmp_path):
    child = sharer(tmp_path, alone=True)
    assert child.stdout.readline().strip() == "got"
    assert not machine_free(tmp_path)
    os.kill(child.pid, signal.SIGKILL)
    child.wait(30)
    with machine_share(True, tmp_path) as waited:
        assert waited < 5


def test_the_folder_is_shared_and_a_lock_file_made_by_another_user_serves(tmp_path):
    folder = tmp_path / "slots"
    with machine_share(True, folder):
        pass
    assert folder.stat().st_mode & 0o7777 == 0o1777
    for name in ("machine.lock", "turnstile.lock"):
        os.chmod(folder / name, 0o444)                  # as another user's file looks to us
    with machine_share(True, folder) as waited:
        assert waited < 5


@pytest.mark.parametrize("marks, alone", [({"free_standing"}, True), ({"alone"}, True),
                                          ({"two_pcs"}, True),
                                          ({"free_standing", "alone", "two_pcs"}, True),
                                          (set(), False), ({"requires", "parametrize"}, False)])
def test_a_robot_on_its_own_feet_or_two_pcs_have_the_machine_to_themselves(marks, alone):
    """A free-standing robot's real-time threads take about a core, a two-PC topology's
    1.1-1.5: beside another robot's, a CPU crosses the kernel's real-time budget and the
    fair server stalls them 50 ms at once."""
    assert machine_to_itself(iter(marks)) is alone


@pytest.mark.parametrize("marks, folder, share", [
    ({"two_pcs"}, "system", Share.ALONE), ({"alone"}, "unit", Share.ALONE),
    (set(), "system", Share.SHARED), (set(), "walkman", Share.SHARED),
    (set(), "bridge", Share.SHARED), ({"requires"}, "packaging", Share.SHARED),
    ({"requires", "real_time"}, "interop", Share.SHARED),
    (set(), "unit", Share.NONE), ({"requires"}, "interop", Share.NONE),
    (set(), "pilot", Share.NONE), ({"offline"}, "modules", Share.NONE),
    ({"offline", "free_standing"}, "modules", Share.ALONE)])
def test_a_test_that_runs_no_real_time_thread_holds_nothing(marks, folder, share):
    assert share_of(iter(marks), folder) is share


def test_the_folders_said_to_run_no_real_time_thread_exist():
    assert all((TESTS / folder).is_dir() for folder in NO_REAL_TIME_FOLDERS)


def test_the_second_worker_begins_with_the_tests_that_hold_nothing():
    """xdist's work stealing hands worker 0 the first len // 2 tests, worker 1 the rest."""
    kinds = {"a": Share.ALONE, "s": Share.SHARED, "n": Share.NONE}
    items = [f"{kind}{i}" for i, kind in enumerate("snasnsssnnasss")]
    order = arranged(items, lambda item: kinds[item[0]], 2)
    assert sorted(order) == sorted(items)
    first, second = order[:len(items) // 2], order[len(items) // 2:]
    assert first == ["a2", "a10", "s0", "s3", "s5", "s6", "s7"]
    assert second == ["n1", "n4", "n8", "n9", "s11", "s12", "s13"]
    assert arranged(items, lambda item: kinds[item[0]], 1) == \
        ["a2", "a10", "s0", "s3", "s5", "s6", "s7", "s11", "s12", "s13", "n1", "n4", "n8", "n9"]


def test_more_tests_alone_than_a_worker_s_part_still_come_first():
    kinds = {"a": Share.ALONE, "s": Share.SHARED, "n": Share.NONE}
    order = arranged(["n0", "a1", "a2", "s3", "a4"], lambda item: kinds[item[0]], 2)
    assert order == ["a1", "a2", "a4", "n0", "s3"]


def test_while_a_test_holds_nothing_no_thread_of_it_or_its_programs_becomes_real_time(
        monkeypatch):
    """Run as a test that holds nothing, this test already has WALKMAN_NO_RT: taken away
    first, so that only no_real_time can set it.  The grant is asked in a thread of its
    own, which ends: were it granted, no thread of the worker would stay real-time."""
    monkeypatch.delenv("WALKMAN_NO_RT", raising=False)

    def refusal() -> Optional[str]:
        answer: List[Optional[str]] = []
        asker = threading.Thread(target=lambda: answer.append(realtime_refused(10)))
        asker.start()
        asker.join()
        return answer[0]

    with no_real_time():
        assert refusal() == "WALKMAN_NO_RT is set"
        child = subprocess.run([sys.executable, "-c",
                                "import os; print(os.environ.get('WALKMAN_NO_RT'))"],
                               capture_output=True, text=True, check=True)
        assert child.stdout.strip() == "1"
    assert "WALKMAN_NO_RT" not in os.environ
    monkeypatch.setenv("WALKMAN_NO_RT", "before")
    with no_real_time():
        pass
    assert os.environ["WALKMAN_NO_RT"] == "before"


def test_a_fixture_wider_than_a_test_serves_tests_of_one_share():
    one_share_per_fixture([("m.py::robot", "m.py::a", Share.SHARED),
                           ("m.py::robot", "m.py::b", Share.SHARED),
                           ("n.py::cloud", "n.py::c", Share.NONE)])
    with pytest.raises(ValueError, match=r"m.py::robot serves m.py::a \(shared\), "
                                         r"m.py::c \(none\)"):
        one_share_per_fixture([("m.py::robot", "m.py::a", Share.SHARED),
                               ("m.py::robot", "m.py::b", Share.SHARED),
                               ("m.py::robot", "m.py::c", Share.NONE)])
