"""Bottles as text: the form ``yarp read`` prints and ``yarp write`` parses.

Theory of operation
-------------------
This is a line-by-line port of YARP 3.5's ``BottleImpl::fromString``,
``smartAdd``, ``isComplete`` and the ``Store*::toStringNested`` family, quirks
included, because the text carrier and the name server speak it: a peer must
get back exactly what real YARP would have produced.  Some of those quirks are
surprising and deliberate here:

* ``true``/``false`` (unquoted) are vocabs, ``null`` is the vocab ``null``;
* integers are parsed with C's ``strtoll(.., 0)``: ``010`` is octal 8, ``0x1f``
  hex, and ``1-2`` reads as ``1``; a value that fits 32 bits is an INT32;
* anything with a ``.`` or an ``e`` is a FLOAT64, and it must parse completely
  or it becomes 0.0 (``1e`` -> 0.0), as ``yarp::conf::numeric::from_string``;
* doubles print with ``%.21g`` plus ``.0`` when they look like integers;
* strings are quoted only when they contain anything but letters, ``_`` and
  (after the first character) digits, ``.``, ``-``.

Parsing is total up to one limit: any text yields a Bottle (an unclosed list
is dropped, as YARP drops it) unless lists or blobs nest deeper than
:data:`~yarp_lite.bottle.MAX_DEPTH`, which raises :class:`RemoteProtocolError`
(YARP would recurse until its stack overflows).  Every nested list is
re-read from its text, so the cost is at most ``MAX_DEPTH`` times the
length, and the length is bounded by whoever read the line (a stream line
is at most ``yarp_lite.stream.MAX_LINE`` bytes).  :func:`is_complete` says
whether more lines are needed.
"""

from __future__ import annotations

import math

from yarp_lite.bottle import (MAX_DEPTH, Bottle, Float32, Int64, Value, Vocab,
                              format_bottle, format_double, format_value, quote_string,
                              vocab_encode)
from yarp_lite.errors import RemoteProtocolError

_SEPARATORS = ", \t\n\r"
_WHITESPACE = " \t\n\r"


# --------------------------------------------------------------------------
# Parsing


def _tokens(text: str) -> "tuple[list[str], bool]":
    """Split text into top-level tokens as ``BottleImpl::fromString`` does.

    Returns the tokens and whether every list, blob and quote was closed
    (``BottleImpl::isComplete``; a ``,`` separates tokens but cannot change
    nesting, so one scan answers both).  An unclosed trailing token is
    dropped, as YARP drops it.
    """
    tokens: list[str] = []
    arg: list[str] = []
    quoted = back = begun = False
    nested = nested_alt = 0
    for ch in text + " ":
        if back:
            arg.append(ch)
            back = False
            continue
        if not begun and ch not in _WHITESPACE:
            begun = True
        if not begun:
            continue
        if ch == '"':
            quoted = not quoted
        if not quoted:
            if ch == "(":
                nested += 1
            elif ch == ")":
                nested -= 1
            elif ch == "{":
                nested_alt += 1
            elif ch == "}":
                nested_alt -= 1
        if ch == "\\":
            back = True
            arg.append(ch)
        elif not quoted and ch in _SEPARATORS and nested == 0 and nested_alt == 0:
            if arg:
                tokens.append("".join(arg))
            arg = []
            begun = False
        else:
            arg.append(ch)
    return tokens, nested == 0 and nested_alt == 0 and not quoted


def parse(text: str) -> Bottle:
    """Parse one Bottle from its text form (``BottleImpl::fromString``)."""
    return _parse(text, 0)


def _parse(text: str, depth: int) -> Bottle:
    if depth > MAX_DEPTH:
        raise RemoteProtocolError(f"text Bottle nested deeper than {MAX_DEPTH}", "text bottle")
    return Bottle(Vocab("null") if token == "null" else _smart_value(token, depth)
                  for token in _tokens(text)[0])


def is_complete(text: str) -> bool:
    """True when no list, blob or quote is left open (``BottleImpl::isComplete``)."""
    return _tokens(text)[1]


