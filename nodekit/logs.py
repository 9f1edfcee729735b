"""Log lines a user can read on stderr, tagged with the program that wrote them."""

from __future__ import annotations

import logging
import os
from typing import Sequence

#: The loggers of our layers; third-party ones (rospy's) keep their own handlers.
OUR_LOGGERS = ("bridge", "yarp_lite", "walkman", "rosnodes", "nodekit", "pilot")
#: Set (to anything but "" or 0) to begin every line with its wall-clock time in seconds,
#: so lines of several programs can be put in one order (``bench/bench_pilot.py`` does).
LOG_TIME_ENV = "WALKMAN_LOG_TIME"


def time_prefix() -> str:
    """The start of a log format: the line's time when :data:`LOG_TIME_ENV` asks, else ""."""
    return "%(created).6f " if os.environ.get(LOG_TIME_ENV, "") not in ("", "0") else ""


def line_format(tag: str) -> str:
    """``[tag] LEVEL logger: message`` (after the time when :data:`LOG_TIME_ENV` asks)."""
    return f"{time_prefix()}[{tag}] %(levelname)s %(name)s: %(message)s"


def configure_logging(tag: str, verbose: bool = False,
                      names: Sequence[str] = OUR_LOGGERS, line: str = "") -> None:
    """Our loggers print ``[tag] LEVEL logger: message`` (or ``line``, a logging format) to
    stderr, not through the root's.

    rospy.init_node (in a background thread) replaces the root logger's
    handlers with its log files; our lines must keep coming meanwhile.
    """
    handler = logging.StreamHandler()
    handler.setFormatter(logging.Formatter(line or line_format(tag)))
    for name in names:
        logger = logging.getLogger(name)
        for old in [h for h in logger.handlers if getattr(h, "_nodekit", False)]:
            logger.removeHandler(old)
        handler._nodekit = True  # type: ignore[attr-defined]
        logger.addHandler(handler)
        logger.setLevel(logging.DEBUG if verbose else logging.INFO)
        logger.propagate = False
