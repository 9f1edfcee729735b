"""The witness module (walkman/modules/witness.py): what it writes, and the one reader of it.

In process, on recording interfaces (no ports): commands fed as a bridge
delivers them, lifetime trailer and all, then ``run()`` as the runner calls it.
"""

from __future__ import annotations

import time

import pytest

from walkman.gym.interfaces import PilotCommand, RecordingInterfaces
from walkman.gym.runner import load_module_class
from walkman.gym.validity import Lifetime
from walkman.modules import module_class, witness
from yarp_lite.bottle_text import parse


@pytest.fixture
def started(tmp_path, monkeypatch):
    log = tmp_path / "executed.log"
    monkeypatch.setenv(witness.LOG_VARIABLE, str(log))
    interfaces = RecordingInterfaces("/counter", witness.Module)
    module = witness.Module("witness", {}, interfaces)
    assert module.custom_init()
    yield module, interfaces, log
    module.custom_release()


def test_it_is_found_by_name_as_every_module_of_the_package():
    assert module_class("witness") is witness.Module
    assert load_module_class("witness") is witness.Module   # walkman-module witness


def test_each_command_run_is_one_line_with_its_start_and_lifetime(started):
    module, interfaces, log = started
    interfaces.commands.feed(parse("(count 1.0) 41 (age 0.25 valid 3.0)"))
    interfaces.commands.feed(parse("(count 2.0) 42"))
    before = time.time()
    module.run()
    module.run()
    module.run()                                 # nothing left: no line
    after = time.time()
    first, second = witness.read_log(log)
    assert (first.name, first.seq, first.age, first.validity) == ("count", 41, 0.25, 3.0)
    assert (second.name, second.seq, second.age, second.validity) == ("count", 42, None, None)
    assert before - 0.001 <= first.at <= second.at <= after + 0.001   # written to the ms
    assert interfaces.state == "counting" and interfaces.data == [42]


def test_a_command_already_too_old_never_reaches_run(started):
    module, interfaces, log = started
    interfaces.commands.feed(parse("(count 1.0) 7 (age 4.0 valid 3.0)"))
    interfaces.commands.feed(parse("(count 2.0) 8 (age 1.0 valid 3.0)"))
    module.run()
    module.run()
    assert [e.seq for e in witness.read_log(log)] == [8]
    assert any("expired" in text for text in interfaces.commands.take_rejections())


def test_lines_parse_back_and_other_lines_are_not_executions():
    command = PilotCommand("count", (3.0,), 12, Lifetime(1.5, 2.0))
    line = witness.line_of(command, 1000.25)
    assert line == "executed count 12 at 1000.250 age 1.5 valid 2"
    parsed = witness.parse_line(line)
    assert parsed == witness.Execution("count", 12, 1000.25, 1.5, 2.0)
    assert not parsed.arrived_expired
    assert witness.parse_line("executed count 12 at 5.000 age 2.5 valid 2").arrived_expired
    no_lifetime = witness.parse_line(witness.line_of(PilotCommand("once", (), None), 3.0))
    assert no_lifetime == witness.Execution("once", None, 3.0, None, None)
    assert not no_lifetime.arrived_expired
    assert witness.parse_line("2024 [INFO] witness: ready for the pilot") is None


def test_a_line_being_written_is_left_for_the_next_read(tmp_path):
    log = tmp_path / "executed.log"
    assert witness.read_log(log) == []              # no file yet: nothing ran
    log.write_text("executed count 1 at 1.000 age - valid -\nexecuted count 2 at 2.0")
    assert [e.seq for e in witness.read_log(log)] == [1]


def test_a_module_of_ours_that_cannot_load_is_an_error_naming_it(tmp_path, monkeypatch):
    """A broken module made the gateway fall back to generic decoding without a word."""
    import sys

    import walkman.modules
    from walkman.modules import ModuleLoadError

    assert module_class("not_one_of_ours") is None      # another team's: none of ours
    assert module_class("my_wave:Module") is None
    broken = tmp_path / "walkman_broken"
    broken.mkdir()
    (broken / "broken_task.py").write_text("import no_such_library\n")
    (broken / "no_module.py").write_text("X = 1\n")
    monkeypatch.setattr(walkman.modules, "__path__", [*walkman.modules.__path__, str(broken)])
    for name in ("broken_task", "no_module"):
        monkeypatch.delitem(sys.modules, f"walkman.modules.{name}", raising=False)
    with pytest.raises(ModuleLoadError, match=r"walkman.modules.broken_task cannot be imported: "
                                              r"ModuleNotFoundError: No module named "
                                              r"'no_such_library'"):
        module_class("broken_task")
    with pytest.raises(ModuleLoadError, match="walkman.modules.no_module has no Module class"):
        module_class("no_module")
