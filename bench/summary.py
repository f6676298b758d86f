"""The summary table `bench run` and `bench analyze` print at the end.

Values and U are rounded as on the certificate (U to two significant digits, the value
to U's decimal), so the console never shows a figure the certificate does not.
"""

from __future__ import annotations

from typing import Any

from bench.certificate.rounding import format_value_u


def _pct(x: float | None, digits: int = 3) -> str:
    return "-" if x is None else f"{x * 100:.{digits}f} %"


def _ppm(x: float | None) -> str:
    return "-" if x is None else f"{x * 1e6:.3f}"


def summary_lines(result: dict[str, Any]) -> list[str]:
    out = [""]
    axes = result.get("axes") or {}
    if axes:
        head = (f"{'axis':<7}{'set deg/s':>11}{'turns':>6}  {'rate error ± U(k=2), ppm':<26}"
                f"{'instab. ppm':>12}{'intra-turn':>12}{'corrected':>12}  verdict")
        out += [head, "-" * len(head)]
        for name, ax in axes.items():
            for r in ax.get("rates", []):
                err = format_value_u(r.get("rate_error_rel"), r.get("rate_error_u_rel"),
                                     1e6, signed=True).joined()
                out.append(
                    f"{name:<7}{r['set_rate_dps']:>+11g}{r.get('turns', 0):>6}  {err:<26}"
                    f"{_ppm(r.get('rate_instability_rel')):>12}"
                    f"{_pct(r.get('intra_turn_instability_rel')):>12}"
                    f"{_pct(r.get('intra_turn_instability_corrected_rel')):>12}  "
                    f"{r.get('verdict', '-').upper()}")
            for p in ax.get("pairs", []):
                k = format_value_u(p["k"], p["k_u"]).joined()
                w0 = format_value_u(p["w0_dps"], p["w0_u_dps"], signed=True).joined("deg/s")
                out.append(f"{name:<7}{p['rate_dps']:>11g}  k = {k}   w0 = {w0}")
    drift = result.get("drift")
    if drift:
        for name, ax in drift.get("axes", {}).items():
            own = format_value_u(ax["own_dph"], ax["own_u_dph"], signed=True).joined("deg/h")
            app = format_value_u(ax["apparent_dph"], ax["apparent_u_dph"],
                                 signed=True).joined("deg/h")
            out.append(f"{name}: own drift {own}, apparent {app}")
        if "azimuth_deg" in drift:
            az = format_value_u(drift["azimuth_deg"], drift["azimuth_u_deg"]).joined("deg")
            out.append(f"azimuth {az}")
    out.append(f"verdict: {str(result.get('verdict', '-')).upper()}")
    return out
