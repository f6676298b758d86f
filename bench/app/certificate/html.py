"""The certificate as one self-contained HTML file (Jinja2; plots inline as base64 PNG)."""

from __future__ import annotations

import base64
from dataclasses import asdict

import jinja2

from bench.report.certificate.model import Block, Document, Fields, Figure, Para, Signatures, Table

BAD_PREFIXES = ("FAIL", "NOT MET", "INCOMPLETE", "SIMULATED")


def is_bad(cell: str) -> bool:
    """A cell the reader must not miss: a failed check or an unmet capability rule."""
    text = str(cell)
    return text.startswith(BAD_PREFIXES) or text.endswith("not met")


def _kind(block: Block) -> str:
    for cls, name in ((Para, "para"), (Fields, "fields"), (Table, "table"), (Figure, "figure"),
                      (Signatures, "signatures")):
        if isinstance(block, cls):
            return name
    raise TypeError(f"unknown certificate block {type(block).__name__}")


def _env() -> jinja2.Environment:
    env = jinja2.Environment(
        loader=jinja2.PackageLoader("bench.app.certificate", "templates"),
        autoescape=True, trim_blocks=True, lstrip_blocks=True,
        undefined=jinja2.StrictUndefined)
    env.filters["b64"] = lambda data: base64.b64encode(data).decode("ascii")
    env.tests["bad"] = is_bad
    return env


def render_html(doc: Document) -> str:
    sections = []
    figure_no = 0
    for s in doc.sections:
        blocks = []
        for b in s.blocks:
            kind = _kind(b)
            if kind == "figure":
                figure_no += 1
                view: object = {**asdict(b), "number": figure_no}
            else:
                view = b
            blocks.append((kind, view))
        sections.append({"section": s, "blocks": blocks})
    return _env().get_template("certificate.html.j2").render(doc=doc, sections=sections)
