"""The bridge's status as a YARP Bottle, and back (pure functions).

The status is a nested dict (link phase, queues, per-channel counters, bytes
per 8-bit id).  On ``/bridge/<side>/status:o`` and in ``rpc status`` replies it
travels as YARP property lists, ``((key value) ...)``, so ``yarp read`` shows
it readably; :func:`from_bottle` gives the dict back to tools that sample it
(keys come back as strings, as YARP text has no integer keys).

:func:`from_bottle` reads what a port delivered, so anything that is not a
status raises :class:`BridgeProtocolError`; its depth is bounded by the
Bottle decoders' own nesting limits.
"""

from __future__ import annotations

from typing import Any, Dict

from bridge.errors import BridgeProtocolError
from yarp_lite.bottle import Bottle


def to_bottle(status: Dict[str, Any]) -> Bottle:
    def convert(value: Any) -> Any:
        if isinstance(value, dict):
            return Bottle([Bottle([str(key), convert(item)]) for key, item in value.items()])
        if isinstance(value, (list, tuple)):
            return Bottle([convert(item) for item in value])
        if isinstance(value, float):
            return float(value)
        return value

    return convert(status)


def _is_property_list(value: Any) -> bool:
    return isinstance(value, list) and all(
        isinstance(pair, list) and len(pair) == 2 and isinstance(pair[0], str) for pair in value)


def from_bottle(bottle: Bottle) -> Dict[str, Any]:
    """The dict :func:`to_bottle` was given (an empty list reads as an empty dict)."""
    def convert(value: Any) -> Any:
        if _is_property_list(value):
            return {str(pair[0]): convert(pair[1]) for pair in value}
        if isinstance(value, list):
            return [convert(item) for item in value]
        return value

    result = convert(bottle)
    if not isinstance(result, dict):
        raise BridgeProtocolError(f"not a bridge status: {str(bottle)[:80]!r}")
    return result
