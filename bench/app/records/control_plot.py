"""Control chart figure of one instrument (PNG bytes, Agg canvas): per series, the
individuals chart with its centre line and 1/2/3 sigma limits from the stated baseline,
and the EWMA with its limits (docs/method.md C2)."""

from __future__ import annotations

import io

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from bench.app.records.control import BASELINE_RUNS, InstrumentStatus

DPI = 110
MAX_SERIES = 16


def control_png(status: InstrumentStatus) -> bytes | None:
    """The figure, or None when no series has a point."""
    series = [s for s in status.series if s.points][:MAX_SERIES]
    if not series:
        return None
    fig = Figure(figsize=(9.0, 2.4 * len(series) + 0.6), layout="constrained")
    axs = fig.subplots(len(series), 1, squeeze=False).ravel()
    for ax, s in zip(axs, series, strict=True):
        n = list(range(1, len(s.points) + 1))
        y = [p.check.value for p in s.points]
        u = [p.check.u or 0.0 for p in s.points]
        ax.errorbar(n, y, yerr=u, fmt="o-", ms=3, lw=0.6, capsize=2, color="C0",
                    label="check value ± U (k = 2)")
        if s.centre is not None and s.sigma:
            ax.axvspan(0.5, min(BASELINE_RUNS, len(n)) + 0.5, color="0.9", zorder=0,
                       label=f"baseline (first {BASELINE_RUNS} runs)")
            ax.axhline(s.centre, color="k", lw=0.8, label="centre")
            for k, style in ((3, "-"), (2, "--"), (1, ":")):
                for sign in (1, -1):
                    ax.axhline(s.centre + sign * k * s.sigma, color="C3", lw=0.7, ls=style,
                               label=f"±{k} sigma ({s.sigma_source})"
                               if sign > 0 and k == 3 else None)
            ew = [(i + 1, e, h) for i, (e, h) in enumerate(zip(s.ewma, s.ewma_limit,
                                                                 strict=True))
                  if e is not None and h is not None]
            if ew:
                ax.plot([a for a, _, _ in ew], [e for _, e, _ in ew], "s-", ms=3, lw=0.8,
                        color="C2", label="EWMA (lambda 0.2)")
                ax.plot([a for a, _, _ in ew], [s.centre + h for _, _, h in ew], color="C2",
                        lw=0.6, ls="--", label="EWMA limits")
                ax.plot([a for a, _, _ in ew], [s.centre - h for _, _, h in ew], color="C2",
                        lw=0.6, ls="--")
        sig = {g.run_uid for g in s.signals}
        bad = [(i + 1, p.check.value) for i, p in enumerate(s.points) if p.run_uid in sig]
        if bad:
            ax.plot([a for a, _ in bad], [b for _, b in bad], "x", ms=9, mew=2, color="red",
                    label="signal (rule broken)")
        ax.set_ylabel(s.label.rsplit(", ", 1)[-1], fontsize=7)
        ax.ticklabel_format(axis="y", useOffset=False)
        ax.set_xlabel("run (oldest first)", fontsize=7)
        ax.tick_params(labelsize=7)
        ax.grid(True, alpha=0.3, lw=0.5)
        ax.legend(fontsize=5.5, ncol=3, loc="best")
        ax.set_title(f"{s.label}\n{s.baseline_text}", fontsize=7)
    fig.suptitle(f"Control charts, {status.name}: {status.state}", fontsize=9)
    FigureCanvasAgg(fig)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=DPI)
    return buf.getvalue()
