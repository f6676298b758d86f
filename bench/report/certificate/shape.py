"""The containers of result.json the certificate reads, checked before it reads them.

A certificate must not crash on a result that lacks a field or carries one of the wrong
type: that would leave the operator with raw data and no report. Every container the
builder walks is checked here once; one of the wrong type is dropped and named, and the
certificate lists what it ignored (section Deviations). Leaf values (numbers, text) are
checked where they are printed.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

# dict: a mapping (its keys free); {"*": x}: a mapping whose every value is x;
# {"key": x}: a mapping whose `key` is x when present; [x]: a list of x.
Spec = Any
_RATE: Spec = {"systematic": {"harmonics": [dict], "mains": dict, "binned": dict},
               "intra_turn": {"averaged": [dict]}, "counter_rate_dps": list}
RESULT: Spec = {
    "stand": dict, "instruments": {"*": dict}, "dates": dict, "conditions": dict,
    "certificate": dict, "method": dict, "procedure_file": dict, "raw_files": [dict],
    "checks": [dict],
    "axes": {"*": {"rates": [_RATE], "pairs": [dict], "noise_floor": dict}},
    "drift": {"axes": {"*": {"cycles": [dict], "positions": [dict], "start_offset": dict,
                             "example_cycle": dict,
                             "budget": {"own_u_dph": dict, "apparent_u_dph": dict}}}},
}
# entries meaningless without these numbers are dropped, and named
REQUIRED = {"rates": "set_rate_dps", "pairs": "rate_dps", "harmonics": "order"}


def _is_number(x: Any) -> bool:
    if isinstance(x, bool):
        return False
    try:
        return math.isfinite(float(x))
    except (TypeError, ValueError):
        return False


def _where(path: tuple[str | int, ...]) -> str:
    out = ""
    for p in path:
        out += f"[{p}]" if isinstance(p, int) else (f".{p}" if out else str(p))
    return out


def conform(value: Any, spec: Spec, path: tuple[str | int, ...],
            dropped: list[str]) -> Any:
    """`value` with every container that does not fit `spec` removed (and named)."""
    if spec is dict or isinstance(spec, dict):
        if not isinstance(value, Mapping):
            dropped.append(f"{_where(path)} (expected a mapping, found "
                           f"{type(value).__name__})")
            return None
        out = dict(value)
        if isinstance(spec, dict):
            for key, inner in spec.items():
                targets = list(out) if key == "*" else [key] if key in out else []
                for k in targets:
                    if out[k] is None:  # null means absent
                        del out[k]
                        continue
                    fixed = conform(out[k], inner, (*path, k), dropped)
                    if fixed is None:
                        del out[k]
                    else:
                        out[k] = fixed
        return out
    if spec is list or isinstance(spec, list):
        if not isinstance(value, list):
            dropped.append(f"{_where(path)} (expected a list, found {type(value).__name__})")
            return None
        if spec is list:
            return value
        out_list = []
        required = REQUIRED.get(str(path[-1])) if path else None
        for i, item in enumerate(value):
            fixed = conform(item, spec[0], (*path, i), dropped)
            if fixed is None:
                continue
            if required and not _is_number(fixed.get(required)):
                dropped.append(f"{_where((*path, i))} (no numeric {required})")
                continue
            out_list.append(fixed)
        return out_list
    return value


def conform_result(result: Any) -> tuple[dict[str, Any], list[str]]:
    """The result with malformed containers dropped, and the list of what was dropped."""
    dropped: list[str] = []
    fixed = conform(result, RESULT, (), dropped)
    if fixed is None:
        return {}, ["result.json (expected a mapping)"]
    return fixed, dropped
