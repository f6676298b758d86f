"""The trend plot: a table's figures across recertifications (PNG bytes, Agg canvas).

Top row: the table itself, rate error and per-turn instability against date with U
(k = 2) bars and the tolerance band. Bottom row: the FOG's cross-calibration, k and w0
(docs/method.md A3), whose drift between recertifications tells the gyro's own ageing apart
from the table's. A drift-pulse history plots own and apparent drift instead.
"""

from __future__ import annotations

import io
from collections.abc import Sequence
from dataclasses import dataclass

from matplotlib import colormaps
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from bench.app.records.store import TrendPoint

DPI = 130


@dataclass(frozen=True)
class Panel:
    quantity: str
    label: str
    scale: float             # stored value x scale = plotted value
    band: str                # "sym" (+-T), "upper" (0..T) or "" (no tolerance)


LADDER = (Panel("rate_error_rel", "rate error δ, ppm", 1e6, "sym"),
          Panel("rate_instability_rel", "per-turn instability σ, ppm", 1e6, "upper"),
          Panel("k", "FOG scale k − 1, ppm (METHOD A3)", 1e6, ""),
          Panel("w0_dps", "FOG bias w0, deg/s", 1.0, ""))
DRIFT = (Panel("own_drift_dph", "own drift, deg/h", 1.0, "sym"),
         Panel("apparent_drift_dph", "apparent drift, deg/h", 1.0, ""))


def _series_name(p: TrendPoint) -> str:
    f = p.figure
    rate = "" if f.set_rate_dps is None else (
        f" ±{abs(f.set_rate_dps):g} deg/s" if f.quantity in ("k", "w0_dps")
        else f" {f.set_rate_dps:+g} deg/s")
    return f"{f.axis}{rate}"


#: the series' colours (a qualitative map of 20) and, past 20 series, their markers
SERIES_COLOURS = colormaps["tab20"]
SERIES_MARKERS = "osD^"


def trend_png(points: Sequence[TrendPoint], title: str = "") -> bytes | None:
    """The trend figure, or None when no point has a date and a plotted quantity."""
    points = [p for p in points if p.date_utc is not None]
    panels = [pn for pn in (LADDER + DRIFT)
              if any(p.figure.quantity == pn.quantity for p in points)]
    if not panels:
        return None
    cols = 2 if len(panels) > 1 else 1
    rows = (len(panels) + cols - 1) // cols
    fig = Figure(figsize=(7.0, 2.7 * rows + 0.4), layout="constrained")
    axs = fig.subplots(rows, cols, squeeze=False).ravel()
    for ax in axs[len(panels):]:
        ax.set_visible(False)
    for ax, pn in zip(axs, panels, strict=False):
        _panel(ax, pn, [p for p in points if p.figure.quantity == pn.quantity])
    note = "error bars: U (k = 2)" + ("; ▽ upper limit (not resolved)"
                                      if any(p.figure.is_limit for p in points) else "")
    fig.suptitle(f"{title}\n{note}" if title else note, fontsize=9)
    FigureCanvasAgg(fig)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=DPI)
    return buf.getvalue()


def _panel(ax: Axes, pn: Panel, points: list[TrendPoint]) -> None:
    series: dict[str, list[TrendPoint]] = {}
    for p in points:
        series.setdefault(_series_name(p), []).append(p)
    tolerances = sorted({p.figure.tolerance for p in points if p.figure.tolerance})
    offset = 1.0 if pn.quantity == "k" else 0.0
    lows = [(p.figure.value - offset - (p.figure.u or 0.0)) * pn.scale for p in points]
    highs = [(p.figure.value - offset + (p.figure.u or 0.0)) * pn.scale for p in points]
    lo, hi = min(lows), max(highs)
    def order(item: tuple[str, list[TrendPoint]]) -> tuple[str, float, float]:
        """Axis, then rate magnitude, + before - (not 10 before 2 as text sorts)."""
        f = item[1][0].figure
        rate = f.set_rate_dps or 0.0
        return f.axis, abs(rate), -rate

    for i, (name, pts) in enumerate(sorted(series.items(), key=order)):
        # dated points only (trend_png); the ignores below: matplotlib's stubs take no
        # datetime x, which its units framework converts (matplotlib.dates)
        x = [p.date_utc for p in pts]
        offset = 1.0 if pn.quantity == "k" else 0.0
        y = [(p.figure.value - offset) * pn.scale for p in pts]
        u = [(p.figure.u or 0.0) * pn.scale for p in pts]
        # 20 distinct colours, then another marker: 12 series never share a look
        color = SERIES_COLOURS(i % 20)
        marker = SERIES_MARKERS[(i // 20) % len(SERIES_MARKERS)]
        ax.plot(x, y, "-", lw=0.5, color=color, alpha=0.5)  # type: ignore[arg-type]
        est = [j for j, p in enumerate(pts) if not p.figure.is_limit]
        if est:
            ax.errorbar([x[j] for j in est], [y[j] for j in est],  # type: ignore[arg-type]
                        yerr=[u[j] for j in est],
                        fmt=marker, ms=3, capsize=3, color=color, label=name)
        lim = [j for j, p in enumerate(pts) if p.figure.is_limit]
        if lim:   # not resolved: the upper limit, drawn as one (never a point with U)
            ax.plot([x[j] for j in lim], [y[j] for j in lim],  # type: ignore[arg-type]
                    "v", ms=5, mfc="none",
                    color=color, label=f"{name}: upper limit" if not est else None)
        for p in pts:
            if p.calibration_state:
                ax.annotate(p.calibration_state, (p.date_utc, (p.figure.value - offset)
                                                  * pn.scale),
                            fontsize=5, xytext=(3, 3), textcoords="offset points")
    reach = max(abs(lo), abs(hi), 1e-300)
    for j, tol in enumerate(tolerances):
        t = tol * pn.scale
        label = f"tolerance ±{t:g}" if pn.band == "sym" else f"tolerance {t:g}"
        if t > 4 * reach:       # the band would flatten the trend: say where it is instead
            label += " (beyond this scale)"
        else:
            lo, hi = min(lo, -t if pn.band == "sym" else 0.0), max(hi, t)
        if pn.band == "sym":
            ax.axhspan(-t, t, color="green", alpha=0.07, label=label if j == 0 else None)
            ax.axhline(t, color="green", lw=0.6, ls="--")
            ax.axhline(-t, color="green", lw=0.6, ls="--")
        elif pn.band == "upper":
            ax.axhspan(0, t, color="green", alpha=0.07, label=label if j == 0 else None)
            ax.axhline(t, color="green", lw=0.6, ls="--")
    pad = 0.1 * (hi - lo) or 0.1 * reach or 1.0
    ax.set_ylim(lo - pad, hi + pad)
    ax.set_ylabel(pn.label, fontsize=8)
    ax.tick_params(labelsize=7)
    ax.grid(True, alpha=0.3, lw=0.5)
    for lbl in ax.get_xticklabels():
        lbl.set_rotation(25)
        lbl.set_horizontalalignment("right")
    ax.legend(fontsize=5.5, ncol=2, loc="best")
    # a short title fits a half-width panel; what the bars and marks mean is said once,
    # under the figure's title
    ax.set_title(pn.label.split(",")[0], fontsize=8)
