"""Shared fixtures: isolated YARP worlds, the reference YARP, process cleanup."""

from __future__ import annotations

import logging
import os
import sys
from pathlib import Path

import pytest

from nodekit.logs import OUR_LOGGERS
from hypothesis import HealthCheck, settings

# Hypothesis profiles.  Two busy cores: a generated case may take longer than the 200 ms
# default deadline, so none has one.
#   dev  -- the default: randomised, the example database remembers failures.
#   ci   -- derandomised (the same examples every run, so a red CI is reproducible and a
#           green one is not luck), no database; chosen when CI is set.
#   fuzz -- many more randomised examples, for a long hand run (fuzz/README.md).
# WALKMAN_HYPOTHESIS_PROFILE (or HYPOTHESIS_PROFILE) names one explicitly.
settings.register_profile("dev", deadline=None)
settings.register_profile("ci", deadline=None, derandomize=True, database=None,
                          print_blob=True)
settings.register_profile("fuzz", deadline=None, max_examples=20_000,
                          suppress_health_check=[HealthCheck.too_slow,
                                                 HealthCheck.data_too_large])
settings.load_profile(os.environ.get("WALKMAN_HYPOTHESIS_PROFILE")
                      or os.environ.get("HYPOTHESIS_PROFILE")
                      or ("ci" if os.environ.get("CI") else "dev"))

sys.path.append(str(Path(__file__).resolve().parent))

from harness import (YarpWorld, dump_outputs_if_failed, lite_implementation,  # noqa: E402
                     missing_reference, real_implementation)
from requirements import apply_marks  # noqa: E402
from robot_slots import (Share, arranged, machine_share, no_real_time,  # noqa: E402
                         one_share_per_fixture, share_of)


def pytest_configure(config):
    config.addinivalue_line("markers", "requires(name, ...): needs root, the reference YARP... "
                            "(tests/requirements.py): skipped when missing, failed when "
                            "WALKMAN_REQUIRE_<NAME> is set")
    config.addinivalue_line("markers", "free_standing: runs a robot with the harness off in "
                            "real time; it has the machine to itself, as 'alone' "
                            "(tests/robot_slots.py)")
    config.addinivalue_line("markers", "two_pcs: starts both PCs of a topology with a "
                            "simulated robot; it has the machine to itself, as 'alone' "
                            "(tests/robot_slots.py)")
    config.addinivalue_line("markers", "alone: has the machine to itself while it runs; "
                            "every other test waits (tests/robot_slots.py)")
    config.addinivalue_line("markers", "real_time: starts programs with real-time threads "
                            "(a HAL) from a folder whose tests otherwise start none "
                            "(tests/robot_slots.py)")
    config.addinivalue_line("markers", "lockstep: runs the robot and its modules as "
                            "processes on the lockstep clock at --rtf max: no real-time thread, "
                            "beside anything (tests/robot_slots.py)")
    config.addinivalue_line("markers", "offline: runs the robot on simulated time in this "
                            "process: no real-time thread, none in what it starts "
                            "(tests/robot_slots.py)")


#: Folders in the order their tests run, those that start whole topologies first, then those
#: with processes or installs of their own: the workers begin with the minute-long tests and
#: end on the short ones (unit, control, fuzz...), which fill the gaps (alphabetical order
#: put tests/system last, and its longest test started in the final minutes of a run).
HEAVY_FIRST = ("system", "modules", "bridge", "interop", "packaging", "walkman", "bench",
               "pilot", "integration")
TESTS = Path(__file__).resolve().parent


def folder_of(item) -> str:
    """The folder of tests/ an item lives in ("unit", "system", ...)."""
    return Path(str(item.fspath)).resolve().relative_to(TESTS).parts[0]


def share_of_item(item) -> Share:
    return share_of((mark.name for mark in item.iter_markers()), folder_of(item))


