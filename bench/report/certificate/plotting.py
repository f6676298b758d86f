"""What every certificate plot shares: one size, one resolution, one grid style, PNG bytes
from matplotlib's Agg canvas with no pyplot state, and a tolerant reading of numbers.

The plots themselves are the kinds' (procedures/<kind>/plots.py): each returns None when
the result carries nothing to plot, so a partial run still gets a certificate. Nothing
here names a procedure kind.
"""

from __future__ import annotations

import functools
import io
import math
from typing import TYPE_CHECKING, SupportsFloat, SupportsIndex

import numpy as np

from drivers.json_types import JsonValue

if TYPE_CHECKING:   # matplotlib is imported when a plot is drawn (`bench validate` starts at once)
    from matplotlib.backend_bases import RendererBase
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

DPI = 150
WIDTH_IN = 7.0
#: the space kept around each panel's labels, inches
PAD_IN = 0.06


def png_of(fig: Figure) -> bytes:
    """The figure as PNG bytes, at the certificate's resolution."""
    canvas = _canvas_class()(fig)
    if fig.get_layout_engine() is None and getattr(fig, "_stacked_rows", False):
        _stack_rows(fig, canvas.get_renderer())
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=DPI)
    return buf.getvalue()


@functools.cache
def _canvas_class() -> type[FigureCanvasAgg]:
    """matplotlib's Agg canvas, whose renderers share one mathtext parser.

    Each Agg renderer parses the math it draws (a log axis's tick labels, 10^n) with a
    parser of its own, whose cache is its own; a figure has two renderers (placed, then
    drawn) and a certificate eight figures, and the same labels were parsed again in each
    (a tenth of a figure's time; issue 62). One parser, with its cache: the same parse of
    the same text, font, size and resolution, drawn by whichever renderer asks."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg, RendererAgg
    from matplotlib.mathtext import MathTextParser

    parser = MathTextParser("path")

    class Canvas(FigureCanvasAgg):
        def get_renderer(self) -> RendererAgg:
            renderer: RendererAgg = super().get_renderer()
            renderer.mathtext_parser = parser
            return renderer

    return Canvas


def _stack_rows(fig: Figure, renderer: RendererBase) -> None:
    """One column of panels placed once, from their labels' extents: each panel's title
    above it, its tick labels and axis label below and left of it, all inside the canvas.
    Constrained layout found the same places by drawing every artist's extent twice, the
    largest part of a figure's cost (issue 62); here only the axes' labels are measured,
    and those measures are cached for the drawing."""
    width_in, height_in = fig.get_size_inches()
    dpi = fig.dpi
    axes = fig.axes
    left_in = right_in = 0.0
    above_in, below_in = [], []
    for ax in axes:
        frame = ax.get_window_extent(renderer)
        y_ext = ax.yaxis.get_tightbbox(renderer)
        x_ext = ax.xaxis.get_tightbbox(renderer)
        if y_ext is not None:
            left_in = max(left_in, (frame.x0 - y_ext.x0) / dpi)
        top = frame.y1
        if x_ext is not None:
            right_in = max(right_in, (x_ext.x1 - frame.x1) / dpi)
            below_in.append(max(frame.y0 - x_ext.y0, 0.0) / dpi)
            top = max(top, x_ext.y1)
        else:
            below_in.append(0.0)
        for title in (ax.title, getattr(ax, "_left_title", None),
                      getattr(ax, "_right_title", None)):    # set_title(loc=...)'s
            if title is not None and title.get_text():
                top = max(top, title.get_window_extent(renderer).y1)
        above_in.append((top - frame.y1) / dpi)
    left_in += PAD_IN
    right_in = max(right_in, 0.0) + PAD_IN
    panel_in = (height_in - sum(above_in) - sum(below_in) - 2 * PAD_IN * len(axes)) / len(axes)
    y_in = height_in
    for ax, above, below in zip(axes, above_in, below_in, strict=True):
        y_in -= above + PAD_IN + panel_in
        ax.set_position((left_in / width_in, y_in / height_in,
                         (width_in - left_in - right_in) / width_in, panel_in / height_in))
        y_in -= below + PAD_IN


def figure_grid(rows: int, cols: int = 1, height_in: float = 2.6
                ) -> tuple[Figure, np.ndarray]:
    """A figure of the certificate's width with `rows` x `cols` gridded panels (one
    column: placed by `_stack_rows` when drawn; more: by constrained layout)."""
    from matplotlib.figure import Figure
    fig = Figure(figsize=(WIDTH_IN, height_in * rows), layout="constrained" if cols > 1 else None)
    fig._stacked_rows = cols == 1  # type: ignore[attr-defined]
    axs = np.atleast_1d(fig.subplots(rows, cols, squeeze=False)).ravel()
    for ax in axs:
        ax.grid(True, which="both", alpha=0.3, lw=0.5)
        ax.tick_params(labelsize=8)
    return fig, axs


def plot_number(x: JsonValue) -> float:
    """A value as a float for plotting (NaN, drawn as a gap, for what is no number)."""
    if not isinstance(x, SupportsFloat | SupportsIndex | str | bytes):
        return math.nan     # what float() refuses anyway
    try:
        v = float(x)
    except (TypeError, ValueError):
        return math.nan
    return v
