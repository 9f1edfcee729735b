"""nodekit.stacks: every thread's stack on SIGUSR1, in faulthandler's format, and the
process lives on whatever its threads are doing."""

from __future__ import annotations

import signal
import subprocess
import sys
import threading
import time

from nodekit.stacks import format_stacks, print_stacks

CHILD = r"""
import importlib, sys, threading, time
from nodekit import stacks
stacks.on_signals()
def churn():                       # imports, again and again: frames come and go
    while True:
        for name in ("json", "csv", "textwrap", "fractions"):
            sys.modules.pop(name, None)
            importlib.import_module(name)
threading.Thread(target=churn, name="churn", daemon=True).start()
print("ready", flush=True)
time.sleep(120)
"""


def parked(event: threading.Event) -> None:
    event.wait()


def test_every_thread_is_listed_most_recent_call_first_with_its_name():
    event = threading.Event()
    thread = threading.Thread(target=parked, args=(event,), name="parker", daemon=True)
    thread.start()
    try:
        text = format_stacks(sys._current_frames(),
                             {t.ident: t.name for t in threading.enumerate()},
                             threading.get_ident())
    finally:
        event.set()
    block = next(b for b in text.split("\n\n") if '"parker"' in b)
    lines = block.splitlines()
    assert lines[0] == f'Thread 0x{thread.ident:016x} "parker" (most recent call first):'
    assert lines[1].endswith(" in wait")                     # where it is now, first
    assert any(line.endswith(" in parked") for line in lines)
    assert text.startswith(("Thread 0x", "Current thread 0x"))
    assert "Current thread 0x" in text and " in test_every_thread_is_listed" in text


def test_print_stacks_writes_to_the_stream_given(tmp_path):
    with open(tmp_path / "out.txt", "w") as stream:
        print_stacks(stream)
    assert "(most recent call first):" in (tmp_path / "out.txt").read_text()


def test_a_process_asked_a_hundred_times_while_a_thread_imports_lives_and_answers_each():
    """faulthandler's dump of all threads, from inside the signal, once killed a module
    with SIGSEGV while its connector thread was importing."""
    child = subprocess.Popen([sys.executable, "-c", CHILD], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True)
    try:
        assert child.stdout.readline().strip() == "ready"
        for _ in range(100):
            child.send_signal(signal.SIGUSR1)
            time.sleep(0.005)
        assert child.poll() is None, child.stderr.read()
    finally:
        child.kill()
        _, err = child.communicate(timeout=30)
    assert err.count('"churn" (most recent call first):') >= 1, err[-2000:]
    assert "Fatal Python error" not in err
