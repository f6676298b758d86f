"""Measurement procedures the engine runs, as plug-ins (python-can's interfaces are the model).

A procedure kind turns a validated config into a plan, executes each step of it on the
bench, and analyses a run directory's raw data into result.json. The engine knows
nothing of rate ladders or drift pulses.
"""

from __future__ import annotations

import importlib
import importlib.util
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from procedures.base import ProcedureKind

#: procedure name (the `procedure:` key) -> module defining `KIND`
REGISTRY: dict[str, str] = {
    "rate-ladder": "procedures.rate_ladder",
    "drift-pulse": "procedures.drift_pulse",
}


def procedure_names() -> list[str]:
    return [name for name, mod in REGISTRY.items() if importlib.util.find_spec(mod)]


def procedure_kind(name: str) -> ProcedureKind:
    return importlib.import_module(REGISTRY[name]).KIND
