"""The drift-pulse procedure's uncertainty budgets (EA-4/02 form, bench.report.budget), built from
the analysis results in result.json and added to it (`budgets` lists; additions only):
own and apparent drift per axis (docs/method.md B: w_own = (w_0 + w_180)/2, w_app =
(w_0 - w_180)/2), and the platform azimuth A = atan2(-app_y, app_x) (method B).

The analysis (procedures/drift_pulse/analysis.py) gives each source's standard uncertainty in
deg/h (`budget.*_ustd_dph`); this module states their distribution, sensitivity and
degrees of freedom and combines them, so the reader sees where each U comes from.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from bench.report.budget import NORMAL, RECTANGULAR, STUDENT_T, Budget, Term, num

#: each source the analysis names: (label, distribution, Type A?)
SOURCES: dict[str, tuple[str, str, bool]] = {
    "repeatability": ("scatter of the cycles' drifts (Type A)", STUDENT_T, True),
    "angle_sensor_scale": ("command angle sensor scale k_as, calibration (Type B)", NORMAL,
                           False),
    "pulse_mismatch": ("+/- pulse mismatch, stated bound (Type B)", RECTANGULAR, False),
    "start_offset": ("integration start offset, measured by the timing cycles (Type B)",
                     NORMAL, False),
    "drift_random_walk": ("gyro drift random walk over the run (Type B, its spec)",
                          NORMAL, False),
    "turn_position": ("turntable landing within its position tolerance (Type B)",
                      RECTANGULAR, False),
}


def _drift_budget(d: Mapping[str, Any], which: str) -> Budget | None:
    terms_in = ((d.get("budget") or {}).get(f"{which}_ustd_dph")
                or (d.get("budget") or {}).get(f"{which}_u_dph"))
    value = num(d.get(f"{which}_dph"))
    if not isinstance(terms_in, Mapping) or value is None:
        return None
    cycles = d.get("cycles")
    n = len(cycles) if isinstance(cycles, list) else None
    terms = []
    for key, u in terms_in.items():
        uu = num(u)
        if uu is None:
            continue
        label, dist, type_a = SOURCES.get(key, (key.replace("_", " "), NORMAL, False))
        # the analysis takes the Type A term as GUM-S1's scaled t (s/sqrt(n) widened by
        # sqrt((n-1)/(n-3)), n = cycles per position): its nu is then infinite and k = 2
        # (docs/method.md D1 states this exception of part B)
        terms.append(Term(label + (f" (scaled t, GUM-S1 6.4.9, {n} cycles)" if type_a and n
                                   else ""), value if type_a else 0.0, uu, dist, 1.0, None,
                          "deg/h"))
    if not terms:
        return None
    return Budget(f"{which} drift", f"{which}_dph", "deg/h", value, tuple(terms),
                  num(d.get(f"{which}_U_dph") or d.get(f"{which}_u_dph")))


def azimuth_budget(drift: Mapping[str, Any]) -> Budget | None:
    """A = atan2(-app_y, app_x): dA/dapp_x = app_y / r^2, dA/dapp_y = -app_x / r^2 (rad
    per deg/h), r^2 = app_x^2 + app_y^2; in deg per deg/h."""
    axes = drift.get("axes") or {}
    x, y = axes.get("x") or {}, axes.get("y") or {}
    ax, ay = num(x.get("apparent_dph")), num(y.get("apparent_dph"))
    ux = num(x.get("apparent_U_dph") or x.get("apparent_u_dph"))
    uy = num(y.get("apparent_U_dph") or y.get("apparent_u_dph"))
    az = num(drift.get("azimuth_deg"))
    if None in (ax, ay, ux, uy, az) or (ax == 0 and ay == 0):
        return None
    assert ax is not None and ay is not None and ux is not None and uy is not None
    r2 = ax * ax + ay * ay
    deg = 180.0 / math.pi
    terms = (Term("apparent drift of X, app_x (its budget above)", ax, ux / 2, NORMAL,
                  deg * ay / r2, None, "deg/h"),
             Term("apparent drift of Y, app_y (its budget above)", ay, uy / 2, NORMAL,
                  -deg * ax / r2, None, "deg/h"))
    return Budget("platform azimuth A", "azimuth_deg", "deg", az, terms,
                  num(drift.get("azimuth_U_deg") or drift.get("azimuth_u_deg")))


def add_budgets(result: dict[str, Any]) -> dict[str, Any]:
    """result.json with `budgets` lists under drift.axes.<axis> and drift (additions only)."""
    drift = result.get("drift")
    if not isinstance(drift, dict):
        return result
    for d in (drift.get("axes") or {}).values():
        if isinstance(d, dict):
            d["budgets"] = [b.to_dict() for b in (_drift_budget(d, "own"),
                                                    _drift_budget(d, "apparent"))
                            if b is not None]
    az = azimuth_budget(drift)
    drift["budgets"] = [az.to_dict()] if az is not None else []
    return result
