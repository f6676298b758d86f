"""The containers of result.json the certificate reads, checked before it reads them.

A certificate must not crash on a result that lacks a field or carries one of the wrong
type: that would leave the operator with raw data and no report. Every container the
builder walks is checked here once; one of the wrong type is dropped and named, and the
certificate lists what it ignored (section Deviations). Leaf values (numbers, text) are
checked where they are printed. The containers every result has are here; those of the
kind's own part, the kind declares (`bench.core.registry.ShapesResult.result_shape`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

# dict: a mapping (its keys free); {"*": x}: a mapping whose every value is x;
# {"key": x}: a mapping whose `key` is x when present; [x]: a list of x; [x, "key"]: a
# list of x whose entries without a numeric `key` are dropped (and named): they mean
# nothing without that number.
Spec = Any
RESULT: Spec = {
    "stand": dict, "instruments": {"*": dict}, "dates": dict, "conditions": dict,
    "certificate": dict, "method": dict, "procedure_file": dict, "raw_files": [dict],
    "checks": [dict],
}


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
        required = spec[1] if isinstance(spec, list) and len(spec) > 1 else None
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


def kind_shape(result: Any) -> dict[str, Spec]:
    """The containers of the kind's part: the kind the result names, else (an older
    result) every installed kind's (their parts have keys of their own)."""
    from bench.core.registry import ShapesResult, installed_records, procedure_names

    named = result.get("procedure") if isinstance(result, Mapping) else None
    shape: dict[str, Spec] = {}
    for name in [str(named)] if named else procedure_names():
        kind = installed_records(name)
        if isinstance(kind, ShapesResult):
            shape.update(kind.result_shape)
    return shape


def conform_result(result: Any) -> tuple[dict[str, Any], list[str]]:
    """The result with malformed containers dropped, and the list of what was dropped."""
    dropped: list[str] = []
    fixed = conform(result, {**kind_shape(result), **RESULT}, (), dropped)
    if fixed is None:
        return {}, ["result.json (expected a mapping)"]
    return fixed, dropped
