"""Forward error correction for the UDP channel: a systematic Reed-Solomon erasure code.

Theory of operation
-------------------
``k`` data datagrams are followed by ``m`` repair datagrams; any ``k`` of the
``k + m`` rebuild every data datagram.  (XOR parity, which nimbro_network and
MIT's shaper used, repairs one loss per group; at 10 % loss it needs a repair
fraction of 0.5 to reach 98 %, this code needs about 0.3.)

The code works over GF(256) (polynomial 0x11d).  Repair row ``j`` combines the
data with a Cauchy matrix, ``C[j][i] = 1 / (x_j + y_i)``; every square
sub-matrix of a Cauchy matrix is invertible, so whichever ``k`` datagrams
arrive, the ``k x k`` system they form can be solved.  Datagrams of different
lengths are framed as ``len (2 bytes) + payload``, zero padded to the longest.
Pure functions over bytes, vectorized with numpy lookup tables.

:func:`recover` takes what arrived from the network, so it checks every
number before using it: ``1 <= k <=`` :data:`MAX_DATA`, data indices inside
the group, repair rows below :data:`MAX_REPAIRS`, repairs of one length
between 2 and :data:`MAX_SYMBOL` bytes (a 2-byte length + a datagram), no
data longer than its repairs.  Anything else is :class:`BridgeProtocolError`.
"""

from __future__ import annotations

import math
import struct
from typing import Dict, List, Sequence

import numpy as np

from bridge.errors import BridgeProtocolError, BridgeUsageError

_EXP = np.zeros(512, np.uint8)
_LOG = np.zeros(256, np.int64)
_value = 1
for _power in range(255):
    _EXP[_power] = _value
    _LOG[_value] = _power
    _value <<= 1
    if _value & 0x100:
        _value ^= 0x11D
_EXP[255:510] = _EXP[0:255]
# _MUL[a] is the row "a * b for every b": one fancy index multiplies a whole datagram.
_MUL = np.zeros((256, 256), np.uint8)
_nonzero = np.arange(1, 256)
for _a in range(1, 256):
    _MUL[_a, 1:] = _EXP[_LOG[_a] + _LOG[_nonzero]]
_LEN = struct.Struct(">H")
MAX_SYMBOLS = 255
#: Group limits: data datagrams, repair rows (x_j = row < 128 <= y_i keeps x_j != y_i).
MAX_DATA, MAX_REPAIRS = 127, 128
#: Longest symbol: the 2-byte length and the longest payload it can describe.
MAX_SYMBOL = _LEN.size + 0xFFFF


def _inverse(value: int) -> int:
    if value == 0:
        raise ZeroDivisionError("0 has no inverse in GF(256)")
    return int(_EXP[255 - _LOG[value]])


def _coefficient(row: int, column: int, k: int) -> int:
    """Cauchy entry for repair ``row`` and data ``column``: x_j = row, y_i = 128 + column."""
    return _inverse(row ^ (128 + column))


def repair_count(k: int, fraction: float) -> int:
    """How many repair datagrams a group of ``k`` gets for a repair ``fraction``."""
    return 0 if fraction <= 0 or k == 0 else max(1, math.ceil(k * fraction))


def _symbols(payloads: Sequence[bytes]) -> np.ndarray:
    width = max(len(p) for p in payloads) + _LEN.size
    out = np.zeros((len(payloads), width), np.uint8)
    for row, payload in enumerate(payloads):
        out[row, :_LEN.size] = np.frombuffer(_LEN.pack(len(payload)), np.uint8)
        out[row, _LEN.size:_LEN.size + len(payload)] = np.frombuffer(payload, np.uint8)
    return out


def encode(payloads: Sequence[bytes], m: int) -> List[bytes]:
    """The ``m`` repair datagrams for ``payloads`` (each as long as the longest + 2)."""
    k = len(payloads)
    if k == 0 or m == 0:
        return []
    if k > MAX_DATA or m > MAX_REPAIRS:
        raise BridgeUsageError(f"FEC groups hold at most {MAX_DATA} data and {MAX_REPAIRS} "
                               f"repair datagrams, got {k} + {m}")
    longest = max(len(payload) for payload in payloads)
    if longest + _LEN.size > MAX_SYMBOL:
        raise BridgeUsageError(f"a payload of {longest} bytes is too long for FEC")
    data = _symbols(payloads)
    repairs = []
    for row in range(m):
        acc = np.zeros(data.shape[1], np.uint8)
        for column in range(k):
            acc ^= _MUL[_coefficient(row, column, k)][data[column]]
        repairs.append(acc.tobytes())
    return repairs


