"""What ``/bridge/<side>/rpc:i`` answers: the words of ``yarp rpc`` to a bridge (pure).

``status``, ``cancel MODULE SEQ|all``, ``stop_all``, ``release`` and ``help``.
:func:`answer` parses a request and formats the reply; what is done is the
bridge's (:class:`Operations`), so the words are tested without sockets.  A
malformed request is answered ``error why``, never raised: the requests come from
any program on the name server.
"""

from __future__ import annotations

from typing import Any, Dict, List, Optional, Protocol, Tuple

from bridge import status as status_codec
from bridge.errors import BridgeUsageError
from bridge.stop_line import Ack
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
