"""The certificate's one-column figures are placed once from their labels' extents, not by
constrained layout (issue 62): every title, tick label and axis label inside the canvas,
no panel's labels over another's, and the panels as wide as the widest tick labels allow."""

from __future__ import annotations

import io

import numpy as np
import pytest
from PIL import Image

from bench.report.certificate.plotting import DPI, PAD_IN, WIDTH_IN, figure_grid, png_of


@pytest.mark.parametrize(("scale", "rows"), [(1e-3, 2), (123456.789, 3), (1.0, 1)])
def test_labels_inside_the_canvas_and_apart(scale: float, rows: int) -> None:
    fig, axs = figure_grid(rows, height_in=2.4)
    x = np.linspace(0.0, 360.0, 50)
    for i, ax in enumerate(axs):
        ax.plot(x, scale * (i + 1) * np.sin(np.radians(x)), label="a series")
        ax.set_title(f"Panel {i}: a title as long as the certificate's, U (k = 2) as bars",
                     fontsize=9)
        ax.set_xlabel("table angle φ from the zero mark, °", fontsize=8)
        ax.set_ylabel("Δω_sys / ω_set, ppm", fontsize=8)
        ax.legend(fontsize=7)
    png = png_of(fig)
    with Image.open(io.BytesIO(png)) as im:
        assert im.size == (round(WIDTH_IN * DPI), round(2.4 * rows * DPI))
    renderer = fig.canvas.get_renderer()
    canvas = fig.bbox
    boxes = [ax.get_tightbbox(renderer) for ax in axs]
    for box in boxes:     # each panel with its labels inside the canvas
        assert box is not None
        assert box.x0 >= canvas.x0 and box.y0 >= canvas.y0
        assert box.x1 <= canvas.x1 and box.y1 <= canvas.y1
    for upper, lower in zip(boxes, boxes[1:], strict=False):   # apart, top to bottom
        assert upper.y0 > lower.y1
    # the labels' space at the left is the widest labels' and a pad, not a guess
    widest = max(ax.get_window_extent(renderer).x0 - ax.yaxis.get_tightbbox(renderer).x0
                 for ax in axs)
    left = axs[0].get_window_extent(renderer).x0
    assert left == pytest.approx(widest + PAD_IN * fig.dpi, abs=1.0)


def test_more_than_one_column_keeps_constrained_layout() -> None:
    fig, _ = figure_grid(2, 2)
    assert fig.get_layout_engine() is not None
    fig, _ = figure_grid(2)
    assert fig.get_layout_engine() is None
