"""yarp_lite.cli's output: what a user or a script reading a tool's stdout sees."""
from __future__ import annotations

import io
from typing import List

import pytest

from yarp_lite import cli


class RecordingPipe(io.RawIOBase):
    """The write end of a pipe: remembers each write as one chunk, as the kernel would."""

    def __init__(self) -> None:
        self.chunks: List[bytes] = []

    def writable(self) -> bool:
        return True

    def write(self, data) -> int:
        self.chunks.append(bytes(data))
        return len(data)


def test_a_line_leaves_in_one_write_on_an_unbuffered_stdout(monkeypatch: pytest.MonkeyPatch):
    # PYTHONUNBUFFERED's stdout: no buffer, text written through. A log line from another
    # thread on the same pipe can only land between writes, never inside one.
    pipe = RecordingPipe()
    monkeypatch.setattr("sys.stdout", io.TextIOWrapper(pipe, write_through=True))
    cli.out("1 30.0 2 0.1 0.2")
    cli.out()
    assert pipe.chunks == [b"1 30.0 2 0.1 0.2\n", b"\n"]
