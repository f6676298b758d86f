"""The trend plot: a table's figures across recertifications (PNG bytes, Agg canvas).

One panel per figure the run's procedure kind declares as trended (`FigureSpec.trend`,
bench/report/figures.py), in the kind's order, each with U (k = 2) bars and its check's
tolerance band: for a rate ladder the table's rate error and per-turn instability, then
the FOG's k and w0 (docs/method.md A3), whose drift between recertifications tells the
gyro's own ageing apart from the table's; for a drift-pulse history own and apparent drift.
`trend_figure` is the figure itself (what is plotted can be read back from it).
"""

from __future__ import annotations

import io
from collections.abc import Sequence

from matplotlib import colormaps
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from bench.app.records.store import TrendPoint
from bench.kind import declared_figures
from bench.report.figures import FigureSpec

DPI = 130


def _series_name(p: TrendPoint, spec: FigureSpec) -> str:
    f = p.figure
    rate = "" if f.set_rate_dps is None else (
        f" ±{abs(f.set_rate_dps):g} deg/s" if spec.rate_is_magnitude
        else f" {f.set_rate_dps:+g} deg/s")
    return f"{f.axis}{rate}".strip() or spec.name


#: the series' colours (a qualitative map of 20) and, past 20 series, their markers
SERIES_COLOURS = colormaps["tab20"]
SERIES_MARKERS = "osD^"


def trend_figure(points: Sequence[TrendPoint], title: str = "",
                 figures: Sequence[FigureSpec] | None = None) -> Figure | None:
    """The trend figure, or None when no point has a date and a trended quantity.
    `figures`: the declarations of the runs' kinds (every installed kind's when None)."""
    specs = declared_figures() if figures is None else figures
    points = [p for p in points if p.date_utc is not None]
    panels = [s for s in specs if s.trend is not None
              and any(s.matches(p.figure.quantity) for p in points)]
    if not panels:
        return None
    cols = 2 if len(panels) > 1 else 1
    rows = (len(panels) + cols - 1) // cols
    fig = Figure(figsize=(7.0, 2.7 * rows + 0.4), layout="constrained")
    axs = fig.subplots(rows, cols, squeeze=False).ravel()
    for ax in axs[len(panels):]:
        ax.set_visible(False)
    for ax, spec in zip(axs, panels, strict=False):
        _panel(ax, spec, [p for p in points if spec.matches(p.figure.quantity)])
    note = "error bars: U (k = 2)" + ("; ▽ upper limit (not resolved)"
                                      if any(p.figure.is_limit for p in points) else "")
    fig.suptitle(f"{title}\n{note}" if title else note, fontsize=9)
    return fig


def trend_png(points: Sequence[TrendPoint], title: str = "",
              figures: Sequence[FigureSpec] | None = None) -> bytes | None:
    """The trend figure as PNG, or None (see `trend_figure`)."""
    fig = trend_figure(points, title, figures)
    if fig is None:
        return None
    FigureCanvasAgg(fig)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=DPI)
    return buf.getvalue()


def _panel(ax: Axes, spec: FigureSpec, points: list[TrendPoint]) -> None:
    assert spec.trend is not None
    band, offset, scale = spec.trend.band, spec.trend.offset, spec.scale
    series: dict[str, list[TrendPoint]] = {}
    for p in points:
        series.setdefault(_series_name(p, spec), []).append(p)
    tolerances = sorted({p.figure.tolerance for p in points if p.figure.tolerance})
    lows = [(p.figure.value - offset - (p.figure.u or 0.0)) * scale for p in points]
    highs = [(p.figure.value - offset + (p.figure.u or 0.0)) * scale for p in points]
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
        y = [(p.figure.value - offset) * scale for p in pts]
        u = [(p.figure.u or 0.0) * scale for p in pts]
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
                                                  * scale),
                            fontsize=5, xytext=(3, 3), textcoords="offset points")
    reach = max(abs(lo), abs(hi), 1e-300)
    for j, tol in enumerate(tolerances):
        t = tol * scale
        label = f"tolerance ±{t:g}" if band == "sym" else f"tolerance {t:g}"
        if t > 4 * reach:       # the band would flatten the trend: say where it is instead
            label += " (beyond this scale)"
        else:
            lo, hi = min(lo, -t if band == "sym" else 0.0), max(hi, t)
        if band == "sym":
            ax.axhspan(-t, t, color="green", alpha=0.07, label=label if j == 0 else None)
            ax.axhline(t, color="green", lw=0.6, ls="--")
            ax.axhline(-t, color="green", lw=0.6, ls="--")
        elif band == "upper":
            ax.axhspan(0, t, color="green", alpha=0.07, label=label if j == 0 else None)
            ax.axhline(t, color="green", lw=0.6, ls="--")
    pad = 0.1 * (hi - lo) or 0.1 * reach or 1.0
    ax.set_ylim(lo - pad, hi + pad)
    ax.set_ylabel(spec.trend_label, fontsize=8)
    ax.tick_params(labelsize=7)
    ax.grid(True, alpha=0.3, lw=0.5)
    for lbl in ax.get_xticklabels():
        lbl.set_rotation(25)
        lbl.set_horizontalalignment("right")
    ax.legend(fontsize=5.5, ncol=2, loc="best")
    # a short title fits a half-width panel; what the bars and marks mean is said once,
    # under the figure's title
    ax.set_title(spec.trend_label.split(",")[0], fontsize=8)
