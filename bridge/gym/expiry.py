"""The bridge's part in a command's validity: each side adds the time it held the command.

A GYM switch or command carries its lifetime (:mod:`walkman.gym.validity`), the
seconds it has waited so far.  The pilot bridge adds the time a command sat in its
outbox when it puts the command in a frame (a blackout's whole length, for one
written while the link was down); the robot bridge adds half the link's round trip
and the time the command sat in its inbox when it writes it to the module.  Only
flows whose :class:`~bridge.flows.Route` is ``expiring`` are touched; a payload that
is not a Bottle is the peer's error and is left for the codec to refuse.
"""

from __future__ import annotations

from bridge.errors import BridgeProtocolError
from bridge.wire import compact
from walkman.gym import validity


def aged_payload(payload: bytes, seconds: float) -> bytes:
    """A compact-encoded switch or command, ``seconds`` older."""
    try:
        bottle = compact.decode(payload)
    except BridgeProtocolError:
        return payload
    return compact.encode(validity.aged(bottle, seconds))
