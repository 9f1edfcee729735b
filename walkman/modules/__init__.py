"""GYM modules: one per task.  ``walkman-module NAME`` runs ``walkman.modules.NAME.Module``."""

from __future__ import annotations

import importlib
import importlib.util
from typing import Optional


class ModuleLoadError(ImportError):
    """One of our modules is there but cannot be loaded: the message names it and why."""


def module_class(name: str) -> Optional[type]:
    """The GYM module class behind a configured name when it is one of ours; None when no
    module of ours has that name (another team's, configured in the bridge's XML).  One of
    ours that fails to import, or has no ``Module``, is an error that names it and the cause:
    a gateway must not quietly fall back to decoding its statuses generically."""
    if not name.isidentifier() or importlib.util.find_spec(f"walkman.modules.{name}") is None:
        return None
    try:
        found = importlib.import_module(f"walkman.modules.{name}")
    except Exception as exc:  # its import ran its code: any error is the module's
        raise ModuleLoadError(f"walkman.modules.{name} cannot be imported: "
                              f"{type(exc).__name__}: {exc}") from exc
    cls = getattr(found, "Module", None)
    if cls is None:
        raise ModuleLoadError(f"walkman.modules.{name} has no Module class")
    return cls
