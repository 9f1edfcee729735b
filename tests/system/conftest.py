"""Fixtures for the system tests: PCs (name-server pairs) in temporary folders."""

import pytest

from harness import dump_outputs_if_failed
from system.topology import Pc
from walkman.modules.witness import LOG_VARIABLE


@pytest.fixture
def make_pc(tmp_path, request):
    """Factory of :class:`system.topology.Pc`; all closed (and explained on failure) after."""
    pcs = []

    def factory(name: str = "pc") -> Pc:
        pc = Pc(name, tmp_path / name)
        pcs.append(pc)
        return pc

    yield factory
    for pc in pcs:
        dump_outputs_if_failed(request, pc.processes.values())
        pc.close()


@pytest.fixture
def counter(tmp_path, monkeypatch):
    """The witness module's log (``walkman-module witness``): what it executes."""
    log = tmp_path / "executed.log"
    monkeypatch.setenv(LOG_VARIABLE, str(log))
    return log
