"""Log lines a user can read on stderr, tagged with the program that wrote them."""

from __future__ import annotations

import logging
from typing import Sequence

#: The loggers of our layers; third-party ones (rospy's) keep their own handlers.
OUR_LOGGERS = ("bridge", "yarp_lite", "walkman", "rosnodes", "nodekit", "pilot")


def configure_logging(tag: str, verbose: bool = False,
                      names: Sequence[str] = OUR_LOGGERS) -> None:
    """Our loggers print ``[tag] LEVEL logger: message`` to stderr, not through the root's.

    rospy.init_node (in a background thread) replaces the root logger's
    handlers with its log files; our lines must keep coming meanwhile.
    """
    handler = logging.StreamHandler()
    handler.setFormatter(logging.Formatter(f"[{tag}] %(levelname)s %(name)s: %(message)s"))
    for name in names:
        logger = logging.getLogger(name)
        for old in [h for h in logger.handlers if getattr(h, "_nodekit", False)]:
            logger.removeHandler(old)
        handler._nodekit = True  # type: ignore[attr-defined]
        logger.addHandler(handler)
        logger.setLevel(logging.DEBUG if verbose else logging.INFO)
        logger.propagate = False
