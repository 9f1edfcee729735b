"""Picking TCP port numbers for servers started by launchers, tests and benchmarks.

Numbers come from below the kernel's ephemeral range (32768 and up on Linux):
there, an outgoing connection can take a number between the check and the
moment a server (or the ports it hands numbers to) binds it.
"""

from __future__ import annotations

import random
import socket


def is_free(port: int, host: str = "127.0.0.1") -> bool:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        try:
            probe.bind((host, port))
            return True
        except OSError:
            return False


def free_port(span: int = 1, start: int = 11000, end: int = 32000) -> int:
    """A port such that ``port .. port + span - 1`` are all free right now."""
    for _ in range(500):
        base = random.randrange(start, end - span)
        if all(is_free(base + offset) for offset in range(span)):
            return base
    raise RuntimeError(f"no run of {span} free TCP ports between {start} and {end}")
