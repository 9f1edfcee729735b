"""Everything that decides a GYM module's lifecycle lives in this file (paper, Figure 8).

::

    constructor --start--> running --pause--> paused --resume--> running
    running, paused --stop--> stopped --start--> running
    every state --quit--> destructor

The table is the whole truth: :func:`next_state` either returns the new
state or raises :class:`IllegalTransition` naming the module, the state and
the command, which the watchdog reports to the pilot on the warning port.
"""

from __future__ import annotations

from enum import Enum
from typing import Dict


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
