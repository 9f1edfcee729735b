"""What /proc says about a chaos run (system/chaos_proc.py): a real marked process and its port."""

from __future__ import annotations

import os
import subprocess
import sys

from system import chaos_proc
from system.processes import wait_until


def test_a_marked_process_and_its_port_are_found_as_leaks():
    marker = f"test{os.getpid()}"
    listener = subprocess.Popen(
        [sys.executable, "-c", "import socket, sys, time\n"
         "s = socket.socket(); s.bind(('127.0.0.1', 0)); s.listen()\n"
         "print(s.getsockname()[1], flush=True); time.sleep(60)"],
        env={**os.environ, chaos_proc.MARKER: marker}, stdout=subprocess.PIPE, text=True)
    try:
        port = int(listener.stdout.readline())
        assert [p["pid"] for p in chaos_proc.marked(marker)] == [listener.pid]
        assert chaos_proc.sockets(listener.pid) == [f"tcp port {port} (pid {listener.pid})"]
        assert chaos_proc.marked("another-run") == []
    finally:
        listener.kill()
        listener.wait()
    wait_until(lambda: not chaos_proc.marked(marker), 5, message="the listener gone")
    assert chaos_proc.leaks(marker, None) == {"processes": [], "ports": [], "namespaces": []}
