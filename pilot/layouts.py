"""Named Pilot Interface layouts, read from an INI file (``models/pilot_layouts.ini``).

Theory of operation
-------------------
The paper's PI was built from configuration files: three pilots at the DRC
each ran a differently composed GUI.  A layout is a list of tabs, each a list
of widgets, and an optional ``side`` column shown beside the tabs.  Parsing is
pure and strict: an unknown widget, a module the bridge configuration lacks, a
layout without tabs is a :class:`LayoutError` naming the file, the layout and
the word, before any window opens.
"""

from __future__ import annotations

import configparser
from dataclasses import dataclass, field
from pathlib import Path
from typing import Dict, List, Sequence, Tuple

from walkman import MODELS_DIR

DEFAULT_LAYOUTS = MODELS_DIR / "pilot_layouts.ini"
#: Widgets that stand alone; the others name a module (``task:drc_valve``).
PLAIN_WIDGETS = ("modules", "view3d", "camera", "status", "link", "log")
MODULE_WIDGETS = ("task", "generic")
#: Widgets a window holds once (one librviz render window per process).
SINGLE_WIDGETS = ("view3d", "camera", "log")


class LayoutError(Exception):
    """A layout file or name is wrong; the text says where."""


@dataclass(frozen=True)
class Widget:
    kind: str          # one of PLAIN_WIDGETS or MODULE_WIDGETS
    module: str = ""

    def __str__(self) -> str:
        return f"{self.kind}:{self.module}" if self.module else self.kind


@dataclass
class Layout:
    name: str
    description: str = ""
    tabs: List[Tuple[str, List[Widget]]] = field(default_factory=list)
    side: List[Widget] = field(default_factory=list)

    def widgets(self) -> List[Widget]:
        return [w for _, ws in self.tabs for w in ws] + list(self.side)


def _widgets(text: str, where: str, modules: Sequence[str]) -> List[Widget]:
    out = []
    for word in text.split():
        kind, _, module = word.partition(":")
        if kind in PLAIN_WIDGETS and not module:
            out.append(Widget(kind))
        elif kind in MODULE_WIDGETS and module:
            if modules and module not in modules:
                raise LayoutError(f"{where}: '{word}' names module '{module}', which the bridge "
                                  f"configuration does not list ({', '.join(modules)})")
            out.append(Widget(kind, module))
        else:
            raise LayoutError(f"{where}: unknown widget '{word}' (widgets: "
                              f"{', '.join(PLAIN_WIDGETS)}, task:MODULE, generic:MODULE)")
    return out


def parse_layouts(text: str, source: str = "<layouts>",
                  modules: Sequence[str] = ()) -> Dict[str, Layout]:
    """Every layout of a layouts file's text; ``modules`` (if given) checks module names."""
    parser = configparser.ConfigParser(interpolation=None, delimiters=("=",))
    parser.optionxform = str  # tab titles keep their case
    try:
        parser.read_string(text, source=source)
    except configparser.Error as exc:
        raise LayoutError(" ".join(str(exc).split())) from None
    layouts: Dict[str, Layout] = {}
    for section in parser.sections():
        kind, _, name = section.partition(" ")
        if kind != "layout" or not name.strip():
            raise LayoutError(f"{source}: section [{section}] must be [layout NAME]")
        name = name.strip()
        layout = Layout(name)
        for key, value in parser.items(section):
            where = f"{source}: layout '{name}', {key}"
            if key == "description":
                layout.description = value
            elif key == "side":
                layout.side = _widgets(value, where, modules)
            elif key.startswith("tab ") and key[4:].strip():
                layout.tabs.append((key[4:].strip(), _widgets(value, where, modules)))
            else:
                raise LayoutError(f"{where}: unknown key (description, side, tab TITLE)")
        if not layout.tabs:
            raise LayoutError(f"{source}: layout '{name}' has no tab")
        for single in SINGLE_WIDGETS:
            if [str(w) for w in layout.widgets()].count(single) > 1:
                raise LayoutError(f"{source}: layout '{name}' shows {single} more than once "
                                  f"(one per window)")
        layouts[name] = layout
    if not layouts:
        raise LayoutError(f"{source}: no [layout NAME] section")
    return layouts


def load_layout(name: str, path: Path = DEFAULT_LAYOUTS, modules: Sequence[str] = ()) -> Layout:
    try:
        text = Path(path).read_text()
    except OSError as exc:
        raise LayoutError(f"cannot read layouts file {path}: {exc.strerror}") from None
    layouts = parse_layouts(text, str(path), modules)
    if name not in layouts:
        raise LayoutError(f"{path} has no layout '{name}' (layouts: {', '.join(layouts)})")
    return layouts[name]
