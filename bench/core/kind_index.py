"""Where the installed procedure kinds are: read by the kind registry
(bench/core/registry.py) and by the journal codec (bench/core/events.py, to find each
kind's declared events). A leaf module: it imports nothing of the bench, so both can use
it without an import cycle.
"""

from __future__ import annotations

import importlib
import pkgutil
from functools import cache
from importlib.metadata import entry_points

GROUP = "ratebench.procedures"
#: where an install whose metadata predates the entry points finds the kinds (an old
#: editable install): every module of this package that defines `KIND`
FALLBACK_PACKAGE = "procedures"


@cache
def registered() -> dict[str, str]:
    """procedure name -> "module:attribute" of its kind."""
    found = {ep.name: ep.value for ep in entry_points(group=GROUP)}
    if found:
        return found
    try:
        package = importlib.import_module(FALLBACK_PACKAGE)
    except ImportError:
        return {}
    for info in pkgutil.iter_modules(package.__path__, f"{FALLBACK_PACKAGE}."):
        kind = getattr(importlib.import_module(info.name), "KIND", None)
        if kind is not None:
            found[kind.name] = f"{info.name}:KIND"
    return found
