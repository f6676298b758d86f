"""The certificate's PDF breaks each table cell's text into lines once (issue 62: fpdf lays
out every cell twice, for the rows' heights and to draw them), a text that fits on one line
without breaking it character by character, and a row's height without drawing its cells
unseen: the same PDF to the byte as fpdf's own table and breaking, fewer breakings, and
fpdf as it was afterwards."""

from __future__ import annotations

import datetime as dt
import random
from pathlib import Path
from typing import Any

import fpdf.fpdf
import pytest
from fpdf.enums import Align
from fpdf.line_break import MultiLineBreak
from fpdf.table import Table as FpdfTable

from bench.app.certificate import pdf as certificate_pdf
from bench.app.certificate.build import build_document
from bench.report.certificate.sources import Sources
from bench.report.codec import encode
from procedures.rate_ladder.sample import rate_ladder_result

FIXED = dt.datetime(2026, 1, 2, 3, 4, 5, tzinfo=dt.UTC)


@pytest.fixture
def fixed_date(monkeypatch: pytest.MonkeyPatch) -> None:
    """Every PDF made at one time, so two renderings can be compared byte for byte."""
    init = certificate_pdf._Pdf.__init__

    def dated(self: certificate_pdf._Pdf, *args: Any) -> None:
        init(self, *args)
        self.set_creation_date(FIXED)
    monkeypatch.setattr(certificate_pdf._Pdf, "__init__", dated)


class _Counting(MultiLineBreak):
    made = 0

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        type(self).made += 1
        super().__init__(*args, **kwargs)


def test_lines_broken_once_give_the_same_pdf(fixed_date: None, tmp_path: Path,
                                             monkeypatch: pytest.MonkeyPatch) -> None:
    doc = build_document(Sources.load(encode(rate_ladder_result()), None))
    with monkeypatch.context() as fpdf_own:     # fpdf's table, every text broken by fpdf
        fpdf_own.setattr(certificate_pdf, "_Table", FpdfTable)
        fpdf_own.setattr(certificate_pdf, "_plain_lines", lambda *args: None)
        as_fpdf_breaks = certificate_pdf._rendered(doc, certificate_pdf._png)
    monkeypatch.setattr(certificate_pdf, "MultiLineBreak", _Counting)
    monkeypatch.setattr(fpdf.fpdf, "MultiLineBreak", _Counting)
    _Counting.made = 0
    certificate_pdf._rendered(doc, certificate_pdf._png)
    every_time = _Counting.made
    _Counting.made = 0
    once = certificate_pdf.render_pdf(doc)
    assert once == as_fpdf_breaks
    assert fpdf.fpdf.MultiLineBreak is _Counting      # fpdf as it was
    assert certificate_pdf._BrokenOnce.lines == {}
    # a table's cell is broken for its row's height and again to draw it: now once, and
    # plain text (all of this certificate's) without fpdf's breaking
    assert 0 == _Counting.made < every_time, (_Counting.made, every_time)


_WORDS = ("Mean", "rate", "±", "U", "°/s", "0.000123", "−4.5e-06", "k = 2", "PASS", "FAIL",
          "(guard band)", "σ", "√", "≤", "ω_set", "A", "", "iiii", "WWWWWWWWWWWW", "—", "\n",
          "calibration", "uncertainty", "\u0301")


def _as_compared(lines: list[Any]) -> list[Any]:
    return [(line._replace(fragments=[]),
             [(f.characters, f.graphics_state, f.k, f.link, type(f)) for f in line.fragments])
            for line in lines]


def test_plain_lines_are_the_lines_fpdf_breaks() -> None:
    """Where `_plain_lines` gives lines, fpdf's breaking gives those lines and no others, to
    the last bit of their widths: texts near and far over the width, with runs of spaces,
    newlines, words longer than a line and a zero-width mark, in each font and alignment."""
    rng = random.Random(62)
    pdf = certificate_pdf._Pdf(build_document(Sources.load(encode(rate_ladder_result()), None)),
                               certificate_pdf._png)
    pdf.add_page()
    given = several = 0
    for _ in range(500):
        family, style = rng.choice([(certificate_pdf.SANS, ""), (certificate_pdf.SANS, "B"),
                                    (certificate_pdf.SANS, "I"), (certificate_pdf.MONO, "")])
        pdf.set_font(family, style, rng.choice([6.3, 7.5, 8.5, 9.5]))
        text = "".join(rng.choice(_WORDS) + " " * rng.choice([0, 1, 1, 1, 2])
                       for _ in range(rng.randint(1, 8)))
        fragments = pdf._preload_font_styles(text, False)
        width = pdf.get_string_width(text) * rng.choice([0.2, 0.5, 1.0]) + rng.uniform(-1.0, 2.0)
        margins = rng.choice([[], [pdf.c_margin], [pdf.c_margin, pdf.c_margin]])
        align = rng.choice([Align.L, Align.R, Align.C, Align.J])
        options = {"align": align, "print_sh": False, "wrapmode": fpdf.enums.WrapMode.WORD}
        try:
            expected = list(iter(MultiLineBreak(fragments, width, margins, **options).get_line,
                                 None))
        except fpdf.errors.FPDFException as e:      # a character wider than the line
            with pytest.raises(fpdf.errors.FPDFException, match=str(e)):
                certificate_pdf._plain_lines(fragments, width, margins, align)
            continue
        lines = certificate_pdf._plain_lines(fragments, width, margins, align)
        if lines is None:
            continue
        given += 1
        several += len(expected) > 1
        assert _as_compared(lines) == _as_compared(expected), text
    assert given > 300 and several > 100, (given, several)
