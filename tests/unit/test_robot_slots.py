"""tests/robot_slots.py: two-PC topologies take turns, machine-wide; a free-standing robot
has the machine to itself; a dead holder frees its slot."""

from __future__ import annotations

import fcntl
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from robot_slots import machine_to_itself, slots, two_pcs_slot

TESTS = Path(__file__).resolve().parents[1]
HOLDER = """
import sys, time
sys.path.insert(0, {tests!r})
from pathlib import Path
from robot_slots import two_pcs_slot
print("trying", flush=True)
with two_pcs_slot(Path({folder!r}), count={count}) as waited:
    print("got", time.monotonic(), waited, flush=True)
    sys.stdin.readline()          # hold until the test says
"""


def holder(folder: Path, count: int) -> subprocess.Popen:
    return trying(HOLDER.format(tests=str(TESTS), folder=str(folder), count=count))


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


def free(folder: Path, index: int) -> bool:
    with open(folder / f"two-pcs-{index}.lock", "a+") as handle:
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            return False
        fcntl.flock(handle, fcntl.LOCK_UN)
        return True


@pytest.mark.parametrize("cores, expected", [(None, None), (1, 1), (2, 1), (3, 1), (4, 2),
                                             (16, 8)])
def test_one_slot_per_two_cores_and_never_none(cores, expected):
    if cores is None:
        assert slots() == max(1, (os.cpu_count() or 1) // 2)
    else:
        assert slots(cores) == expected


def test_a_second_robot_waits_until_the_first_lets_go(tmp_path):
    with two_pcs_slot(tmp_path, count=1) as waited:
        assert waited < 5
        child = holder(tmp_path, 1)
        try:
            wait_for(lambda: blocked_on_a_lock(child.pid), "the second holder blocked")
            released_at = time.monotonic()
        except BaseException:
            child.kill()
            raise
    try:
        word, got_at, child_waited = child.stdout.readline().split()
        assert word == "got" and float(got_at) >= released_at
        assert float(child_waited) > 0
    finally:
        child.communicate("\n", timeout=30)


def test_two_slots_hold_two_robots_and_a_third_waits(tmp_path):
    with two_pcs_slot(tmp_path, count=2), two_pcs_slot(tmp_path, count=2):
        assert not free(tmp_path, 0) and not free(tmp_path, 1)
        third = holder(tmp_path, 2)
        try:
            wait_for(lambda: blocked_on_a_lock(third.pid), "the third holder blocked")
        finally:
            third.kill()
            third.wait(30)
    assert free(tmp_path, 0) and free(tmp_path, 1)


def test_a_killed_holder_frees_its_slot(tmp_path):
    child = holder(tmp_path, 1)
    assert child.stdout.readline().startswith("got")
    assert not free(tmp_path, 0)
    os.kill(child.pid, signal.SIGKILL)
    child.wait(30)
    with two_pcs_slot(tmp_path, count=1) as waited:
        assert waited < 5


def test_the_folder_is_shared_and_a_slot_file_made_by_another_user_serves(tmp_path):
    folder = tmp_path / "slots"
    with two_pcs_slot(folder, count=1):
        pass
    assert folder.stat().st_mode & 0o7777 == 0o1777
    lock = folder / "two-pcs-0.lock"
    os.chmod(lock, 0o444)                         # as another user's file looks to us
    with two_pcs_slot(folder, count=1) as waited:
        assert waited < 5


def test_no_slots_is_a_clear_error(tmp_path):
    with pytest.raises(ValueError, match="at least one two-PC slot, not 0"):
        with two_pcs_slot(tmp_path, count=0):
            pass


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



@pytest.mark.parametrize("marks, alone", [({"free_standing"}, True), ({"alone"}, True),
                                          ({"free_standing", "alone", "two_pcs"}, True),
                                          ({"two_pcs"}, False), (set(), False),
                                          ({"requires", "parametrize"}, False)])
def test_a_free_standing_robot_has_the_machine_to_itself(marks, alone):
    """Its real-time threads take about a core: beside a second robot's, a CPU crosses the
    kernel's real-time budget and the fair server stalls them 50 ms at once."""
    assert machine_to_itself(iter(marks)) is alone
