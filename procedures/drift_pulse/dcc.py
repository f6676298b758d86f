"""The drift-pulse procedure's part of the DCC (docs/method.md part B): per gyro axis the
own and apparent drift with their budgets and the drift per platform position and cycle;
the platform azimuth and the horizontal Earth rate. `DriftDcc` answers the DCC writer's
questions (bench.report.dcc.parts.DccParts).
"""

from __future__ import annotations

from collections.abc import Sequence

from lxml import etree

from bench.report.budget import BudgetRecord
from bench.report.certificate import methods
from bench.report.certificate.parts import Sources
from bench.report.dcc import units as U
from bench.report.dcc import vocab as V
from bench.report.dcc.conformity import Checks, judge
from bench.report.dcc.parts import DccParts
from bench.report.dcc.xml import el, ident, list_quantity, name, num, quantity, text_el
from procedures.drift_pulse.codec import drift_model
from procedures.drift_pulse.result import AxisFigures, DriftFigures, PositionFigures, budget_of

# the drift procedure's refTypes, namespace "ratebench" (docs/dcc.md, section "refTypes")
OWN_DRIFT = V.RB + "ownDrift"
APPARENT_DRIFT = V.RB + "apparentDrift"
DRIFT_POSITION = V.RB + "driftPerPosition"
DRIFT_CYCLES = V.RB + "driftPerCycle"
TABLE_POSITION = V.RB + "tablePosition"
STD = V.RB + "standardDeviation"
AZIMUTH = V.RB + "azimuth"
EARTH_RATE = V.RB + "earthHorizontalRate"
LATITUDE = V.RB + "siteLatitude"

#: the sections of docs/method.md the drift procedure follows
METHOD_SECTIONS = ("B",)


class DriftDcc(DccParts):
    """The drift procedure's answers to the DCC (the kind's `dcc` part)."""

    def dcc_item(self, src: Sources) -> tuple[str, Sequence[str]]:
        return "gyro-platform test stand", list(src.model(drift_model).axes)

    def dcc_used_methods(self, src: Sources) -> tuple[str, Sequence[str]]:
        return methods.B_REFERENCE, METHOD_SECTIONS

    def dcc_results(self, results: etree._Element, src: Sources, checks: Checks) -> None:
        drift_results(results, src.model(drift_model), checks)


def _k(budgets: Sequence[BudgetRecord], key: str) -> float | None:
    """The coverage factor of figure `key`'s budget, stated beside it in result.json
    (procedures/drift_pulse/result.py; docs/method.md D1); None: k = 2."""
    budget = budget_of(budgets, key)
    return None if budget is None else budget.k


def drift_results(results: etree._Element, drift: DriftFigures, checks: Checks) -> None:
    """The platform's measurementResult: the site latitude as its influence condition,
    each axis's drift (own, apparent, per position), then the platform's azimuth and
    horizontal Earth rate (docs/method.md B)."""
    mr = el(results, "measurementResult", id="platform", ref_id="item")
    name(mr, "Gyro platform: own and apparent drift per axis, azimuth (docs/method.md B)")
    lat = num(drift.latitude_deg)
    if lat is not None:
        conds = el(mr, "influenceConditions")
        c = el(conds, "influenceCondition", id="siteLatitude", ref_type=LATITUDE)
        name(c, "Site latitude")
        quantity(el(c, "data"), None, "latitude", LATITUDE, lat, U.DEG,
                 label="drift.latitude_deg")
    res = el(mr, "results")
    for axis, ax in drift.axes.items():
        _axis_result(res, axis, ax, checks)
    _platform_result(res, drift, checks)
    if not len(res):
        r = el(res, "result")
        name(r, "No drift results")
        text_el(el(r, "data"), "text", "Nothing was measured to completion.")


