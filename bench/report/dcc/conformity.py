"""Conformity in the DCC: each check of the run on the quantity it judges.

ILAC-G8 layout as PTB's good practice has it: `measurementMetaData/metaData` with refType
basic_conformity, the rule (norm and clause), the decision in words, `conformity` pass or
fail, and the acceptance limits -T/+T (or the expected value of a consistency check).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from lxml import etree

from bench.report.certificate.parts import Sources
from bench.report.dcc import units as U
from bench.report.dcc import vocab as V
from bench.report.dcc.xml import DCC_NS, el, ident, name, quantity, statement, text_el
from bench.report.result_frame import Check

ILAC_G8 = "ILAC-G8:09/2019"
RULE_REFERENCE = {"simple": "4.2.1 simple acceptance (shared risk)",
                  "guard-band": "4.2.2 guarded acceptance, guard band w = U"}


@dataclass
class Checks:
    """The run's checks, each handed to the quantity it judges (or left for statements)."""

    items: list[Check]
    used: set[int] = field(default_factory=set)

    def take(self, axis: str | None, rate: float | None, quantity_key: str
             ) -> list[tuple[int, Check]]:
        found = []
        for i, c in enumerate(self.items):
            if i in self.used or c.quantity != quantity_key:
                continue
            if axis is not None and c.axis not in (axis, None):
                continue
            c_rate = c.figure("set_rate_dps")
            if (rate is None) != (c_rate is None) or (rate is not None and c_rate != rate):
                continue
            self.used.add(i)
            found.append((i, c))
        return found

    def rest(self) -> list[tuple[int, Check]]:
        return [(i, c) for i, c in enumerate(self.items) if i not in self.used]


def checks_of(src: Sources) -> list[Check]:
    """The run's checks[], from the typed frame."""
    return list(src.frame.checks)


def judge(q: etree._Element, found: list[tuple[int, Check]], unit: str,
          magnitude: bool = False) -> None:
    """Each check as measurementMetaData on the quantity it judges (good-practice layout);
    `magnitude`: the quantity is a standard deviation (one-sided, never below 0), which
    has no lower limit."""
    if not found:
        return
    meta = el(q, "measurementMetaData")
    for i, c in found:
        rule = c.rule or "simple"
        verdict = {"pass": "pass", "fail": "fail"}.get(str(c.verdict).lower())
        md = el(meta, "metaData", id=ident("check", i + 1), ref_type=V.CONFORMITY)
        name(md, f"Check {i + 1}: conformity with the tolerance")
        if rule in RULE_REFERENCE:
            el(md, "norm", ILAC_G8)
            el(md, "reference", RULE_REFERENCE[rule])
        text_el(md, "declaration", f"{(c.verdict or '').upper()}: "
                f"{c.reason or 'no reason recorded'}. Decision rule: {rule}.")
        if verdict:
            el(md, "conformity", verdict)
        suffix = next((s for s in ("rel", "dph", "dps", "deg", "s")
                       if c.states(f"value_{s}")), "rel")
        tol, expected = c.figure(f"tolerance_{suffix}"), c.figure(f"expected_{suffix}")
        cunit = U.BY_SUFFIX.get(suffix, unit)
        data = el(md, "data")
        cid = ident("check", i + 1)
        if tol is not None:
            _limits(data, cid, c, rule, suffix, tol, cunit, magnitude)
        if expected is not None:
            quantity(data, f"{cid}_expected", "expected value", V.REFERENCE, expected, cunit)
        if not len(data):
            md.remove(data)


def _limits(data: etree._Element, cid: str, c: Check, rule: str, suffix: str,
            tol: float, unit: str, one_sided: bool) -> None:
    """The tolerance T (the maker's specification) and the acceptance limits the decision
    rule derives from it (ILAC-G8:09/2019 4.2): simple acceptance accepts within T;
    guarded acceptance within T - U for a two-sided value; a standard deviation (one-sided,
    never below 0) has no lower limit, and under guarded acceptance its one-sided upper
    limit, not the value, is held against T."""
    if not one_sided:
        quantity(data, f"{cid}_tol_low", "lower tolerance limit (-T)", V.TOLERANCE_LOW,
                 -tol, unit)
    quantity(data, f"{cid}_tol_high", "upper tolerance limit (+T)", V.TOLERANCE_HIGH, tol,
             unit)
    u = c.figure(f"U_{suffix}") if c.figure(f"U_{suffix}") is not None else \
        c.figure(f"u_{suffix}")
    if rule == "guard-band" and one_sided:
        upper = c.figure(f"upper_{suffix}")
        if upper is not None:
            quantity(data, f"{cid}_upper", "one-sided 97.5 % upper limit of the value "
                     "(chi-square), held against the acceptance limit", V.REFERENCE, upper,
                     unit)
        quantity(data, f"{cid}_high", "upper acceptance limit for that upper limit (T)",
                 V.LIMIT_HIGH, tol, unit)
        return
    guard = u if rule == "guard-band" and u is not None else 0.0
    if rule == "guard-band" and u is None:
        return                   # no U: no guarded acceptance limit can be stated
    if not one_sided:
        quantity(data, f"{cid}_low", "lower acceptance limit (-T + w)" if guard else
                 "lower acceptance limit (-T)", V.LIMIT_LOW, -tol + guard, unit)
    quantity(data, f"{cid}_high", "upper acceptance limit (T - w)" if guard else
             "upper acceptance limit (T)", V.LIMIT_HIGH, tol - guard, unit)


def leftover_checks(root: etree._Element, src: Sources, checks: Checks) -> None:
    """A check whose quantity the writer did not place still gets its statement."""
    rest = checks.rest()
    if not rest:
        return
    sts = root.find(f"{{{DCC_NS}}}administrativeData/"
                    f"{{{DCC_NS}}}statements")
    for i, c in rest:
        verdict = {"pass": "pass", "fail": "fail"}.get(str(c.verdict).lower())
        statement(sts, V.CONFORMITY, f"Check {i + 1} ({c.axis}, "
                  f"{c.quantity}): {(c.verdict or '').upper()}: "
                  f"{c.reason or 'no reason recorded'}",
                  sid=ident("check", i + 1), conformity=verdict)