@pytest.hookimpl(trylast=True)     # after -k, -m and --deselect: the parts are of what runs
def pytest_collection_modifyitems(config, items):
    """The heaviest folders first, each in its usual order, then arranged by the share of
    the machine each test holds (tests/robot_slots.py); the same on every worker."""
    def rank(item) -> int:
        folder = folder_of(item)
        return HEAVY_FIRST.index(folder) if folder in HEAVY_FIRST else len(HEAVY_FIRST)

    try:
        one_share_per_fixture(
            (f"{definition.baseid}::{name}", item.nodeid, share_of_item(item))
            for item in items
            for name, definitions in item._fixtureinfo.name2fixturedefs.items()
            for definition in definitions[-1:]
            if definition.scope != "function" and definition.baseid)  # ours, not pytest's
    except ValueError as error:
        raise pytest.UsageError(str(error)) from None
    items.sort(key=rank)
    workers = int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1"))
    items[:] = arranged(items, share_of_item, workers)


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    """Every test that runs real-time threads holds the machine, shared, or to itself when
    marked ``alone``, ``free_standing`` or ``two_pcs``, from its setup to its teardown; one
    that runs none holds nothing and runs with ``WALKMAN_NO_RT`` set.  The waits, if any,
    are in the JUnit report's properties (tests/robot_slots.py)."""
    share = share_of_item(item)
    if share is Share.NONE:
        with no_real_time():
            yield
        return
    with machine_share(share is Share.ALONE) as waited:
        if share is Share.ALONE:
            item.user_properties.append(("waited_for_the_machine_s", round(waited, 1)))
        yield


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_setup(item):
    apply_marks(item)  # before any fixture builds what the machine may lack


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


@pytest.hookimpl(wrapper=True, tryfirst=True)
def pytest_runtest_makereport(item, call):
    """Remember each phase's outcome so fixtures can explain a failure."""
    report = yield
    setattr(item, f"report_{report.when}", report)
    return report


@pytest.fixture
def make_world(tmp_path, request):
    worlds = []

    def factory(server_impl, name: str = "world", start: bool = True,
                auth_key=None) -> YarpWorld:
        world = YarpWorld(tmp_path / f"{name}{len(worlds)}", server_impl, auth_key=auth_key)
        worlds.append(world)
        if start:
            world.start_server()
        return world

    yield factory
    for world in worlds:
        dump_outputs_if_failed(request, world.processes)
        world.close()


@pytest.fixture
def lite_world(make_world, lite, monkeypatch):
    """A yarp_lite name server, with this test process pointed at it."""
    world = make_world(lite)
    world.apply_to_process(monkeypatch)
    return world


@pytest.fixture
def emulated_link():
    """The two emulated hosts (robot, pilot) and the radio between them
    (:class:`netem.emulation.EmulatedLink`), taken down after the test, a failed one too.
    Needs root: mark the test ``requires("root")``.  Give it to
    :class:`system.topology.Topology` (``link=``) to place the PCs on the hosts."""
    import random

    from netem.emulation import EmulatedLink

    link = EmulatedLink(f"we{os.getpid() % 100000}", random.randint(20, 250))
    try:
        link.up()
        yield link
    finally:
        link.down()


@pytest.fixture(autouse=True)
def _quiet_logs(caplog):
    caplog.set_level(logging.INFO, logger="yarp_lite")


@pytest.fixture(autouse=True)
def _our_loggers_restored():
    """A program's main() run in-process (walkman-bridge's configure_logging) gives our
    loggers their own handler and stops propagation: later tests' caplog would see nothing."""
    names = OUR_LOGGERS
    saved = {name: (list(logging.getLogger(name).handlers), logging.getLogger(name).propagate,
                    logging.getLogger(name).level) for name in names}
    yield
    for name, (handlers, propagate, level) in saved.items():
        logger = logging.getLogger(name)
        logger.handlers[:] = handlers
        logger.propagate, logger.level = propagate, level
