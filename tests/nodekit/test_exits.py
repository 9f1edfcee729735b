"""nodekit.exits: one phrase for a child's end."""

import pytest

from nodekit.exits import describe_exit


@pytest.mark.parametrize("returncode, said", [
    (-11, "crashed: signal 11 (SIGSEGV)"), (-6, "crashed: signal 6 (SIGABRT)"),
    (-9, "was killed: signal 9 (SIGKILL)"), (-15, "was killed: signal 15 (SIGTERM)"),
    (0, "exited"), (3, "exited: status 3"), (-200, "crashed: signal 200 (unknown)"),
    (None, "running")])
def test_an_exit_is_described_by_its_signal_or_status(returncode, said):
    assert describe_exit(returncode) == said
