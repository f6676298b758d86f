"""The rate ladder's certificate plots, as PNG bytes (bench/report/certificate/plotting.py).

Each function returns None when the result carries nothing to plot, so a partial run
still gets a certificate. Figures follow the seed paper's (figs. 4-5, 7, 8-9, 10).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Protocol

import numpy as np

from bench.report.certificate.plotting import figure_grid, plot_number, png_of
from procedures.rate_ladder.axes_view import PairRow, RateRow

if TYPE_CHECKING:   # matplotlib is imported when a plot is drawn (`bench validate` starts at once)
    from matplotlib.axes import Axes


# -- what the plots read (result.py's typed entries) -----------------------------------------

class HarmonicFit(Protocol):
    """One fitted harmonic of the rate along the turn (docs/method.md A4)."""

    @property
    def order(self) -> float | None: ...
    @property
    def amplitude_rel(self) -> float | None: ...
    @property
    def amplitude_u_rel(self) -> float | None: ...
    @property
    def phase_deg(self) -> float | None: ...


class IntraTurnFit(Protocol):
    """The floor-corrected intra-turn instability's interval (docs/method.md A5)."""

    @property
    def resolved(self) -> bool | None: ...
    @property
    def corrected_upper_rel(self) -> float | None: ...
    @property
    def raw_resolved(self) -> bool | None: ...
    @property
    def raw_upper_rel(self) -> float | None: ...


class BinnedCurve(Protocol):
    """The paper's binned average by angle (docs/method.md A4)."""

    @property
    def centres_deg(self) -> Sequence[float | None]: ...
    @property
    def deviation_rel(self) -> Sequence[float | None]: ...
    @property
    def u_rel(self) -> Sequence[float | None]: ...


class RatePoint(RateRow, Protocol):
    """One commanded rate and direction's results (docs/method.md A1-A5): what the station
    reads (axes_view.py), and the figures the plots draw besides."""

    @property
    def rate_error_u_rel(self) -> float | None: ...
    @property
    def rate_instability_u_rel(self) -> float | None: ...
    @property
    def rate_instability_floor_rel(self) -> float | None: ...
    @property
    def intra_turn_instability_rel(self) -> float | None: ...
    @property
    def intra_turn_instability_u_rel(self) -> float | None: ...
    @property
    def intra_turn_instability_corrected_rel(self) -> float | None: ...
    @property
    def harmonics(self) -> Sequence[HarmonicFit]: ...
    @property
    def binned(self) -> BinnedCurve | None: ...
    @property
    def intra(self) -> IntraTurnFit: ...


class PairPoint(PairRow, Protocol):
    """One +/- pair's FOG cross-calibration (docs/method.md A3), with the expanded
    uncertainties as the analysis wrote them."""

    @property
    def k_u(self) -> float | None: ...
    @property
    def w0_u_dps(self) -> float | None: ...


class AllanCurve(Protocol):
    """The FOG at rest: its Allan deviation (docs/method.md A5)."""

    @property
    def allan_tau_s(self) -> Sequence[float]: ...
    @property
    def allan_dev_dps(self) -> Sequence[float]: ...


DIRECTIONS = ((+1, "+ direction", "o", "C0"), (-1, "− direction", "s", "C3"))


def _rate_axis(ax: Axes, rates: Sequence[float]) -> None:
    pos = [abs(r) for r in rates if r]
    if pos and max(pos) / min(pos) > 20:
        ax.set_xscale("log")
    ax.set_xlabel("|commanded rate|, °/s", fontsize=8)


