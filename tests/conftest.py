"""Shared fixtures: isolated YARP worlds, the reference YARP, process cleanup."""

from __future__ import annotations

import logging
import sys
from pathlib import Path

import pytest

sys.path.append(str(Path(__file__).resolve().parent))

from harness import (YarpWorld, lite_implementation, missing_reference,  # noqa: E402
                     real_implementation)


@pytest.fixture
def lite():
    return lite_implementation()


@pytest.fixture
def reference():
    impl = real_implementation()
    if impl is None:
        missing_reference()
    return impl


@pytest.fixture
def implementations(lite):
    """Both implementations when the reference is built, else only yarp_lite."""
    real = real_implementation()
    return {"yarp_lite": lite, "yarp": real}


@pytest.fixture
def make_world(tmp_path):
    worlds = []

    def factory(server_impl, name: str = "world", start: bool = True) -> YarpWorld:
        world = YarpWorld(tmp_path / f"{name}{len(worlds)}", server_impl)
        worlds.append(world)
        if start:
            world.start_server()
        return world

    yield factory
    for world in worlds:
        world.close()


@pytest.fixture
def lite_world(make_world, lite, monkeypatch):
    """A yarp_lite name server, with this test process pointed at it."""
    world = make_world(lite)
    world.apply_to_process(monkeypatch)
    return world


@pytest.fixture(autouse=True)
def _quiet_logs(caplog):
    caplog.set_level(logging.INFO, logger="yarp_lite")
