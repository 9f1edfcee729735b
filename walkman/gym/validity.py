"""How long a pilot's command may still start: a validity that travels with the command.

Theory of operation
-------------------
A command that reaches the robot long after it was sent (queued through a
blackout of the DARPA link) must not run: the world moved on.  The two PCs'
clocks need not agree, so a command carries no deadline.  It carries its
*lifetime*, a trailing list on the switch or command Bottle::

    (turn 1.57) 42 (age 0.35 valid 10)

``age`` is the seconds it has waited so far and ``valid`` the seconds it may
wait in all (absent: the receiving module's default, :data:`DEFAULT_VALIDITY`
unless its class declares ``command_validity``).  Every hop that holds the
command adds the time it held it, measured on its own clock: the gateway (a
dangerous command's countdown), the pilot bridge's journal, the link, the
robot bridge's journal.  The module compares the age with the validity when it
would *start* the command, and refuses it as expired, on its warning port, if
it is too old.  A command without a trailer (``yarp write``, typed) has age 0
where it was written; a bridge it crosses gives it a trailer.

Pure functions over Bottles; nothing here reads a clock.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional, Tuple

from yarp_lite.bottle import Bottle

#: Seconds a command may wait before it starts, unless the module or the pilot says otherwise.
DEFAULT_VALIDITY = 10.0
#: Seconds a dangerous command may still start after its countdown ended: its way to the
#: module (two bridges, a slow link, a loaded PC), never a blackout's worth.
DANGEROUS_GRACE = 5.0
#: Longest validity a pilot may ask for (a day): more is a typing mistake.
MAX_VALIDITY = 86400.0
_AGE, _VALID = "age", "valid"


class ValidityError(ValueError):
    """A lifetime trailer, or a validity asked for, is malformed; the text says how."""


@dataclass(frozen=True)
class Lifetime:
    """How long a command has waited (``age``) and may wait in all (``validity``)."""

    age: float = 0.0
    validity: Optional[float] = None

    def older(self, seconds: float) -> "Lifetime":
        """This lifetime after ``seconds`` more of waiting (negative clock steps count 0)."""
        return Lifetime(self.age + max(0.0, seconds), self.validity)

    def limit(self, default: float) -> float:
        return self.validity if self.validity is not None else default

    def expired(self, default: float) -> bool:
        return self.age > self.limit(default)

    def remaining(self, default: float) -> float:
        return self.limit(default) - self.age


def check_validity(seconds: float) -> float:
    """A validity a pilot asks for, or :class:`ValidityError` saying what is wrong."""
    if not isinstance(seconds, (int, float)) or isinstance(seconds, bool) or \
            not math.isfinite(seconds) or not 0 < seconds <= MAX_VALIDITY:
        raise ValidityError(f"a validity is a number of seconds in (0, {MAX_VALIDITY:g}], "
                            f"not {seconds!r}")
    return float(seconds)


def _is_trailer(value: object) -> bool:
    return isinstance(value, list) and len(value) >= 2 and value[0] == _AGE


def _number(value: object, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or \
            not math.isfinite(value) or value < 0:
        raise ValidityError(f"{what} must be a finite number of seconds >= 0, not {value!r}")
    return float(value)


def _parse(trailer: list) -> Lifetime:
    if len(trailer) not in (2, 4):
        raise ValidityError(f"a lifetime is (age A) or (age A valid V), got "
                            f"{Bottle([trailer]).to_text()}")
    age = _number(trailer[1], "age")
    validity = None
    if len(trailer) == 4:
        if trailer[2] != _VALID:
            raise ValidityError(f"a lifetime is (age A valid V), got {trailer[2]!r} for valid")
        validity = _number(trailer[3], "valid")
    return Lifetime(age, validity)


def split(bottle: Bottle) -> Tuple[Bottle, Optional[Lifetime]]:
    """The message without its lifetime trailer, and the lifetime (None: it has none).

    Raises :class:`ValidityError` for a trailer that is malformed.
    """
    if bottle and _is_trailer(bottle[-1]):
        return Bottle(list(bottle)[:-1]), _parse(bottle[-1])
    return bottle, None


def stamp(message: Bottle, lifetime: Lifetime) -> Bottle:
    """``message`` (without a trailer) with ``lifetime`` appended."""
    trailer = [_AGE, round(lifetime.age, 3)]
    if lifetime.validity is not None:
        trailer += [_VALID, float(lifetime.validity)]
    return Bottle([*message, Bottle(trailer)])


def aged(bottle: Bottle, seconds: float) -> Bottle:
    """``bottle`` after a hop held it ``seconds``: its lifetime's age grown (a trailer
    added when it had none).  A malformed trailer is left as it is, for the module to
    refuse with its reason: a hop never makes a bad message look good."""
    try:
        message, lifetime = split(bottle)
    except ValidityError:
        return bottle
    return stamp(message, (lifetime or Lifetime()).older(seconds))


def describe_expiry(text: str, lifetime: Lifetime, default: float) -> str:
    """What a module says when it refuses ``text`` as too old."""
    return (f"`{text}` expired after {lifetime.age:.0f} s in the queue (valid "
            f"{lifetime.limit(default):g} s); not run")