def _axis_result(res: etree._Element, axis: str, ax: AxisFigures, checks: Checks) -> None:
    """One axis: its own and apparent drift with U, and per platform position the mean,
    the spread and each cycle's drift."""
    path = f"drift.axes.{axis}"
    aid = ident("drift", axis)
    r = el(res, "result", id=aid, ref_type=V.MEASURED)
    name(r, f"Axis {axis}: drift, deg/h")
    data = el(r, "data")
    figures: tuple[tuple[str, float, float | None, str, str, str | None], ...] = (
        ("own_dph", ax.own_dph, ax.own_U_dph, "own drift (w_0 + w_180) / 2",
         f"{V.MEASURED} {OWN_DRIFT}", "own_drift"),
        ("apparent_dph", ax.apparent_dph, ax.apparent_U_dph, "apparent drift at position "
         "0, (w_0 - w_180) / 2", f"{V.MEASURED} {APPARENT_DRIFT}", "apparent_drift"),
        ("own_nominal_edges_dph", ax.own_nominal_edges_dph, None, "own drift with the "
         "pulse edges at the nominal sample times (the paper's integrator; for "
         "comparison)", OWN_DRIFT, None))
    for key, value, expanded, title, ref, check in figures:
        v = num(value)
        if v is None:
            continue
        node = quantity(data, ident(aid, key), title, ref, v, U.DEG_PER_H, num(expanded),
                        label=f"{path}.{key}", k=_k(ax.budgets, key))
        if check:
            judge(node, checks.take(axis, None, check), U.DEG_PER_H)
    for j, pos in enumerate(ax.positions):
        _position_list(data, aid, f"{path}.positions[{j}]", pos)


def _position_list(data: etree._Element, aid: str, pp: str, pos: PositionFigures) -> None:
    """One platform position: the drift's mean (a budget input), the cycles' spread and
    each cycle's drift."""
    table = pos.table_deg
    lst = el(data, "list", id=ident(aid, "pos", f"{table:g}"), ref_type=DRIFT_POSITION)
    name(lst, f"platform turned to {table:g} deg: drift per cycle and mean")
    quantity(lst, None, "platform position", TABLE_POSITION, table, U.DEG,
             label=f"{pp}.table_deg")
    mean = num(pos.mean_dph)
    if mean is not None:
        # a budget input: its standard uncertainty and dof, no U (docs/method.md D2)
        quantity(lst, ident(aid, "pos", f"{table:g}", "mean_dph"), "mean drift",
                 V.MEASURED, mean, U.DEG_PER_H, label=f"{pp}.mean_dph",
                 note="An input of the own and apparent drifts' budgets; its standard "
                      "uncertainty s/sqrt(n) beside it (nu = n - 1).")
        uu = num(pos.mean_ustd_dph)
        if uu is not None:
            quantity(lst, None, "standard uncertainty of the mean, s/sqrt(n)",
                     V.STANDARD_UNCERTAINTY, uu, U.DEG_PER_H,
                     label=f"{pp}.mean_ustd_dph")
    std = num(pos.std_dph)
    if std is not None:
        quantity(lst, None, "standard deviation of the cycles", STD, std, U.DEG_PER_H,
                 label=f"{pp}.std_dph")
    w = [v for v in (num(x) for x in pos.drifts_dph) if v is not None]
    if w:
        list_quantity(lst, ident(aid, "pos", f"{table:g}", "drifts_dph"),
                      "drift of each cycle, in order", DRIFT_CYCLES, w,
                      U.DEG_PER_H, note="Single-cycle values; their scatter (the "
                      "standard deviation above) is their uncertainty.")


def _platform_result(res: etree._Element, drift: DriftFigures, checks: Checks) -> None:
    """The platform's azimuth and horizontal Earth rate from the apparent drifts, beside
    the expected Earth rate."""
    plat = drift.platform
    if plat is None:
        return
    r = el(res, "result", id="azimuth", ref_type=V.MEASURED)
    name(r, "Platform azimuth and horizontal Earth rate from the apparent drifts")
    data = el(r, "data")
    platform: tuple[tuple[str, float | None, float | None, str, str, str, str | None],
                    ...] = (
        ("azimuth_deg", plat.azimuth_deg, plat.azimuth_U_deg, "platform azimuth of the X "
         "input axis, A = atan2(-app_y, app_x)", f"{V.MEASURED} {AZIMUTH}", U.DEG,
         "azimuth"),
        ("earth_horizontal_dph", plat.earth_horizontal_dph, plat.earth_horizontal_U_dph,
         "horizontal Earth rate from the apparent drifts", f"{V.MEASURED} {EARTH_RATE}",
         U.DEG_PER_H, "earth_horizontal_rate"),
        ("earth_horizontal_expected_dph", drift.earth_horizontal_expected_dph, None,
         "expected 15.041 deg/h x cos(latitude)", f"{V.REFERENCE} {EARTH_RATE}",
         U.DEG_PER_H, None))
    for key, given, expanded, title, ref, unit, check in platform:
        v = num(given)
        if v is None:
            continue
        node = quantity(data, ident("drift", key), title, ref, v, unit, num(expanded),
                        label=f"drift.{key}", k=_k(drift.budgets, key))
        if check:
            judge(node, checks.take(None, None, check), unit)
