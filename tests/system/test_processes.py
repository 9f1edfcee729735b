"""The child-process helper every launcher and process test stands on."""

from __future__ import annotations

import os
import sys

from system.processes import Proc


def test_a_line_that_is_not_utf8_is_shown_escaped_and_later_lines_still_arrive() -> None:
    """fc29: a stray 0xff in a PI's output killed the reader, and the PI's DONE was never seen."""
    script = ("import sys; sys.stdout.buffer.write(b'ogre \\xff\\xfe said\\n'); "
              "sys.stdout.flush(); print('DONE', flush=True)")
    proc = Proc([sys.executable, "-c", script], dict(os.environ), "stray-bytes")
    try:
        proc.wait_for("DONE", timeout=30)
        assert proc.wait(timeout=30) == 0
        assert proc.lines[0] == "ogre \\xff\\xfe said"
    finally:
        proc.kill()