def per_turn(axis: str, rates: Sequence[RatePoint],
             tolerances: Mapping[str, Sequence[tuple[float, float]]], unit: tuple[str, float],
             inst_unit: tuple[str, float]) -> bytes | None:
    """Per-turn rate error and instability vs rate, by direction (paper figs. 4-5)."""
    if not rates:
        return None
    fig, (a1, a2) = figure_grid(2)
    for sign, label, marker, color in DIRECTIONS:
        rr = [r for r in rates if math.copysign(1, plot_number(r.set_rate_dps)) == sign]
        if not rr:
            continue
        x = np.array([abs(plot_number(r.set_rate_dps)) for r in rr]) * (1 + 0.02 * sign)
        for ax, key, (_uname, scale), values in (
                (a1, "rate_error", unit, [(r.rate_error_rel, r.rate_error_u_rel) for r in rr]),
                (a2, "rate_instability", inst_unit,
                 [(r.rate_instability_rel, r.rate_instability_u_rel) for r in rr])):
            y = np.array([plot_number(v) for v, _ in values]) * scale
            u = np.array([plot_number(vu) for _, vu in values]) * scale
            u = np.where(np.isfinite(u), u, 0.0)
            ok = np.ones(len(rr), dtype=bool)
            if key == "rate_instability":   # a σ at the timing floor: its limit only
                ok = np.array([r.rate_instability_resolved is not False for r in rr])
                up = np.array([plot_number(r.rate_instability_upper_rel) for r in rr]) * scale
                lim = ~ok & np.isfinite(up)
                if np.any(lim):
                    ax.plot(x[lim], up[lim], "v", color=color, ms=5, mfc="none",
                            label=f"{label}: upper limit (not resolved)")
            if np.any(ok):
                ax.errorbar(x[ok], y[ok], yerr=u[ok], fmt=marker, color=color, ms=4,
                            capsize=3, lw=1, label=label)
    for ax, key, (uname, scale), title in (
            (a1, "rate_error", unit, "per-turn rate error δ = (mean − ω_set)/ω_set (eq. 1)"),
            (a2, "rate_instability", inst_unit, "per-turn rate instability σ (eq. 2)")):
        tol = tolerances.get(key) or ()
        if len(tol) == 1:
            ax.axhline(tol[0][1] * scale, color="k", ls="--", lw=0.8, label="tolerance")
            if key == "rate_error":
                ax.axhline(-tol[0][1] * scale, color="k", ls="--", lw=0.8)
        elif tol:
            xs = [t[0] for t in tol]
            ts = np.array([t[1] for t in tol]) * scale
            ax.plot(xs, ts, "k--", lw=0.8, drawstyle="steps-mid", label="tolerance")
            if key == "rate_error":
                ax.plot(xs, -ts, "k--", lw=0.8, drawstyle="steps-mid")
        ax.set_ylabel(f"{uname}", fontsize=8)
        ax.set_title(f"Axis {axis}: {title}, U (k = 2) as bars", fontsize=9)
        _rate_axis(ax, [plot_number(r.set_rate_dps) for r in rates])
        ax.legend(fontsize=7)
    floors = sorted({(abs(plot_number(r.set_rate_dps)),
                      plot_number(r.rate_instability_floor_rel) * inst_unit[1])
                     for r in rates if math.isfinite(plot_number(r.rate_instability_floor_rel))})
    if floors:
        a2.plot([f[0] for f in floors], [f[1] for f in floors], ":", color="0.4", lw=1,
                label="timing floor of σ")
        a2.legend(fontsize=7)
    a1.axhline(0, color="0.5", lw=0.6)
    a2.set_yscale("log")  # a tolerance far above the values must not flatten them
    return png_of(fig)


def harmonic_model(harmonics: Sequence[HarmonicFit], phi_deg: np.ndarray) -> np.ndarray:
    """Sum of a_h cos(h phi + p_h), relative (docs/method.md A4)."""
    out = np.zeros_like(phi_deg, dtype=float)
    r = np.radians(phi_deg)
    for h in harmonics:
        out += plot_number(h.amplitude_rel) * np.cos(
            int(plot_number(h.order if h.order is not None else 1)) * r
            + math.radians(plot_number(h.phase_deg if h.phase_deg is not None else 0.0)))
    return out


def systematic(axis: str, rates: Sequence[RatePoint], scale: float,
               uname: str) -> bytes | None:
    """Systematic component vs angle with the fitted harmonics (paper figs. 8-9).

    Rates that carry the paper's binned average get their own panel with it; otherwise
    the fitted curves of every rate are overlaid (relative units, so a component that
    grows in proportion to the rate gives one curve).
    """
    with_bins = [r for r in rates if r.binned is not None and r.binned.centres_deg]
    fitted = [r for r in rates if r.harmonics]
    if not fitted and not with_bins:
        return None
    phi = np.linspace(0.0, 360.0, 721)
    panels = with_bins[:2] if with_bins else [None]
    fig, axs = figure_grid(len(panels), height_in=2.6)
    for ax, r in zip(axs, panels, strict=True):
        if r is None:
            for i, rr in enumerate(fitted):
                ax.plot(phi, harmonic_model(rr.harmonics, phi) * scale,
                        lw=1, color=f"C{i % 10}", label=f"{plot_number(rr.set_rate_dps):+g} °/s")
            ax.set_title(f"Axis {axis}: fitted systematic component Δω_sys/ω_set vs angle",
                         fontsize=9)
        else:
            b = r.binned
            assert b is not None    # with_bins
            phi_b = np.asarray(b.centres_deg, dtype=np.float64)
            y = np.asarray(b.deviation_rel, dtype=np.float64)
            u = np.asarray(b.u_rel or np.zeros_like(y), dtype=np.float64)
            turns = r.turns
            if y.size == phi_b.size and y.size:
                ax.errorbar(phi_b, y * scale, yerr=np.nan_to_num(u) * scale if u.size == y.size
                            else None, fmt=".", ms=3, color="0.4", ecolor="0.75", lw=0.6,
                            label=f"binned mean over {turns} turns (paper's estimator)")
            h = r.harmonics
            if h:
                ax.plot(phi, harmonic_model(h, phi) * scale, "C3", lw=1.2,
                        label=f"fitted harmonics 1…{max(int(plot_number(x.order)) for x in h)}")
            ax.set_title(f"Axis {axis} at {plot_number(r.set_rate_dps):+g} °/s: systematic "
                         "component vs angle", fontsize=9)
        ax.set_xlim(0, 360)
        ax.set_xticks(range(0, 361, 45))
        ax.set_xlabel("table angle φ from the zero mark, °", fontsize=8)
        ax.set_ylabel(f"Δω_sys / ω_set, {uname}", fontsize=8)
        ax.legend(fontsize=7, ncol=2)
    return png_of(fig)


