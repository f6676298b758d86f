"""What every certificate plot shares: one size, one resolution, one grid style, PNG bytes
from matplotlib's Agg canvas with no pyplot state, and a tolerant reading of numbers.

The plots themselves are the kinds' (procedures/<kind>/plots.py): each returns None when
the result carries nothing to plot, so a partial run still gets a certificate. Nothing
here names a procedure kind.
"""

from __future__ import annotations

import io
import math
from typing import TYPE_CHECKING, SupportsFloat, SupportsIndex

import numpy as np

if TYPE_CHECKING:   # matplotlib is imported when a plot is drawn (`bench validate` starts at once)
    from matplotlib.figure import Figure

DPI = 150
WIDTH_IN = 7.0


def png_of(fig: Figure) -> bytes:
    """The figure as PNG bytes, at the certificate's resolution."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    FigureCanvasAgg(fig)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=DPI)
    return buf.getvalue()


def figure_grid(rows: int, cols: int = 1, height_in: float = 2.6
                ) -> tuple[Figure, np.ndarray]:
    """A figure of the certificate's width with `rows` x `cols` gridded panels."""
    from matplotlib.figure import Figure
    fig = Figure(figsize=(WIDTH_IN, height_in * rows), layout="constrained")
    axs = np.atleast_1d(fig.subplots(rows, cols, squeeze=False)).ravel()
    for ax in axs:
        ax.grid(True, which="both", alpha=0.3, lw=0.5)
        ax.tick_params(labelsize=8)
    return fig, axs


def plot_number(x: object) -> float:
    """A value as a float for plotting (NaN, drawn as a gap, for what is no number)."""
    if not isinstance(x, SupportsFloat | SupportsIndex | str | bytes):
        return math.nan     # what float() refuses anyway
    try:
        v = float(x)
    except (TypeError, ValueError):
        return math.nan
    return v
