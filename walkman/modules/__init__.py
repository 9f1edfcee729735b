"""GYM modules: one per task.  ``walkman-module NAME`` runs ``walkman.modules.NAME.Module``."""

from __future__ import annotations

import importlib
from typing import Optional


def module_class(name: str) -> Optional[type]:
    """The GYM module class behind a configured name, when it is one of ours."""
    try:
        return getattr(importlib.import_module(f"walkman.modules.{name}"), "Module")
    except (ImportError, AttributeError):
        return None
