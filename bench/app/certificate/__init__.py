"""The calibration certificate: result.json -> certificate.html and certificate.pdf.

    write_certificate(run, src) -> [RUN_DIR/certificate.html, RUN_DIR/certificate.pdf]

The engine calls this after writing result.json (`bench run`, `bench analyze`), given the
run decoded once (`Sources.load`, bench/report/certificate/sources.py, the codec): every
entry point here takes that typed run, never result.json's JSON map. The
content follows ISO/IEC 17025 clause 7.8; how to read it: docs/certificate.md.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import hashlib
import os
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Protocol

from bench.app.certificate import register
from bench.app.certificate.build import ExtraSection, build_document, restated
from bench.app.certificate.figures import NotAsDrawn, drawn_beside
from bench.app.certificate.html import render_html
from bench.core import rundir_layout as layout
from bench.report.certificate.model import Document
from bench.report.certificate.sources import Sources

if TYPE_CHECKING:   # fpdf is imported when a PDF is rendered, not when a run starts (issue 62)
    from bench.app.certificate.pdf import render_pdf

HTML_NAME = layout.CERTIFICATE_HTML
PDF_NAME = layout.CERTIFICATE_PDF

__all__ = ["Document", "build_document", "render_files", "render_html", "render_pdf",
           "render_issue", "result_digest", "write_certificate"]


def __getattr__(name: str) -> Callable[..., bytes]:
    """`render_pdf`, imported when it is first asked for: fpdf's import is a second of a
    run's start-up, spent before the certificate that needs it (issue 62)."""
    if name == "render_pdf":
        from bench.app.certificate.pdf import render_pdf
        return render_pdf
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


class _HasPath(Protocol):
    path: Path


def _write_atomic(path: Path, data: bytes) -> None:
    tmp = path.with_suffix(path.suffix + ".tmp")
    tmp.write_bytes(data)
    os.replace(tmp, path)


def render_files(src: Sources, out_dir: str | Path, issued: dt.date | None = None, *,
                 documents: list[Document] | None = None,
                 extra_sections: Sequence[ExtraSection] = (),
                 issue: register.Issue | None = None) -> list[Path]:
    """Render the certificate of `src` into `out_dir`: the DRAFT of the run's next
    revision, or, given an `issue` that `bench authorise` is recording, that issue.

    Nothing is recorded here: a draft is not an issue (register.py). `documents`, if
    given, receives the document the files were rendered from (the console's summary is
    cut from it, so it prints the certificate's own text).
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)

    def build() -> Document:
        return build_document(src, issued, issue, extra_sections)

    from bench.app.certificate.pdf import render_pdf
    with drawn_beside() as drawer:
        if drawer is None:
            doc = build()
            pdf = render_pdf(doc)
        else:    # the figures drawn by workers while the PDF's tables are laid out
            with drawer.building():
                doc = build()
            try:
                pdf = render_pdf(doc, drawer.png)
                doc = drawer.resolved(doc)
            except NotAsDrawn:  # a figure is a note or nothing: the blocks differ
                with drawer.building(looking_up=True):
                    doc = build()
                pdf = render_pdf(doc)
    if documents is not None:
        documents.append(doc)
    html_path, pdf_path = out / HTML_NAME, out / PDF_NAME
    _write_atomic(html_path, render_html(doc).encode("utf-8"))
    _write_atomic(pdf_path, pdf)
    return [html_path, pdf_path]


def render_issue(src: Sources, out_dir: Path, issue: register.Issue,
                 changes: Callable[[str], tuple[str, ...]]) -> register.Issue:
    """Render a re-issue: its document is built once, `changes(html)` compares its
    statements (the HTML as rendered) with the replaced revision's, and the files state
    them (bench/app/certificate/revisions.py). Returns the issue as stated."""
    from bench.app.certificate.pdf import render_pdf
    out_dir.mkdir(parents=True, exist_ok=True)
    doc = build_document(src, None, issue)
    issue = dataclasses.replace(issue, changes=changes(render_html(doc)))
    doc = restated(doc, issue)
    _write_atomic(out_dir / HTML_NAME, render_html(doc).encode("utf-8"))
    _write_atomic(out_dir / PDF_NAME, render_pdf(doc))
    return issue


def result_digest(stored: bytes) -> str:
    """SHA-256 of result.json as stored, its bytes (the register records the same digest of
    the same file; never of a re-serialisation)."""
    return hashlib.sha256(stored).hexdigest()


def write_certificate(run: _HasPath, src: Sources,
                      issued: dt.date | None = None, *,
                      documents: list[Document] | None = None,
                      extra_sections: Sequence[ExtraSection] = ()) -> list[Path]:
    """The DRAFT certificate.html and certificate.pdf in the run directory (`bench run`,
    `bench analyze`); `bench authorise` issues it. Returns their paths.

    `extra_sections` (title, blocks) come from outside the run directory (the table's
    history from the records) and are placed before the statements."""
    return render_files(src, run.path, issued, documents=documents,
                        extra_sections=extra_sections)