def one_rev(axes: Mapping[str, Sequence[RatePoint]], scale: float,
            uname: str) -> bytes | None:
    """Once-per-revolution amplitude vs rate, relative and absolute (paper fig. 7)."""
    pts: dict[str, list[tuple[float, float, float]]] = {}
    for axis, rates in axes.items():
        for r in rates:
            for h in r.harmonics:
                if int(plot_number(h.order if h.order is not None else 0)) == 1:
                    pts.setdefault(axis, []).append((plot_number(r.set_rate_dps),
                                                     plot_number(h.amplitude_rel),
                                                     plot_number(h.amplitude_u_rel)))
    if not pts:
        return None
    fig, (a1, a2) = figure_grid(2, height_in=2.4)
    for i, (axis, p) in enumerate(pts.items()):
        for sign, label, marker, _ in DIRECTIONS:
            q = [t for t in p if math.copysign(1, t[0]) == sign]
            if not q:
                continue
            w = np.array([abs(t[0]) for t in q])
            wj = w * (1 + 0.02 * sign)  # the two directions side by side
            a = np.array([t[1] for t in q])
            u = np.nan_to_num(np.array([t[2] for t in q]))
            kw = dict(fmt=marker, color=f"C{i}", ms=4, capsize=3, lw=1,
                      mfc="none" if sign < 0 else f"C{i}")
            a1.errorbar(wj, a * scale, yerr=u * scale, label=f"{axis}, {label}", **kw)
            a2.errorbar(wj, a * w, yerr=u * w, **kw)
    a1.set_ylabel(f"1/rev amplitude, {uname} of ω_set", fontsize=8)
    a2.set_ylabel("1/rev amplitude, °/s", fontsize=8)
    a1.set_title("Once-per-revolution systematic amplitude vs rate, U (k = 2) as bars",
                 fontsize=9)
    allw = [abs(t[0]) for p in pts.values() for t in p if t[0]]
    for ax in (a1, a2):
        _rate_axis(ax, allw)
    a1.set_ylim(bottom=0)
    if allw and max(allw) / min(allw) > 20:
        a2.set_yscale("log")  # the absolute amplitude grows with the rate
    else:
        a2.set_ylim(bottom=0)
    a1.legend(fontsize=7, ncol=2)
    return png_of(fig)


