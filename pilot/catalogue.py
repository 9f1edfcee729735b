"""What a module offers a pilot: its commands, their numbers, and when each is legal.

Theory of operation
-------------------
A GYM module class declares its states (``statuses``), the numbers each
command takes (``arguments``: fewest, most, usage) and which commands count
down before they leave (``dangerous``); a task module also has its state
table (``table``: state -> command -> next state).  :func:`catalogue_of` reads
those once, so the Generic Widget builds its command entry and the task
widgets their buttons from the module's own declaration -- never a second copy
in the GUI.  A module the PI cannot import (another team's) gets a catalogue
with its states only, from the bridge configuration, and a free-text entry.

Which commands are legal follows the table: in state ``s`` exactly the
commands of ``table[s]``.  Modules without a table accept their commands in any
state.  The lifecycle buttons follow Figure 8 (:mod:`walkman.gym.lifecycle`).
"""

from __future__ import annotations

import inspect
from dataclasses import dataclass, field
from typing import Callable, Dict, List, Mapping, Optional, Sequence, Tuple

from walkman.gym.lifecycle import TRANSITIONS, lifecycle_of_status
from walkman.modules import module_class


@dataclass(frozen=True)
class CommandSpec:
    name: str
    fewest: int = 0
    most: int = 0
    usage: str = ""
    dangerous: bool = False
    #: The numbers the module takes when they are left out (its ``_start_NAME``'s
    #: defaults): what a task widget's fields start with.
    defaults: Tuple[float, ...] = ()

    @property
    def fields(self) -> List[str]:
        """One label per number, from the usage (``X Y Z RADIUS`` -> four fields)."""
        words = [w.strip("[]") for w in self.usage.replace(",", " ").split()
                 if w.strip("[]").isupper() or w.strip("[]").replace("_", "").isupper()]
        if len(words) >= self.most:
            return words[:self.most]
        if words and len(words) == self.fewest:    # a group that repeats (``footsteps``):
            return words                           # the fields hold one
        return [f"#{i + 1}" for i in range(self.most)]

    def check(self, numbers: Sequence[float]) -> Optional[str]:
        """Why these numbers are wrong for the command, or None."""
        if not self.fewest <= len(numbers) <= self.most:
            count = str(self.fewest) if self.fewest == self.most else \
                f"{self.fewest} to {self.most}"
            return f"{self.name} takes {count} numbers ({self.usage or 'none'}), got {len(numbers)}"
        return None


def plain_numbers(state: str, values: Sequence[float]) -> str:
    """A status's numbers with nothing known about them (another team's module)."""
    return " ".join(f"{value:g}" for value in values)


@dataclass
class Catalogue:
    module: str
    statuses: List[str]
    commands: Dict[str, CommandSpec] = field(default_factory=dict)
    table: Optional[Mapping[str, Mapping[str, str]]] = None
    #: (state, numbers) -> what the pilot reads: the module class's ``describe_status``
    describe: Callable[[str, Sequence[float]], str] = plain_numbers

    def legal(self, state: str) -> List[str]:
        """The commands the module accepts in ``state``, in the table's order."""
        if self.table is None:
            return list(self.commands)
        return [c for c in self.table.get(state, {}) if c in self.commands]

    def next_state(self, state: str, command: str) -> Optional[str]:
        return None if self.table is None else self.table.get(state, {}).get(command)


def legal_switches(status: Optional[str]) -> List[str]:
    """The lifecycle commands legal now (Figure 8), from the module's last status word.

    Nothing known (the module never spoke, or not for a long while): none.  A GYM
    module's program says its state from its constructor on, so a silent one is not
    running (or not reachable): a ``start`` would wait in the queues for a program that
    nobody launched, until its validity ran out.  Advanced mode still allows every one.
    """
    if status is None:
        return []
    return [switch.value for switch in TRANSITIONS[lifecycle_of_status(status)]]


def defaults_of(start: Optional[Callable]) -> Tuple[float, ...]:
    """The numbers a command's ``_start_NAME(self, ...)`` takes when they are all left out
    (none when one of them has no default: the pilot must give that one)."""
    if start is None:
        return ()
    numbers = list(inspect.signature(start).parameters.values())[1:]
    defaults: List[float] = []
    for parameter in numbers:
        if parameter.kind is not inspect.Parameter.POSITIONAL_OR_KEYWORD or \
                not isinstance(parameter.default, (int, float)) or \
                isinstance(parameter.default, bool):
            break
        defaults.append(float(parameter.default))
    return tuple(defaults) if len(defaults) == len(numbers) else ()


def catalogue_of(module: str, statuses: Sequence[str] = ()) -> Catalogue:
    """The module's catalogue, from its class when it is one of ours."""
    cls = module_class(module)
    if cls is None:
        return Catalogue(module, list(statuses))
    table = getattr(cls, "table", None) or None
    arguments: Mapping[str, Tuple[int, int, str]] = getattr(cls, "arguments", {}) or {}
    dangerous = getattr(cls, "dangerous", frozenset())
    if table is not None:
        from walkman.modules.task import pilot_commands

        names = pilot_commands(table)
    else:
        names = list(arguments)
    commands = {}
    for name in names:
        fewest, most, usage = arguments.get(name, (0, 0, ""))
        commands[name] = CommandSpec(name, fewest, most, usage, name in dangerous,
                                     defaults_of(getattr(cls, f"_start_{name}", None)))
    return Catalogue(module, list(statuses) or list(getattr(cls, "statuses", [])), commands,
                     table, getattr(cls, "describe_status", plain_numbers))
