"""Text Bottles read over several lines: joined as YARP joins them, and bounded."""

from __future__ import annotations

from typing import List

import pytest

from yarp_lite.carriers.base import (MAX_CONTINUATION_LINES, MAX_CONTINUED_TEXT,
                                     read_text_bottle)
from yarp_lite.errors import RemoteProtocolError


class Lines:
    where = "test stream"

    def __init__(self, lines: List[str]) -> None:
        self.lines = list(lines)
        self.read = 0

    def read_line(self, limit: int = 1 << 20) -> str:
        self.read += 1
        return self.lines.pop(0)


def test_open_lists_and_backslashes_continue_a_bottle():
    assert read_text_bottle(Lines(["(1 2", "3) 4"])) == "(1 2\n3) 4"
    assert read_text_bottle(Lines(["a \\", "b", "next"])) == "a b"


@pytest.mark.parametrize("lines", [["("] * (MAX_CONTINUATION_LINES + 5),
                                   ["(" + "x" * 40_000] * 3])
def test_an_endless_bottle_is_refused_not_read_forever(lines):
    stream = Lines(lines)
    with pytest.raises(RemoteProtocolError, match="unclosed list"):
        read_text_bottle(stream)
    assert stream.read <= MAX_CONTINUATION_LINES and MAX_CONTINUED_TEXT < 3 * 40_000