def intra_turn(axes: Mapping[str, Sequence[RatePoint]], scale: float,
               uname: str) -> bytes | None:
    """Intra-turn instability vs rate, raw and floor-corrected, per axis (paper fig. 10)."""
    names = [a for a, rr in axes.items()
             if any(r.intra_turn_instability_rel is not None for r in rr)]
    if not names:
        return None
    fig, axs = figure_grid(len(names), height_in=2.4)
    for ax, axis in zip(axs, names, strict=True):
        rr = axes[axis]
        for sign, label, marker, color in DIRECTIONS:
            q = [r for r in rr if math.copysign(1, plot_number(r.set_rate_dps)) == sign]
            if not q:
                continue
            w = np.array([abs(plot_number(r.set_rate_dps)) for r in q]) * (1 + 0.02 * sign)
            y = np.array([plot_number(r.intra_turn_instability_rel) for r in q]) * scale
            u = np.nan_to_num(np.array([plot_number(r.intra_turn_instability_u_rel)
                                        for r in q])) * scale
            intra = [r.intra for r in q]
            # raw: docs/method.md D2 against the FOG floor, as the table prints it: a point
            # with its bars only when resolved (the analysis's raw_resolved), else its limit
            raw_res = np.array([i.raw_resolved is not False for i in intra])
            raw_up = np.array([plot_number(i.raw_upper_rel) for i in intra]) * scale
            if np.any(raw_res & np.isfinite(y)):
                ax.errorbar(w[raw_res], y[raw_res], yerr=u[raw_res], fmt=marker + "-",
                            color=color, ms=4, capsize=2, lw=1, label=f"{label}, raw")
            raw_lim = ~raw_res & np.isfinite(raw_up)
            if np.any(raw_lim):
                ax.plot(w[raw_lim], raw_up[raw_lim], "v", color=color, ms=5,
                        label=f"{label}, raw: upper limit (not above the FOG floor)")
            # floor-corrected: a resolved value with its bars; an unresolved one only as
            # its upper limit (a downward triangle), never as a point estimate
            res = np.array([i.resolved is not False for i in intra])
            c = np.array([plot_number(r.intra_turn_instability_corrected_rel) for r in q])
            up = np.array([plot_number(i.corrected_upper_rel) for i in intra])
            if np.any(res & np.isfinite(c)):
                err = np.where(np.isfinite(up) & res, up - c, 0.0) * scale
                ax.errorbar(w[res], c[res] * scale, yerr=[np.zeros(res.sum()), err[res]],
                            fmt=marker + "--", color=color, ms=4, capsize=2, lw=1,
                            mfc="none", label=f"{label}, floor-corrected")
            lim = ~res & np.isfinite(up)
            if np.any(lim):
                ax.plot(w[lim], up[lim] * scale, "v", color=color, ms=5, mfc="none",
                        label=f"{label}, floor-corrected: upper limit (not resolved)")
        _rate_axis(ax, [plot_number(r.set_rate_dps) for r in rr])
        ax.set_yscale("log")
        ax.set_ylabel(f"std(Δω_rand)/|ω_set|, {uname}", fontsize=8)
        ax.set_title(f"Axis {axis}: intra-turn instability vs rate", fontsize=9)
        ax.legend(fontsize=7, ncol=2)
    return png_of(fig)


def pairs(axes: Mapping[str, Sequence[PairPoint]]) -> bytes | None:
    """k and w0 of the FOG per +/- pair, with U (k = 2) (docs/method.md A3).

    k is drawn as its deviation from the axis's mean in ppm: two axes' FOGs differ by far
    more than one FOG's k changes with rate, and that change is what the plot is for.
    """
    if not any(axes.values()):
        return None
    fig, (a1, a2) = figure_grid(2, height_in=2.3)
    allw: list[float] = []
    for i, (axis, pp) in enumerate(axes.items()):
        if not pp:
            continue
        w = np.array([plot_number(p.rate_dps) for p in pp])
        allw += w.tolist()
        k = np.array([plot_number(p.k) for p in pp])
        if not np.any(np.isfinite(k)):
            continue
        k_mean = float(np.nanmean(k))
        kw = dict(fmt="o-", color=f"C{i}", ms=4, capsize=3, lw=1)
        a1.errorbar(w, (k - k_mean) * 1e6, yerr=np.nan_to_num([plot_number(p.k_u) for p in pp])
                    * 1e6, label=f"axis {axis} (mean k = {k_mean:.7f})", **kw)
        a2.errorbar(w, [plot_number(p.w0_dps) for p in pp],
                    yerr=np.nan_to_num([plot_number(p.w0_u_dps) for p in pp]),
                    label=f"axis {axis}", **kw)
    a1.set_ylabel("k − mean k, ppm", fontsize=8)
    a2.set_ylabel("ω0, °/s", fontsize=8)
    a1.set_title("FOG cross-calibration per ± pair: scale k and bias ω0, U (k = 2) as bars",
                 fontsize=9)
    for ax in (a1, a2):
        _rate_axis(ax, allw)
        ax.legend(fontsize=7)
    return png_of(fig)


def allan(floors: Mapping[str, AllanCurve]) -> bytes | None:
    """Allan deviation of each axis's static FOG record, with a white-noise slope guide."""
    curves = {a: (np.asarray(f.allan_tau_s, dtype=float), np.asarray(f.allan_dev_dps, dtype=float))
              for a, f in floors.items()}
    curves = {a: c for a, c in curves.items() if c[0].size > 1 and c[0].size == c[1].size}
    if not curves:
        return None
    fig, (ax,) = figure_grid(1, height_in=2.8)
    for i, (axis, (tau, adev)) in enumerate(curves.items()):
        ax.loglog(tau, adev, "o-", color=f"C{i}", ms=3, lw=1, label=f"axis {axis}")
        ax.loglog(tau, adev[0] * np.sqrt(tau[0] / tau), ":", color=f"C{i}", lw=0.8,
                  label=f"white noise, τ^-1/2 from the first point ({axis})")
    ax.set_xlabel("averaging time τ, s", fontsize=8)
    ax.set_ylabel("Allan deviation, °/s", fontsize=8)
    ax.set_title("FOG at rest: Allan deviation", fontsize=9)
    ax.legend(fontsize=7)
    return png_of(fig)
