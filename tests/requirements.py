"""What a test needs from the machine, and what happens when the machine lacks it.

Each :class:`Requirement` has a name and a check that returns None when the
machine has it, else the reason it does not.  A test that needs it either
calls :meth:`Requirement.demand` or carries ``@pytest.mark.requires("name")``
(``pytestmark`` for a whole module; conftest applies the marks).  Missing, the
test *skips* with the reason -- on a developer's machine without root or the
reference YARP -- unless ``WALKMAN_REQUIRE_<NAME>`` is set, as
``launch_scripts/run_tests.sh`` (CI) does, or ``CI=true`` (what CI services set)
and that variable is not ``0``: then it *fails*, because a CI run that skipped the
interop or emulated-network tests would pass by luck.

A new need (a display for rendering tests, say) is one more entry in
:data:`REQUIREMENTS`; nothing else changes.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Callable, Dict, Optional

import pytest


@dataclass(frozen=True)
class Requirement:
    """A named need of some tests; ``check()`` is None when met, else why not."""

    name: str
    check: Callable[[], Optional[str]]

    @property
    def variable(self) -> str:
        """The environment variable that turns "skip when missing" into "fail"."""
        return f"WALKMAN_REQUIRE_{self.name.upper()}"

    @property
    def required(self) -> bool:
        """Set and not ``0``; unset, whether this is a CI run (``CI=true``)."""
        value = os.environ.get(self.variable)
        if value is not None:
            return value not in ("", "0")
        return os.environ.get("CI", "").lower() in ("true", "1")

    def demand(self) -> None:
        """Return when met; otherwise skip the calling test, or fail it when required."""
        reason = self.check()
        if reason is None:
            return
        if self.required:
            why = f"{self.variable} is set" if os.environ.get(self.variable) else "CI is set"
            pytest.fail(f"{reason} ({why}: this run must not skip it)", pytrace=False)
        pytest.skip(f"{reason} (set {self.variable}=1 to make this a failure)")


def _reference_yarp() -> Optional[str]:
    from yarp_lite import reference

    return None if reference.prefix() is not None else reference.MISSING


def _reference_devices() -> Optional[str]:
    from yarp_lite import reference

    return None if reference.devices() is not None else reference.DEVICES_MISSING


def _root() -> Optional[str]:
    from netem import emulation

    return emulation.available()


def _ros() -> Optional[str]:
    import importlib.util
    import shutil

    missing = [what for what, ok in (
        ("roscore (apt-get install ros-core)", shutil.which("roscore")),
        ("rospy (python3-rospy)", importlib.util.find_spec("rospy")),
        ("rosgraph (python3-rosgraph)", importlib.util.find_spec("rosgraph"))) if not ok]
    return None if not missing else f"the ROS tests need {', '.join(missing)}"


def _xvfb() -> Optional[str]:
    import importlib.util
    import shutil

    missing = [what for what, ok in (
        ("Xvfb (apt-get install xvfb)", shutil.which("Xvfb")),
        ("PyQt5 (python3-pyqt5)", importlib.util.find_spec("PyQt5")),
        ("librviz's Python bindings (python3-rviz)", importlib.util.find_spec("rviz")),
        ("interactive_markers (python3-interactive-markers)",
         importlib.util.find_spec("interactive_markers"))) if not ok]
    return None if not missing else f"the GUI tests need {', '.join(missing)}"


#: Every requirement by name, as ``@pytest.mark.requires(NAME)`` names it.
REQUIREMENTS: Dict[str, Requirement] = {
    requirement.name: requirement for requirement in (
        Requirement("reference", _reference_yarp),  # the reference YARP 3.5 build
        # ... with its device plugins: yarpdev, controlboardwrapper2, fakeMotionControl
        Requirement("reference_devices", _reference_devices),
        Requirement("root", _root),  # network namespaces, tc and nftables: emulated hosts
        Requirement("xvfb", _xvfb),  # the Pilot Interface under Xvfb: Qt, librviz, markers
        Requirement("ros", _ros),    # ROS 1 from Debian: roscore, rospy, rosgraph
    )
}


def demand(name: str) -> None:
    """:meth:`Requirement.demand` of the requirement called ``name``."""
    try:
        requirement = REQUIREMENTS[name]
    except KeyError:
        raise ValueError(f"no requirement named {name!r} (known: "
                         f"{', '.join(REQUIREMENTS)})") from None
    requirement.demand()


def apply_marks(item: pytest.Item) -> None:
    """Demand what ``@pytest.mark.requires(...)`` marks on ``item`` name (conftest's hook)."""
    for mark in item.iter_markers("requires"):
        for name in mark.args:
            demand(name)
