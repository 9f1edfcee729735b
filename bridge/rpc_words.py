"""What ``/bridge/<side>/rpc:i`` answers: the words of ``yarp rpc`` to a bridge (pure).

``status``, ``cancel MODULE SEQ|all``, ``stop_all``, ``release`` and ``help``.
:func:`answer` parses a request and formats the reply; what is done is the
bridge's (:class:`Operations`), so the words are tested without sockets.  A
malformed request is answered ``error why``, never raised: the requests come from
any program on the name server.  The asking side's readers are here too
(:func:`read_cancel_reply`, :func:`read_stop_reply`, the pilot gateway's), so a
reply's form is written down once; a refusal raises :class:`BridgeUsageError`
with the bridge's words, a reply of another form :class:`BridgeProtocolError`.
"""

from __future__ import annotations

from typing import Any, Dict, List, Optional, Protocol, Sequence, Tuple

from bridge import status as status_codec
from bridge.errors import BridgeProtocolError, BridgeUsageError
from bridge.gym.stop_line import Ack
from yarp_lite.bottle import Bottle

HELP = ("status: link, queues and counters of this bridge; "
        "cancel MODULE SEQ|all: take back commands not yet sent; "
        "stop_all: hold the robot (HAL and every module); "
        "release: let the HAL move again")


class Operations(Protocol):
    """What a bridge does for its RPC words."""

    def status(self) -> Dict[str, Any]: ...

    def cancel(self, module: str, seq: Optional[int]) -> Tuple[List[int], List[int]]: ...

    def stop_all(self, word: str = "stop_all", timeout: float = 5.0) -> Optional[Ack]: ...


def answer(request: Bottle, bridge: Operations) -> Bottle:
    word = str(request[0]) if request and isinstance(request[0], str) else None
    if word == "status":
        return status_codec.to_bottle(bridge.status())
    if word == "cancel":
        return _cancel(request, bridge)
    if word in ("stop_all", "release") and len(request) == 1:
        return _stop(word, bridge)
    if word == "help":
        return Bottle([HELP])
    said = str(request[0]) if request else ""
    return Bottle(["error", f"unknown command {said!r}: try status, cancel, stop_all, "
                            f"release or help"])


def _cancel(request: Bottle, bridge: Operations) -> Bottle:
    """``cancel MODULE SEQ`` or ``cancel MODULE all`` -> ``ok (cancelled S...)
    (too_late S...)`` or ``error why``."""
    if len(request) != 3 or not isinstance(request[1], str) or \
            not (request[2] == "all" or (isinstance(request[2], int) and
                                         not isinstance(request[2], bool))):
        return Bottle(["error", "usage: cancel MODULE SEQ|all"])
    try:
        cancelled, too_late = bridge.cancel(str(request[1]),
                                            None if request[2] == "all" else int(request[2]))
    except BridgeUsageError as exc:
        return Bottle(["error", str(exc)])
    return Bottle(["ok", Bottle(["cancelled", *cancelled]), Bottle(["too_late", *too_late])])


def _stop(word: str, bridge: Operations) -> Bottle:
    try:
        ack = bridge.stop_all(word)
    except BridgeUsageError as exc:
        return Bottle(["error", str(exc)])
    if ack is None:
        return Bottle(["error", f"{word}: the robot did not acknowledge within 5 s"])
    return Bottle(["ok", ack.word, Bottle(["hal", "ok" if ack.hal else "failed"]),
                   Bottle(["round_trip_ms", round(ack.round_trip_ms, 1)]),
                   Bottle(["robot_ms", round(ack.took_ms, 1)]),
                   Bottle(["paused", *ack.modules])])


# -- the asking side ---------------------------------------------------------------------


def cancel_request(module: str, seq: Optional[int]) -> Bottle:
    """``cancel MODULE SEQ``, or ``cancel MODULE all`` for None."""
    return Bottle(["cancel", module, "all" if seq is None else seq])


def read_cancel_reply(reply: Bottle) -> Tuple[List[int], List[int]]:
    """The sequence numbers cancelled and too late, from :func:`_cancel`'s reply."""
    _refused(reply)
    if not reply or reply[0] != "ok":
        raise BridgeProtocolError(f"a cancel reply is ok (cancelled ...) (too_late ...), "
                                  f"got {reply}")
    fields = _named_lists(reply, 1, ("cancelled", "too_late"))
    if not all(isinstance(n, int) and not isinstance(n, bool)
               for numbers in fields.values() for n in numbers):
        raise BridgeProtocolError(f"a cancel reply lists sequence numbers, got {reply}")
    return fields["cancelled"], fields["too_late"]


def read_stop_reply(reply: Bottle) -> Ack:
    """The robot's acknowledgement, from :func:`_stop`'s reply (its stop id is not said)."""
    _refused(reply)
    if len(reply) < 2 or reply[0] != "ok" or not isinstance(reply[1], str):
        raise BridgeProtocolError(f"a stop reply is ok WORD (hal ...) ..., got {reply}")
    fields = _named_lists(reply, 2, ("hal", "round_trip_ms", "robot_ms", "paused"))
    try:
        (hal,), (round_trip,), (robot,) = (fields["hal"], fields["round_trip_ms"],
                                           fields["robot_ms"])
        return Ack(0, str(reply[1]), hal == "ok", float(robot),
                   tuple(str(m) for m in fields["paused"]), float(round_trip))
    except (TypeError, ValueError) as exc:
        raise BridgeProtocolError(f"a stop reply's fields are (hal ok|failed) "
                                  f"(round_trip_ms MS) (robot_ms MS), got {reply}") from exc


def _refused(reply: Bottle) -> None:
    if len(reply) == 2 and reply[0] == "error":
        raise BridgeUsageError(str(reply[1]))


def _named_lists(reply: Bottle, start: int, names: Sequence[str]) -> Dict[str, list]:
    """``(name v...)`` for each of ``names``, in order, from ``reply[start]`` to its end."""
    lists = list(reply)[start:]
    if len(lists) != len(names) or not all(
            isinstance(item, list) and len(item) >= 1 and item[0] == name
            for item, name in zip(lists, names)):
        raise BridgeProtocolError("a reply's fields are " +
                                  " ".join(f"({name} ...)" for name in names) + f", got {reply}")
    return {name: list(item)[1:] for item, name in zip(lists, names)}
