"""The summary table `bench run` and `bench analyze` print at the end."""

from __future__ import annotations

from typing import Any


def _pct(x: float | None, digits: int = 3) -> str:
    return "-" if x is None else f"{x * 100:.{digits}f} %"


def _ppm(x: float | None) -> str:
    return "-" if x is None else f"{x * 1e6:+.3f}"


def summary_lines(result: dict[str, Any]) -> list[str]:
    out = [""]
    axes = result.get("axes") or {}
    if axes:
        head = (f"{'axis':<7}{'set deg/s':>11}{'turns':>6}  {'rate error ± U(k=2), ppm':<26}"
                f"{'instab. ppm':>12}{'intra-turn':>12}{'corrected':>12}  verdict")
        out += [head, "-" * len(head)]
        for name, ax in axes.items():
            for r in ax.get("rates", []):
                u = r.get("rate_error_u_rel")
                err = f"{_ppm(r.get('rate_error_rel'))} ± {'-' if u is None else f'{u * 1e6:.2g}'}"
                out.append(
                    f"{name:<7}{r['set_rate_dps']:>+11g}{r.get('turns', 0):>6}  {err:<26}"
                    f"{_ppm(r.get('rate_instability_rel'))[1:]:>12}"
                    f"{_pct(r.get('intra_turn_instability_rel')):>12}"
                    f"{_pct(r.get('intra_turn_instability_corrected_rel')):>12}  "
                    f"{r.get('verdict', '-').upper()}")
            for p in ax.get("pairs", []):
                out.append(f"{name:<7}{p['rate_dps']:>11g}  k = {p['k']:.7f} ± {p['k_u']:.1e}"
                           f"   w0 = {p['w0_dps']:+.5f} ± {p['w0_u_dps']:.1e} deg/s")
    drift = result.get("drift")
    if drift:
        for name, ax in drift.get("axes", {}).items():
            out.append(f"{name}: own drift {ax['own_dph']:+.4f} ± {ax['own_u_dph']:.4f} deg/h, "
                       f"apparent {ax['apparent_dph']:+.4f} ± {ax['apparent_u_dph']:.4f} deg/h")
        if "azimuth_deg" in drift:
            out.append(f"azimuth {drift['azimuth_deg']:.3f} ± {drift['azimuth_u_deg']:.3f} deg")
    out.append(f"verdict: {str(result.get('verdict', '-')).upper()}")
    return out