def _looks_numeric(token: str) -> "tuple[bool, bool]":
    """(number-like, has '.' or 'e') exactly as ``smartAdd`` decides."""
    if token in ("inf", "-inf", "nan"):
        return True, True
    number_like = True
    preamble = True
    hex_active = False
    hex_start = 0
    periods = signs = 0
    has_period_or_e = False
    for index, ch in enumerate(token):
        if ch == ".":
            has_period_or_e = True
            periods += 1
            if periods > 1:
                number_like = False
        if not hex_active and ch in "eE":
            has_period_or_e = True
        if preamble and ch in "xX":
            hex_active = True
            hex_start = index
            continue
        if preamble and ch in "0+-":
            if ch in "+-":
                signs += 1
                if signs > 1:
                    number_like = False
            continue
        preamble = False
        if not (ch.isdigit() and ch.isascii() or ch in ".eE+-"
                or (hex_active and ch in "abcdefABCDEF")):
            number_like = False
            break
    if hex_active and len(token) - (hex_start + 1) > 8:
        number_like = False  # YARP only handles 32-bit hexadecimal
    return number_like, has_period_or_e


def _smart_value(token: str, depth: int) -> Value:
    ch = token[0]
    number_like, is_float = _looks_numeric(token)
    if number_like and (ch.isdigit() or ch in "+-.in") and (ch != "." or len(token) > 1):
        if is_float:
            return _c_float(token)
        number = _c_strtoll(token)
        return number if -(1 << 31) <= number < (1 << 31) else Int64(number)
    if ch == "(":
        return _parse(token[1:len(token) - 1], depth + 1)
    if ch == "[":
        return Vocab(vocab_encode(token[1:len(token) - 1]))
    if ch == "{":
        return _blob(token, depth)
    text = _unquote(token)
    if ch != '"':
        if text == "true":
            return Vocab(ord("1"))
        if text == "false":
            return Vocab(0)
    return text


def _blob(token: str, depth: int) -> bytes:
    return bytes(_as_int32(item) & 0xFF for item in _parse(token[1:len(token) - 1], depth + 1))


def _as_int32(value: Value) -> int:
    """``Value::asInt32`` for the items of a blob written as text."""
    if isinstance(value, Vocab):
        return value.code
    if isinstance(value, bool):
        return int(value)
    if isinstance(value, int):
        return value
    if isinstance(value, float) and math.isfinite(value):
        return int(value)
    return 0


def _unquote(src: str) -> str:
    """``StoreString::fromStringNested``: strip outer quotes, undo escapes."""
    out: list[str] = []
    length = len(src)
    skip = length > 0 and src[0] == '"'
    back = False
    for index, ch in enumerate(src):
        if skip and (index == 0 or index == length - 1):
            continue
        if ch == "\\":
            if not back:
                back = True
            else:
                out.append("\\")
                back = False
            continue
        if back:
            out.append({"n": "\n", "r": "\r", "0": "\0"}.get(ch, ch))
        else:
            out.append(ch)
        back = False
    return "".join(out)


def _c_strtoll(text: str) -> int:
    """C's ``strtoll(text, NULL, 0)``: longest valid prefix, clamped to 64 bits."""
    index, length = 0, len(text)
    while index < length and text[index] in " \t\n\r\f\v":
        index += 1
    sign = 1
    if index < length and text[index] in "+-":
        sign = -1 if text[index] == "-" else 1
        index += 1
    base = 10
    if text[index:index + 2].lower() == "0x" and index + 2 < length and \
            text[index + 2] in "0123456789abcdefABCDEF":
        base, index = 16, index + 2
    elif text[index:index + 1] == "0":
        base = 8
    digits = "0123456789abcdef"[:base]
    value = 0
    while index < length and text[index].lower() in digits:
        if value < 1 << 64:  # past 64 bits the clamp decides: no quadratic big-int work
            value = value * base + digits.index(text[index].lower())
        index += 1
    value *= sign
    return max(-(1 << 63), min((1 << 63) - 1, value))


def _c_float(text: str) -> float:
    """``from_string<double>``: the whole text must be a number, else 0.0."""
    if text == "inf":
        return math.inf
    if text == "-inf":
        return -math.inf
    if text == "nan":
        return math.nan
    try:
        body = text.lstrip("+-")
        if body[:2].lower() == "0x":
            value = float.fromhex(body)
            return -value if text.startswith("-") else value
        return float(text)
    except (ValueError, OverflowError):
        return 0.0


__all__ = ["parse", "is_complete", "format_bottle", "format_value", "format_double",
           "quote_string", "Float32"]