def _solve(matrix: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """Gauss-Jordan over GF(256): ``matrix @ x = rhs``."""
    n = matrix.shape[0]
    a, b = matrix.copy(), rhs.copy()
    for col in range(n):
        pivot = next((r for r in range(col, n) if a[r, col]), None)
        if pivot is None:
            raise BridgeProtocolError("FEC system is singular (corrupt repair datagrams)")
        if pivot != col:
            a[[col, pivot]] = a[[pivot, col]]
            b[[col, pivot]] = b[[pivot, col]]
        scale = _inverse(int(a[col, col]))
        a[col] = _MUL[scale][a[col]]
        b[col] = _MUL[scale][b[col]]
        for row in range(n):
            factor = int(a[row, col])
            if row != col and factor:
                a[row] ^= _MUL[factor][a[col]]
                b[row] ^= _MUL[factor][b[col]]
    return b


def recover(k: int, data: Dict[int, bytes], repairs: Dict[int, bytes]) -> Dict[int, bytes]:
    """Every data payload, given any ``k`` of the data (by index) and repairs (by row).

    Returns only the recovered (missing) ones; raises :class:`BridgeProtocolError`
    when fewer than ``k`` datagrams are at hand or the repairs are malformed.
    """
    if not 1 <= k <= MAX_DATA:
        raise BridgeProtocolError(f"FEC group of {k} data datagrams (1..{MAX_DATA})")
    for index in data:
        if not 0 <= index < k:
            raise BridgeProtocolError(f"data datagram {index} outside a group of {k}")
    for row in repairs:
        if not 0 <= row < MAX_REPAIRS:
            raise BridgeProtocolError(f"repair row {row} (0..{MAX_REPAIRS - 1})")
    missing = [index for index in range(k) if index not in data]
    if not missing:
        return {}
    if len(data) + len(repairs) < k:
        raise BridgeProtocolError(f"{len(data) + len(repairs)} of {k} datagrams: too few "
                                  f"to repair")
    widths = {len(r) for r in repairs.values()}
    if len(widths) != 1:
        raise BridgeProtocolError("repair datagrams of one group differ in length")
    width = widths.pop()
    if not _LEN.size <= width <= MAX_SYMBOL:
        raise BridgeProtocolError(f"repair datagrams of {width} bytes "
                                  f"({_LEN.size}..{MAX_SYMBOL})")
    rows = []
    values = []
    for index, payload in data.items():
        if len(payload) + _LEN.size > width:
            raise BridgeProtocolError("a data datagram is longer than its group's repairs")
        row = np.zeros(k, np.uint8)
        row[index] = 1
        rows.append(row)
        symbol = np.zeros(width, np.uint8)
        symbol[:_LEN.size] = np.frombuffer(_LEN.pack(len(payload)), np.uint8)
        symbol[_LEN.size:_LEN.size + len(payload)] = np.frombuffer(payload, np.uint8)
        values.append(symbol)
    for repair_row, payload in sorted(repairs.items())[:len(missing)]:
        rows.append(np.array([_coefficient(repair_row, c, k) for c in range(k)], np.uint8))
        values.append(np.frombuffer(payload, np.uint8).copy())
    if len(rows) > k:  # more than needed: keep the data rows and enough repairs
        rows, values = rows[:k], values[:k]
    solved = _solve(np.array(rows), np.array(values))
    out = {}
    for index in missing:
        symbol = solved[index].tobytes()
        (length,) = _LEN.unpack_from(symbol)
        if length > width - _LEN.size:
            raise BridgeProtocolError(f"repaired datagram {index} claims {length} bytes")
        out[index] = symbol[_LEN.size:_LEN.size + length]
    return out
