"""The drift kind's certificate plots, as PNG bytes (bench/report/certificate/plotting.py).

Each function returns None when the result carries nothing to plot, so a partial run
still gets a certificate.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Protocol

import numpy as np

from bench.report.certificate.plotting import figure_grid, plot_number, png_of


class CycleTrace(Protocol):
    """One drift cycle's recorded trace (docs/method.md part B)."""

    @property
    def t_s(self) -> Sequence[float]: ...
    @property
    def u_v(self) -> Sequence[float]: ...
    @property
    def integral_vs(self) -> Sequence[float]: ...
    @property
    def tc_s(self) -> float: ...


class CycleDrift(Protocol):
    """One drift cycle's estimate and where the platform stood."""

    @property
    def table_deg(self) -> float: ...
    @property
    def drift_dph(self) -> float: ...


class AxisDrift(Protocol):
    """An axis's own drift and its cycles' estimates."""

    @property
    def own_dph(self) -> float: ...
    @property
    def cycles(self) -> Sequence[CycleDrift]: ...


def drift_cycle(axis: str, cycle: CycleTrace) -> bytes | None:
    """U(t) of the angle sensor and the signed integrator output over one cycle."""
    t = np.asarray(cycle.t_s, dtype=float)
    u = np.asarray(cycle.u_v, dtype=float)
    if t.size < 2 or u.size != t.size:
        return None
    fig, (a1, a2) = figure_grid(2, height_in=2.2)
    a1.plot(t, u, "C0", lw=1)
    a1.set_ylabel("U, V", fontsize=8)
    a1.set_title(f"Axis {axis}: angle-sensor output U(t) and signed integral over one cycle",
                 fontsize=9)
    integ = np.asarray(cycle.integral_vs, dtype=float)
    if integ.size == t.size:
        a2.plot(t, integ, "C3", lw=1)
    a2.set_ylabel("∫±U dt, V·s", fontsize=8)
    a2.set_xlabel("time from the start of the first pulse, s", fontsize=8)
    tc = plot_number(cycle.tc_s)
    for ax in (a1, a2):
        if math.isfinite(tc):
            ax.axvline(tc, color="0.4", lw=0.8, ls="--")
    return png_of(fig)


def drift_cycles(axes: Mapping[str, AxisDrift]) -> bytes | None:
    """Drift estimate of every cycle, by axis and platform position."""
    names = [a for a, d in axes.items() if d.cycles]
    if not names:
        return None
    fig, axs = figure_grid(len(names), height_in=2.2)
    for ax, axis in zip(axs, names, strict=True):
        cyc = axes[axis].cycles
        positions = sorted({plot_number(c.table_deg) for c in cyc})
        n = 0
        for j, pos in enumerate(positions):
            q = [c for c in cyc if plot_number(c.table_deg) == pos]
            x = np.arange(n + 1, n + len(q) + 1)
            y = np.array([plot_number(c.drift_dph) for c in q])
            ax.plot(x, y, "o", color=f"C{j}", ms=4, label=f"position {pos:g}°")
            ax.hlines(np.mean(y), x[0] - 0.3, x[-1] + 0.3, color=f"C{j}", lw=0.8)
            n += len(q)
        own = plot_number(axes[axis].own_dph)
        if math.isfinite(own):
            ax.axhline(own, color="k", lw=0.8, ls="--", label="own drift")
        ax.set_ylabel("drift, °/h", fontsize=8)
        ax.set_xlabel("cycle", fontsize=8)
        ax.set_title(f"Axis {axis}: drift per cycle", fontsize=9)
        ax.legend(fontsize=7)
    return png_of(fig)
