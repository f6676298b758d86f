"""The certificate's PDF breaks each table cell's text into lines once (issue 62: fpdf lays
out every cell twice, for the rows' heights and to draw them): the same PDF to the byte as
fpdf's own breaking, fewer breakings, and fpdf as it was afterwards."""

from __future__ import annotations

import datetime as dt
from pathlib import Path
from typing import Any

import fpdf.fpdf
import pytest
from fpdf.line_break import MultiLineBreak

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
    # a table's cell is broken for its row's height and again to draw it: now once
    assert 0 < _Counting.made < 0.7 * every_time, (_Counting.made, every_time)
