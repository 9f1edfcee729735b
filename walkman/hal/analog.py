"""YARP's analog-sensor wrapper (``analogServer``) for the F/T sensors, as pure logic.

The wrapper streams ``<name>`` (here ``/<robot>/<sensor>/analog:o``) as a float64
Vector with a Stamp envelope, and answers calibration requests on
``<name>/rpc:i`` as ``AnalogServerHandler`` answers them: ``[iana] [cal]``
zeroes every channel at the current reading (an F/T sensor's tare),
``[iana] [cal] v...`` sets the offsets, ``[iana] [calc] ch [v]`` does the same
for one channel; the reply is the IAnalogSensor code (0: ``AS_OK``).
Anything else is answered ``[fail]``, as the real handler does.

The real handler reads ``[cal] v...`` as flat numbers while YARP's own client
sends them as one list; both are accepted here.
"""

from __future__ import annotations

import math
import threading
from typing import Callable, Optional, Sequence

import numpy as np

from yarp_lite.bottle import Bottle, Vocab

AS_OK = 0


def rpc_name(stream_port: str) -> str:
    """The wrapper's rpc port: the streaming port's name + ``/rpc:i``."""
    return f"{stream_port}/rpc:i"


class AnalogOffsets:
    """Per-channel offsets subtracted from a sensor's raw reading (thread-safe)."""

    def __init__(self, channels: int) -> None:
        self.offsets = np.zeros(channels)
        self._lock = threading.Lock()

    def apply(self, raw: Sequence[float]) -> np.ndarray:
        with self._lock:
            return np.asarray(raw, dtype=float) - self.offsets

    def set(self, channels: Sequence[int], values: Sequence[float]) -> None:
        with self._lock:
            self.offsets[list(channels)] = values


def respond(request: Bottle, offsets: AnalogOffsets, raw: Callable[[], np.ndarray],
            on_error: Callable[[str], None] = lambda text: None) -> Bottle:
    """The answer to one ``rpc:i`` request."""
    words = [str(v)[:4] if isinstance(v, str) else None for v in request[:2]]
    channels = len(offsets.offsets)
    problem: Optional[str] = None
    if words[:1] != ["iana"] or len(words) < 2 or words[1] not in ("cal", "calc"):
        problem = "try [iana] [cal] [values...] or [iana] [calc] channel [value]"
    elif words[1] == "cal":
        values = request[2:]
        if len(values) == 1 and isinstance(values[0], list):
            values = values[0]
        numbers = _numbers(values)
        if not values:
            offsets.set(range(channels), raw())
        elif numbers is None or len(numbers) != channels:
            problem = f"[cal] takes {channels} finite numbers, got {Bottle(values).to_text()}"
        else:
            offsets.set(range(channels), numbers)
    else:
        channel = request[2] if len(request) > 2 else None
        value = _numbers(request[3:4])
        if not isinstance(channel, int) or isinstance(channel, Vocab) \
                or not 0 <= channel < channels:
            problem = f"[calc] needs a channel 0..{channels - 1}, got {channel!r}"
        elif len(request) > 4 or (len(request) == 4 and value is None):
            problem = "[calc] takes a channel and at most one finite number"
        else:
            offsets.set([channel], value if value else [raw()[channel]])
    if problem is not None:
        on_error(f"{request.to_text()[:100]}: {problem}")
        return Bottle([Vocab("fail")])
    return Bottle([AS_OK])


def _numbers(values: Sequence[object]) -> Optional[list]:
    if all(isinstance(v, (int, float)) and not isinstance(v, Vocab) and math.isfinite(v)
           for v in values):
        return [float(v) for v in values]
    return None
