"""One naming rule for uncertainties in result.json (docs/certificate.md, "result.json").

- `<name>_U<_unit>`: the expanded uncertainty for about 95 %: k = 2, or t(nu_eff) where the
  budget states it (docs/method.md D1) (e.g. `rate_error_U_rel`, `k_U`).
- `<name>_ustd<_unit>`: the standard uncertainty, k = 1 (e.g. `timing_ustd_rel`).

The keys CONTRACT §3 binds end in `_u` (`rate_error_u_rel`, `k_u`, `w0_u_dps`,
`own_u_dph`...) and mean the expanded uncertainty; they stay, and every `_u` key of the
result gets its explicit twin beside it, so a reader never has to guess: `_U` when the `_u`
is expanded, `_ustd` when it is a standard uncertainty (the budgets, the half means, a
cycle's fitted offset). Which `_u` keys are standard is stated here, once.

A kind whose result is a typed model writes its twins as fields of their own (the drift
kind, procedures/drift_pulse/result.py) and adds its body to the document after this rule
has run, so no key of it is derived here (its checks carry their twins too, so the rule
finds nothing to add to them); the rule serves the frame and the kinds not yet converted
(issue 60).
"""

from __future__ import annotations

import re
from typing import overload

#: mappings whose `_u` entries are standard uncertainties (k = 1): uncertainty budgets
STANDARD_PARENTS = frozenset({"rate_error_budget", "budget", "own_u_dph", "apparent_u_dph"})
#: `_u` keys that are standard wherever they appear (inputs and intermediate means)
STANDARD_KEYS = frozenset({"timing_u_rel", "timebase_u_rel", "repeatability_u_rel",
                           "edge_u_s", "period_u_s", "timestamp_u_s", "fog_mean_u_dps",
                           "counter_mean_u_dps", "timebase_correction_u_rel"})
#: lists whose items' `_u` entries are standard (one cycle's fit)
STANDARD_ITEMS = frozenset({"cycles"})

#: stated in every result.json, so the file explains itself
UNCERTAINTY_NAMING = ("_U: expanded uncertainty for about 95 %, k = 2 or t(nu_eff) where the "
                      "budget states it (coverage_factor, dof_eff); _ustd: standard "
                      "uncertainty, k = 1; "
                      "_u (the names CONTRACT section 3 binds, kept): the same value as the "
                      "_U or _ustd key beside it")

_U_KEY = re.compile(r"^(?P<stem>.+?)_u(?P<unit>_.+)?$")


def explicit_name(key: str, standard: bool) -> str | None:
    """`rate_error_u_rel` -> `rate_error_U_rel` (or `_ustd_` if standard); None if `key`
    names no uncertainty."""
    mark = "ustd" if standard else "U"
    if key.startswith("u_"):             # a check's `u_rel`, `u_dph`
        return f"{mark}{key[1:]}"
    m = _U_KEY.match(key)
    if not m:
        return None
    return f"{m['stem']}_{mark}{m['unit'] or ''}"


@overload
def with_explicit_names(doc: dict[str, object], parent: str = "", item_of: str = ""
                        ) -> dict[str, object]: ...
@overload
def with_explicit_names(doc: object, parent: str = "", item_of: str = "") -> object: ...


def with_explicit_names(doc: object, parent: str = "", item_of: str = "") -> object:
    """A copy of `doc` with the explicit twin beside every `_u` key (values unchanged)."""
    if isinstance(doc, list):
        return [with_explicit_names(x, parent, parent) for x in doc]
    if not isinstance(doc, dict):
        return doc
    out: dict[str, object] = {}
    for key, value in doc.items():
        out[key] = with_explicit_names(value, key)
        if isinstance(value, list) or (isinstance(value, dict) and parent != "budget"):
            continue
        standard = (key in STANDARD_KEYS or parent in STANDARD_PARENTS
                    or item_of in STANDARD_ITEMS)
        twin = explicit_name(key, standard)
        if twin is not None and twin not in doc:
            out[twin] = out[key]
    return out
