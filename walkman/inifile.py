"""YARP-style ``.ini`` configuration files and where to find them.

The format of ``Property::fromConfig``: ``key value...`` per line, values in
Bottle text (``0.5`` is a number, ``"a b"`` a string), ``[section]`` headers,
``//`` and ``#`` comments.  :func:`find_config` locates a file like YARP's
ResourceFinder does for ``--from NAME --context CONTEXT``: the path itself,
then ``$YARP_DATA_HOME/contexts/CONTEXT``, then the contexts shipped in
``models/contexts``.  Errors name the file and line.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Dict, List, Optional

from yarp_lite.bottle_text import parse
from walkman import MODELS_DIR

Sections = Dict[str, Dict[str, list]]

SHIPPED_CONTEXTS = MODELS_DIR / "contexts"


class IniError(Exception):
    """A configuration file is missing or malformed; the message says where."""


def parse_ini(text: str, where: str = "<config>") -> Sections:
    sections: Sections = {"": {}}
    current = ""
    for number, raw in enumerate(text.splitlines(), start=1):
        line = raw.split("//", 1)[0]
        if line.lstrip().startswith("#"):
            continue
        line = line.strip()
        if not line:
            continue
        if line.startswith("["):
            if not line.endswith("]") or len(line) < 3:
                raise IniError(f"{where}:{number}: malformed section header {raw.strip()!r}")
            current = line[1:-1].strip()
            sections.setdefault(current, {})
            continue
        words = parse(line)
        if not words:
            raise IniError(f"{where}:{number}: cannot read {raw.strip()!r}")
        key = str(words[0])
        sections[current][key] = list(words[1:])
    return sections


def find_config(name: str, context: str = "") -> Path:
    """Where ``--from name [--context context]`` points, like YARP's ResourceFinder."""
    candidates: List[Path] = [Path(name)]
    if context:
        data_home = os.environ.get("YARP_DATA_HOME")
        if data_home:
            candidates.append(Path(data_home) / "contexts" / context / name)
        candidates.append(SHIPPED_CONTEXTS / context / name)
    candidates.append(SHIPPED_CONTEXTS / name)
    for candidate in candidates:
        if candidate.is_file():
            return candidate
    searched = ", ".join(str(c) for c in candidates)
    raise IniError(f"configuration {name!r} not found (looked in {searched})")


def load(name: str, context: str = "", defaults: Optional[Dict[str, object]] = None) -> Dict[str, object]:
    """Top-level keys of a config, single values unwrapped, over ``defaults``."""
    path = find_config(name, context)
    sections = parse_ini(path.read_text(), str(path))
    values: Dict[str, object] = dict(defaults or {})
    for key, items in sections[""].items():
        values[key] = items[0] if len(items) == 1 else items
    for section, entries in sections.items():
        if section:
            values[section] = entries
    values["__file__"] = str(path)
    return values


def override(values: Dict[str, object], pairs: List[List[str]]) -> Dict[str, object]:
    """``values`` with each ``(key, text)`` of the command line set over the file's, the
    text read as a file's value is (``--set rate 1`` is the number 1) -- as YARP's
    ``--key value`` after ``--from`` overrides the file."""
    out = dict(values)
    for key, text in pairs:
        try:
            words = parse(text)
        except ValueError as exc:
            raise IniError(f"--set {key} {text!r}: {exc}") from None
        if not key.strip():
            raise IniError(f"--set {key!r} {text!r}: the key is empty")
        if not words:
            raise IniError(f"--set {key} {text!r}: no value in it")
        out[key] = words[0] if len(words) == 1 else list(words)
    return out
