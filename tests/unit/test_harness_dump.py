"""tests/harness.dump_outputs_if_failed: a failed test keeps what its programs said and how they ended."""

import os
import shutil
import sys
from types import SimpleNamespace

from harness import REPO, Proc, dump_outputs_if_failed, wait_until


def test_a_failed_tests_dump_says_which_program_vanished_and_how(capsys):
    name = f"test_dump_probe_{os.getpid()}"
    request = SimpleNamespace(node=SimpleNamespace(name=name,
                                                   report_call=SimpleNamespace(failed=True)))
    quiet = Proc([sys.executable, "-c", "import os, signal; print('serving', flush=True); "
                  "os.kill(os.getpid(), signal.SIGKILL)"], dict(os.environ), "victim")
    alive = Proc([sys.executable, "-c", "import time; print('up', flush=True); time.sleep(60)"],
                 dict(os.environ), "survivor")
    kept = REPO / "out" / "failed" / name
    try:
        quiet.wait(30)
        wait_until(lambda: alive.lines, timeout=30, message="the survivor's first line")
        dump_outputs_if_failed(request, [quiet, alive])
        printed = capsys.readouterr().out
        assert f"victim, pid {quiet.popen.pid}, was killed: signal 9 (SIGKILL)" in printed
        assert f"survivor, pid {alive.popen.pid}, running" in printed
        whole = (kept / "00-victim.log").read_text()
        assert whole.startswith("serving\n") and "was killed: signal 9 (SIGKILL)" in whole
    finally:
        alive.kill()
        shutil.rmtree(kept, ignore_errors=True)


def test_a_passing_test_leaves_nothing(capsys):
    name = f"test_dump_pass_{os.getpid()}"
    request = SimpleNamespace(node=SimpleNamespace(name=name,
                                                   report_call=SimpleNamespace(failed=False)))
    proc = Proc([sys.executable, "-c", "print('fine')"], dict(os.environ), "fine")
    proc.wait(30)
    dump_outputs_if_failed(request, [proc])
    assert capsys.readouterr().out == ""
    assert not (REPO / "out" / "failed" / name).exists()
