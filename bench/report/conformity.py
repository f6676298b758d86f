"""Statements of conformity: a measured value, its U (k = 2), a tolerance, a decision rule.

Two rules, chosen in the procedure file (`decision_rule`), as ILAC-G8 describes them:
- simple acceptance: pass when |value| <= tolerance; U is stated but does not move the
  limit (the risk of a false pass near the limit is up to 50 %);
- guard band by U: pass only when |value| + U <= tolerance (false pass below ~2.5 %); a
  value inside the tolerance but within U of the limit fails, and says so.
One rule for a quantity that is not resolved (an upper limit "< L" instead of value +/- U,
`judge_limit`): it conforms when L is within the tolerance, under either rule (L is already
a one-sided limit at the stated level, so it is its own guard band); it is NOT ASSESSED only
when L exceeds the tolerance (the data then neither show conformity nor refute it).
Beside each decision, the RMG 63-2003 capability rule: the measurement's error limit
(here U) should not exceed 0.2-0.3 of the tolerance it checks (docs/method.md A6).
"""

from __future__ import annotations

import msgspec

RULES = {
    "simple": "simple acceptance: pass when |value| <= tolerance (U stated, not subtracted)",
    "guard-band": "guarded acceptance: pass when |value| + U <= tolerance (guard band = U)",
}
CAPABILITY_GOOD = 0.2
CAPABILITY_LIMIT = 0.3


class Check(msgspec.Struct, frozen=True, kw_only=True):
    """One judgement, as result.json's `checks[]` states it (a msgspec Struct: its field
    order is the key order; a kind's check with more fields derives from it). `U_rel` is
    `u_rel`'s explicit twin (the expanded U, k = 2: bench/report/uncertainty_names.py)."""

    axis: str
    set_rate_dps: float
    quantity: str
    value_rel: float
    u_rel: float
    U_rel: float | None = None       # noqa: N815 - u_rel's twin; None: the same as u_rel
    tolerance_rel: float
    rule: str
    verdict: str
    reason: str
    capability_ratio: float
    capability_ok: bool
    upper_rel: float | None = None   # the one-sided limit L of an unresolved value
    one_sided: bool = False          # the statement is "< L" (judged on L, judge_limit)


def judge(axis: str, set_rate_dps: float, quantity: str, value_rel: float, u_rel: float,
          tolerance_rel: float, rule: str) -> Check:
    if rule not in RULES:
        raise ValueError(f"decision rule {rule!r}: expected one of {', '.join(RULES)}")
    mag = abs(value_rel)
    ratio = u_rel / tolerance_rel
    if mag > tolerance_rel:
        verdict, reason = "fail", (f"|value| {mag:.3g} exceeds the tolerance "
                                   f"{tolerance_rel:.3g}")
    elif rule == "guard-band" and mag + u_rel > tolerance_rel:
        verdict, reason = "fail", (f"|value| {mag:.3g} is inside the tolerance "
                                   f"{tolerance_rel:.3g} but within U = {u_rel:.2g} of it: "
                                   "the guard band is not met")
    else:
        verdict = "pass"
        reason = (f"|value| + U = {mag + u_rel:.3g} <= tolerance {tolerance_rel:.3g}"
                  if rule == "guard-band" else
                  f"|value| {mag:.3g} <= tolerance {tolerance_rel:.3g}")
    return Check(axis=axis, set_rate_dps=set_rate_dps, quantity=quantity, value_rel=value_rel,
                 u_rel=u_rel, tolerance_rel=tolerance_rel, rule=rule, verdict=verdict,
                 reason=reason, capability_ratio=ratio, capability_ok=ratio <= CAPABILITY_LIMIT)


def judge_limit(axis: str, set_rate_dps: float, quantity: str, value_rel: float,
                u_rel: float, upper_rel: float, tolerance_rel: float, rule: str,
                level: str) -> Check:
    """An unresolved quantity stated as "< L" (L = upper_rel, one-sided at `level`): pass
    when L <= tolerance, else not assessed (the module docstring's one rule)."""
    if rule not in RULES:
        raise ValueError(f"decision rule {rule!r}: expected one of {', '.join(RULES)}")
    ratio = u_rel / tolerance_rel
    if upper_rel <= tolerance_rel:
        verdict = "pass"
        reason = (f"not resolved: < {upper_rel:.3g} ({level} one-sided limit) <= tolerance "
                  f"{tolerance_rel:.3g}")
    else:
        verdict = "not-assessed"
        reason = (f"not resolved: its {level} one-sided limit {upper_rel:.3g} exceeds the "
                  f"tolerance {tolerance_rel:.3g}, so the data neither show conformity nor "
                  "refute it")
    return Check(axis=axis, set_rate_dps=set_rate_dps, quantity=quantity, value_rel=value_rel,
                 u_rel=u_rel, tolerance_rel=tolerance_rel, rule=rule, verdict=verdict,
                 reason=reason, capability_ratio=ratio, capability_ok=ratio <= CAPABILITY_LIMIT,
                 upper_rel=upper_rel, one_sided=True)
