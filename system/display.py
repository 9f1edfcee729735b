"""A private X display (Xvfb) for the Pilot Interface's tests and benchmark."""

from __future__ import annotations

import os
import shutil
import subprocess
from contextlib import contextmanager
from typing import Dict, Iterator


def display_env(display: str) -> Dict[str, str]:
    """What a program needs in its environment to draw on ``display`` with librviz: Qt's
    X11 platform too (an inherited ``QT_QPA_PLATFORM=offscreen`` made librviz abort)."""
    return {"DISPLAY": display, "QT_QPA_PLATFORM": "xcb"}


class DisplayError(RuntimeError):
    """Xvfb is missing or did not start."""


@contextmanager
def private_display(size: str = "1400x900x24") -> Iterator[str]:
    """Start Xvfb on a display number it picks itself; yields ``:N``, stops it after."""
    if shutil.which("Xvfb") is None:
        raise DisplayError("Xvfb is not installed (Debian package xvfb)")
    read, write = os.pipe()
    server = subprocess.Popen(["Xvfb", "-displayfd", str(write), "-screen", "0", size,
                               "-nolisten", "tcp"], pass_fds=(write,),
                              stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    os.close(write)
    with os.fdopen(read) as pipe:
        number = pipe.readline().strip()
    try:
        if not number.isdigit():
            server.kill()
            raise DisplayError(f"Xvfb did not say its display number: "
                               f"{server.communicate(timeout=10)[1].decode(errors='replace')}")
        yield f":{number}"
    finally:
        if server.poll() is None:
            server.terminate()
            server.wait(10)
