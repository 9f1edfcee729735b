"""What ``/<robot>/rpc:i`` answers: the robot-wide words of the HAL (pure).

``[get] chains``, ``[get] stats``, ``[get] halt``, ``[set] halt on|off`` (the
pilot's stop-all), and, on the simulated robot, ``[set] harness MODE``,
``[set] push IX IY IZ [SECONDS]`` and ``[set] station NAME``.  :func:`answer`
parses a request and formats the reply as YARP's devices do (``[ok]`` or
``[fail] why``); what is done is the HAL's (:class:`Operations`), so the words
are tested without sockets.  A malformed request is answered ``[fail] why``,
never raised: requests come from any program on the name server.
"""

from __future__ import annotations

from typing import Dict, List, Optional, Protocol, Sequence

from walkman.hal.sim import HARNESS_MODES
from walkman.model.mjcf import STATIONS
from yarp_lite.bottle import Bottle, Vocab

USAGE = ("unknown request; try [get] chains, [get] stats, [set] harness locked|trolley|off, "
         "[set] push IX IY IZ, [set] station NAME, [set] halt on|off, [get] halt")
#: What ``[set] harness`` takes besides the modes' own names (YARP's booleans).
HARNESS_WORDS = {"on": "locked", "true": "locked", "1": "locked", "false": "off", "0": "off"}


class RobotWordError(ValueError):
    """An operation refused a well-formed request (the reason is the pilot's to read)."""


class Operations(Protocol):
    """What the HAL does for its robot-wide words (a simulation-only one raises
    :class:`RobotWordError` on a real robot's backend)."""

    def chain_joints(self) -> Dict[str, Sequence[str]]: ...

    def stats(self) -> Dict[str, float]: ...

    def halt(self, on: bool) -> None: ...

    def halted(self) -> bool: ...

    def set_harness(self, mode: str) -> None: ...

    def push(self, impulse: List[float], seconds: Optional[float]) -> None: ...

    def go_to_station(self, name: str) -> None: ...


def ok() -> Bottle:
    return Bottle([Vocab("ok")])


def fail(why: str) -> Bottle:
    return Bottle([Vocab("fail"), why])


def answer(request: Bottle, hal: Operations) -> Bottle:
    verb = str(request[0]) if request else ""
    what = str(request[1]) if len(request) > 1 else ""
    try:
        if verb == "get" and what == "chains":
            return Bottle([Bottle([name, *joints]) for name, joints in hal.chain_joints().items()])
        if verb == "get" and what == "stats":
            return Bottle([Bottle([key, value]) for key, value in hal.stats().items()])
        if verb == "get" and what == "halt":
            return Bottle([Vocab("ok"), "on" if hal.halted() else "off"])
        if verb == "set" and what == "halt" and len(request) == 3 and \
                str(request[2]) in ("on", "off"):
            hal.halt(str(request[2]) == "on")
            return ok()
        if verb == "set" and what == "harness" and len(request) > 2:
            mode = _harness_mode(request[2])
            if mode not in HARNESS_MODES:
                return fail(f"harness must be one of {', '.join(HARNESS_MODES)}, got {mode!r}")
            hal.set_harness(mode)
            return ok()
        if verb == "set" and what == "push":
            return _push(request, hal)
        if verb == "set" and what == "station":
            name = str(request[2]) if len(request) == 3 else ""
            if name not in STATIONS:
                return fail(f"station must be one of {', '.join(STATIONS)}, got "
                            f"{request.to_text()[:80]!r}")
            hal.go_to_station(name)
            return ok()
    except RobotWordError as exc:
        return fail(str(exc))
    return fail(USAGE)


def _harness_mode(value: object) -> str:
    """The mode a ``[set] harness`` word names.  YARP's text reads ``true`` and ``false``
    as the vocabs ``'1'`` and 0 (whose text is empty): ``set harness false`` in ``yarp rpc``
    arrives as ``Vocab('')``."""
    if isinstance(value, Vocab) and str(value) in ("", "1"):
        return "locked" if str(value) == "1" else "off"
    return HARNESS_WORDS.get(str(value), str(value))


def _push(request: Bottle, hal: Operations) -> Bottle:
    """``[set] push IX IY IZ [SECONDS]``: a simulated push on the torso (N*s, world)."""
    values = list(request)[2:]
    if len(values) not in (3, 4) or not all(isinstance(v, (int, float)) and
                                            not isinstance(v, bool) for v in values):
        return fail(f"push takes IX IY IZ (N*s) and optionally SECONDS, got "
                    f"{request.to_text()[:80]!r}")
    try:
        hal.push([float(v) for v in values[:3]], float(values[3]) if len(values) == 4 else None)
    except ValueError as exc:   # the backend's own limits (RobotWordError is one)
        return fail(str(exc))
    return ok()
