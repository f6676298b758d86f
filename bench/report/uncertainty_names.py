"""One naming rule for uncertainties in result.json (docs/certificate.md, "result.json").

- `<name>_U<_unit>`: the expanded uncertainty for about 95 %: k = 2, or t(nu_eff) where the
  budget states it (docs/method.md D1) (e.g. `rate_error_U_rel`, `k_U`).
- `<name>_ustd<_unit>`: the standard uncertainty, k = 1 (e.g. `timing_ustd_rel`).

The keys CONTRACT §3 binds end in `_u` (`rate_error_u_rel`, `k_u`, `w0_u_dps`,
`own_u_dph`...) and mean the expanded uncertainty; they stay, and every `_u` key of the
result has its explicit twin beside it, so a reader never has to guess: `_U` when the `_u`
is expanded, `_ustd` when it is a standard uncertainty (the budgets, the half means, a
cycle's fitted offset). Each kind's result model writes the twins as fields of their own
(procedures/rate_ladder/result.py, procedures/drift_pulse/result.py; issue 60): no key is
derived by a rule over names. This module states the rule, in every result.json.
"""

from __future__ import annotations

#: stated in every result.json, so the file explains itself
UNCERTAINTY_NAMING = ("_U: expanded uncertainty for about 95 %, k = 2 or t(nu_eff) where the "
                      "budget states it (coverage_factor, dof_eff); _ustd: standard "
                      "uncertainty, k = 1; "
                      "_u (the names CONTRACT section 3 binds, kept): the same value as the "
                      "_U or _ustd key beside it")
