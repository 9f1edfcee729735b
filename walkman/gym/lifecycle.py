"""Everything that decides a GYM module's lifecycle lives in this file (paper, Figure 8).

::

    constructor --start--> running --pause--> paused --resume--> running
    running, paused --stop--> stopped --start--> running
    every state --quit--> destructor

The table is the whole truth: :func:`next_state` either returns the new
state or raises :class:`IllegalTransition` naming the module, the state and
the command, which the watchdog reports to the pilot on the warning port.
Each switch runs one hook of the module (:data:`HOOKS`, :func:`run_hook`);
``stop`` and ``quit`` release only what ``custom_init`` set up
(:func:`releases`).  :mod:`walkman.gym.transitions` carries a switch out
(hooks, status words, hold) for both the process runner and the offline
runner; it and the pilot gateway, which waits for the state a switch leads
to (:data:`TARGET`) and reads the lifecycle from a status word
(:func:`lifecycle_of_status`, :func:`status_word`), all use this file, so
they cannot disagree.
"""

from __future__ import annotations

from enum import Enum
from typing import Any, Dict


#: s a running module may take to reach a safe pause (finish a step) on ``pause`` or ``stop``.
PAUSE_GRACE = 5.0

class State(str, Enum):
    CONSTRUCTOR = "constructor"
    RUNNING = "running"
    PAUSED = "paused"
    STOPPED = "stopped"
    DESTRUCTOR = "destructor"


class Switch(str, Enum):
    START = "start"
    PAUSE = "pause"
    RESUME = "resume"
    STOP = "stop"
    QUIT = "quit"


TRANSITIONS: Dict[State, Dict[Switch, State]] = {
    State.CONSTRUCTOR: {Switch.START: State.RUNNING, Switch.QUIT: State.DESTRUCTOR},
    State.RUNNING: {Switch.PAUSE: State.PAUSED, Switch.STOP: State.STOPPED,
                    Switch.QUIT: State.DESTRUCTOR},
    State.PAUSED: {Switch.RESUME: State.RUNNING, Switch.STOP: State.STOPPED,
                   Switch.QUIT: State.DESTRUCTOR},
    State.STOPPED: {Switch.START: State.RUNNING, Switch.QUIT: State.DESTRUCTOR},
    State.DESTRUCTOR: {},
}


#: The state each switch leads to, from wherever it is legal.
TARGET: Dict[Switch, State] = {switch: target for moves in TRANSITIONS.values()
                               for switch, target in moves.items()}
#: The module hook each switch runs (``custom_<hook>``).
HOOKS: Dict[Switch, str] = {Switch.START: "init", Switch.PAUSE: "pause",
                            Switch.RESUME: "resume", Switch.STOP: "release",
                            Switch.QUIT: "release"}
#: Status words a module says outside ``running`` (the runner sets them), by lifecycle.
STATUS_WORDS: Dict[str, State] = {"initializing": State.CONSTRUCTOR,
                                  "waiting_hal": State.CONSTRUCTOR, "paused": State.PAUSED,
                                  "stopped": State.STOPPED, "destructor": State.DESTRUCTOR}


def lifecycle_of_status(word: str) -> State:
    """The lifecycle behind a status word: a module's own words mean ``running``."""
    return STATUS_WORDS.get(word, State.RUNNING)


def status_word(state: State) -> str:
    """The status word said for ``state`` outside ``running`` (the pilot's first word too)."""
    return "initializing" if state == State.CONSTRUCTOR else state.value


def releases(before: State) -> bool:
    """Whether ``stop``/``quit`` from ``before`` must undo ``custom_init`` (it is in force)."""
    return before in (State.RUNNING, State.PAUSED)


def run_hook(thread: Any, hook: str) -> bool:
    """Call ``custom_<hook>`` of a module; ``release`` has no verdict and counts as done."""
    result = getattr(thread, f"custom_{hook}")()
    return True if hook == "release" else bool(result)


class IllegalTransition(Exception):
    def __init__(self, module: str, state: State, command: str) -> None:
        allowed = ", ".join(s.value for s in TRANSITIONS[state]) or "nothing"
        super().__init__(f"{module}: '{command}' is not valid while {state.value} "
                         f"(allowed: {allowed})")
        self.module, self.state, self.command = module, state, command


def parse_switch(text: str) -> Switch:
    try:
        return Switch(text.strip().lower())
    except ValueError:
        raise ValueError(f"'{text}' is not a switch command (start, pause, resume, stop, quit)") \
            from None


def next_state(module: str, state: State, command: str) -> State:
    """The state after ``command``; raises :class:`IllegalTransition` if not allowed."""
    try:
        switch = parse_switch(command)
    except ValueError:
        raise IllegalTransition(module, state, command) from None
    try:
        return TRANSITIONS[state][switch]
    except KeyError:
        raise IllegalTransition(module, state, command) from None
