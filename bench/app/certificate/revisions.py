"""What changed between two revisions of a certificate: every statement it makes, not only
result.json (issue 43).

Why: a re-issue states what it changes (ISO/IEC 17025 7.8.8.2). The values come from
result.json, but a revision also states the measurement assurance of the instruments, the
traceability, the conformity text, conditions and deviations, which come from the run
directory and the lab's records and may change while result.json does not. The replaced
revision's statements are read from its HTML as issued (issued/<number>/certificate.html),
never rebuilt from today's files; the new revision's from its document rendered the same
way. Lines that name the revision itself (number, revision, date of issue, authorisation,
the event log's growing byte count) differ by nature and are not compared.
"""

from __future__ import annotations

from collections.abc import Iterator

from lxml import html as lxml_html

from bench.core import rundir_layout as layout

#: sections whose every line belongs to the revision itself
OWN_SECTIONS = ("Authorisation",)
#: field labels (and line starts) that name the revision itself, not what it states
OWN_LINES = ("Certificate number", "Draft identifier", "Revision", "Date of issue",
             layout.EVENTS, "Page ")


def _text(node: lxml_html.HtmlElement) -> str:
    return " ".join(node.text_content().split())


def statements(html_text: str) -> list[tuple[str, str]]:
    """(section title, statement) of every paragraph, field, table caption and table row of
    a certificate's HTML, in order; a row's cells joined by ' | '."""
    root = lxml_html.fromstring(html_text.encode("utf-8"))
    out: list[tuple[str, str]] = []
    for section in root.iter("section"):
        head = section.find("h2")
        title = _text(head).split(" ", 1)[-1] if head is not None else ""
        if title in OWN_SECTIONS:
            continue
        for node in section.iter("p", "tr", "div"):
            if node.tag == "div" and "caption" not in (node.get("class") or ""):
                continue
            if node.tag == "tr":
                cells = [_text(c) for c in node if c.tag in ("td", "th")]
                line = " | ".join(cells) if "fields" not in (
                    node.getparent().get("class") or "") else ": ".join(cells)
            else:
                line = _text(node)
            if line and not line.startswith(OWN_LINES):
                out.append((title, line))
    return out


def _key(line: str) -> str:
    """What pairs an old line with its new version: a field's label, a row's first cells."""
    if " | " in line:
        return " | ".join(line.split(" | ")[:3])
    return line.split(": ", 1)[0] if ": " in line else line


def _diff(old: list[tuple[str, str]], new: list[tuple[str, str]]) -> Iterator[str]:
    before, after = set(old), set(new)
    gone = [s for s in old if s not in after]
    came = [s for s in new if s not in before]
    paired = {(sec, _key(line)): line for sec, line in came}
    used = set()
    for sec, line in gone:
        match = paired.get((sec, _key(line)))
        if match is not None and (sec, match) not in used:
            used.add((sec, match))
            yield f"{sec}: '{line}' -> '{match}'"
        else:
            yield f"{sec}: no longer states '{line}'"
    for sec, line in came:
        if (sec, line) not in used:
            yield f"{sec}: now states '{line}'"


def statement_changes(old_html: str | None, new_html: str) -> tuple[str, ...] | None:
    """Every statement that differs between the replaced revision's HTML and the new one's;
    None when the replaced revision's HTML is not kept (nothing can be said)."""
    if old_html is None:
        return None
    return tuple(_diff(statements(old_html), statements(new_html)))
