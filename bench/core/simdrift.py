"""Twins that drift across runs: a FOG scale step or ramp from run N (stand `sim:` keys).

Measurement assurance (docs/method.md C) is shown on twins only if a twin can change
between runs the way a real FOG does after a knock or with age:

    sim:
      run_number: 9                 # this run's number; absent: 1 + the runs of this
                                    # table in the records (resolved at the run's start)
      axes:
        outer:
          fog: {scale: 1.0003,
                scale_step: {from_run: 9, rel: 2.4e-5},        # scale * (1 + rel) from run 9
                scale_ramp: {from_run: 3, rel_per_run: 1e-7}}  # and/or + rel_per_run a run

`drifted(stand, run_number)` turns these keys into the truth's plain `scale` for this
run, before any twin sees the stand, and says what it applied.
"""

from __future__ import annotations

import copy
from collections.abc import Mapping
from typing import Any

DRIFT_KEYS = ("scale_step", "scale_ramp")


def has_drift(stand: Mapping[str, Any]) -> bool:
    axes = ((stand.get("sim") or {}).get("axes") or {})
    return any(k in ((a or {}).get("fog") or {}) for a in axes.values()
               if isinstance(a, Mapping) for k in DRIFT_KEYS)


def stated_run_number(stand: Mapping[str, Any]) -> int | None:
    n = (stand.get("sim") or {}).get("run_number")
    return int(n) if n is not None else None


def drifted(stand: Mapping[str, Any], run_number: int) -> tuple[dict[str, Any], list[str]]:
    """The stand with each drifting FOG's scale for run `run_number`; what was applied."""
    out = copy.deepcopy(dict(stand))
    notes = []
    for axis, a in ((out.get("sim") or {}).get("axes") or {}).items():
        fog = (a or {}).get("fog")
        if not isinstance(fog, dict):
            continue
        step, ramp = fog.pop("scale_step", None), fog.pop("scale_ramp", None)
        rel = 0.0
        if step and run_number >= int(step["from_run"]):
            rel += float(step["rel"])
        if ramp and run_number >= int(ramp["from_run"]):
            rel += float(ramp["rel_per_run"]) * (run_number - int(ramp["from_run"]) + 1)
        if step or ramp:
            fog["scale"] = float(fog.get("scale", 1.0)) * (1.0 + rel)
            notes.append(f"sim: axis {axis} FOG scale x (1 {rel:+.3g}) in run {run_number}")
    return out, notes
