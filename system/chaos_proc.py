"""What /proc says about a chaos run's processes: leaks (and their sockets), names.

Theory of operation
-------------------
Every program a run starts carries ``WALKMAN_CHAOS_RUN=<id>`` in its
environment (:data:`MARKER`); children inherit it, daemons that double-fork
too.  After the cleanup, any living process whose ``/proc/<pid>/environ``
holds the run's marker is a leak (:func:`marked`), whatever its parent or
session, and so is every listening TCP or bound UDP socket it holds
(:func:`sockets`, from its own ``/proc/<pid>/net``: the emulated hosts'
namespaces included).  Zombies are not leaks: their parent reaps them.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Dict, List

from system.processes import WaitTimeout, wait_until

MARKER = "WALKMAN_CHAOS_RUN"


def marked(marker: str) -> List[dict]:
    """Living processes (not zombies) whose environment carries this run's marker."""
    needle = f"{MARKER}={marker}".encode()
    found = []
    for entry in os.listdir("/proc"):
        if not entry.isdigit() or int(entry) == os.getpid():
            continue
        try:
            if needle not in Path(f"/proc/{entry}/environ").read_bytes().split(b"\0"):
                continue
            state = Path(f"/proc/{entry}/stat").read_text().rsplit(")", 1)[1].split()[0]
            command = Path(f"/proc/{entry}/cmdline").read_bytes().replace(b"\0", b" ")
        except (FileNotFoundError, ProcessLookupError, PermissionError, IndexError):
            continue
        if state != "Z":
            found.append({"pid": int(entry), "cmdline": command.decode(errors="replace")[:300]})
    return found


def sockets(pid: int) -> List[str]:
    """The listening TCP and bound UDP sockets a process holds, in its network namespace."""
    inodes = set()
    try:
        fds = os.listdir(f"/proc/{pid}/fd")
    except (FileNotFoundError, ProcessLookupError, PermissionError):
        return []
    for fd in fds:
        try:
            link = os.readlink(f"/proc/{pid}/fd/{fd}")
        except (FileNotFoundError, ProcessLookupError):
            continue  # closed meanwhile
        if link.startswith("socket:["):
            inodes.add(link[len("socket:["):-1])
    out = []
    for proto in ("tcp", "tcp6", "udp", "udp6"):
        try:
            rows = Path(f"/proc/{pid}/net/{proto}").read_text().splitlines()[1:]
        except OSError:
            continue
        for row in rows:
            cols = row.split()
            listening = cols[3] == "0A" if proto.startswith("tcp") else cols[3] == "07"
            if listening and cols[9] in inodes:
                out.append(f"{proto} port {int(cols[1].rsplit(':', 1)[1], 16)} (pid {pid})")
    return out


def leaks(marker: str, link) -> Dict[str, list]:
    """What outlived the cleanup: processes, their sockets, the emulated hosts."""
    try:  # the cleanup's last SIGKILLs take a moment to land
        wait_until(lambda: not marked(marker), 5.0, interval=0.1)
    except WaitTimeout:
        pass  # counted below
    processes = marked(marker)
    ports = [s for p in processes for s in sockets(p["pid"])]
    namespaces = [link.namespace(side) for side in ("robot", "pilot")
                  if link is not None and link.exists()]
    return {"processes": processes, "ports": ports, "namespaces": namespaces}


def comm(pid: int) -> str:
    """A process's short name (``python3``, ``rosmaster``), or ``?`` once it is gone."""
    try:
        return Path(f"/proc/{pid}/comm").read_text().strip()
    except OSError:
        return "?"
