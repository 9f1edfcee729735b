"""tests/requirements.py: a missing requirement skips, or fails when the run requires it."""

from __future__ import annotations

from pathlib import Path

import pytest

import requirements
from requirements import Requirement, apply_marks

MISSING = Requirement("gadget", lambda: "no gadget on this machine")
PRESENT = Requirement("gadget", lambda: None)


def test_a_missing_requirement_skips_with_its_reason(monkeypatch):
    monkeypatch.delenv("WALKMAN_REQUIRE_GADGET", raising=False)
    monkeypatch.delenv("CI", raising=False)
    with pytest.raises(pytest.skip.Exception, match="no gadget on this machine"):
        MISSING.demand()


@pytest.mark.parametrize("value", ["1", "yes"])
def test_a_missing_requirement_fails_when_the_run_requires_it(monkeypatch, value):
    monkeypatch.setenv("WALKMAN_REQUIRE_GADGET", value)
    with pytest.raises(pytest.fail.Exception, match="no gadget.*WALKMAN_REQUIRE_GADGET is set"):
        MISSING.demand()


def test_zero_means_not_required(monkeypatch):
    monkeypatch.setenv("WALKMAN_REQUIRE_GADGET", "0")
    monkeypatch.setenv("CI", "true")
    with pytest.raises(pytest.skip.Exception):
        MISSING.demand()


def test_a_ci_run_requires_what_it_does_not_say_otherwise(monkeypatch):
    monkeypatch.delenv("WALKMAN_REQUIRE_GADGET", raising=False)
    monkeypatch.setenv("CI", "true")
    with pytest.raises(pytest.fail.Exception, match="no gadget.*CI is set"):
        MISSING.demand()


def test_a_met_requirement_lets_the_test_run(monkeypatch):
    monkeypatch.setenv("WALKMAN_REQUIRE_GADGET", "1")
    assert PRESENT.demand() is None


class Item:
    """What apply_marks reads of a pytest item."""

    def __init__(self, *names: str) -> None:
        self.marks = [pytest.mark.requires(*names).mark]

    def iter_markers(self, name: str):
        return iter(m for m in self.marks if m.name == name)


def test_marks_name_the_requirements_a_test_demands(monkeypatch):
    monkeypatch.setitem(requirements.REQUIREMENTS, "gadget", MISSING)
    monkeypatch.setenv("WALKMAN_REQUIRE_GADGET", "1")
    with pytest.raises(pytest.fail.Exception, match="no gadget"):
        apply_marks(Item("gadget"))
    with pytest.raises(ValueError, match="no requirement named 'gizmo'"):
        apply_marks(Item("gizmo"))


def test_ci_requires_every_requirement():
    text = (Path(requirements.__file__).resolve().parents[1] / "launch_scripts" /
            "run_tests.sh").read_text()
    for requirement in requirements.REQUIREMENTS.values():
        assert f"export {requirement.variable}=1" in text
