"""The certificate as a document model, rendered alike to HTML and to PDF.

`build.py` decides every word and number once; the renderers only lay them out, so the
two formats cannot disagree about a value.
"""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass(frozen=True)
class Para:
    """A paragraph. style: body, note (small), formula (monospace, indented), strong."""

    text: str
    style: str = "body"


@dataclass(frozen=True)
class Fields:
    """Label / value rows (identification, instruments, conditions)."""

    rows: tuple[tuple[str, str], ...]


@dataclass(frozen=True)
class Table:
    """A table. `widths` are relative column widths; `align` one of l, c, r per column.

    A cell whose text starts with FAIL, NOT MET or INCOMPLETE is shown highlighted.
    """

    header: tuple[str, ...]
    rows: tuple[tuple[str, ...], ...]
    widths: tuple[float, ...] = ()
    align: str = ""
    caption: str = ""
    notes: tuple[str, ...] = ()
    mono: bool = False  # hashes and file names

    def __post_init__(self) -> None:
        for row in self.rows:
            if len(row) != len(self.header):
                raise ValueError(f"table {self.caption!r}: row {row!r} has {len(row)} cells, "
                                 f"header has {len(self.header)}")


@dataclass(frozen=True)
class Figure:
    """A plot as PNG bytes; width_frac of the text width."""

    png: bytes
    caption: str
    width_frac: float = 1.0


@dataclass(frozen=True)
class Signatures:
    """Signature lines: (role, name) per signer; the name may be blank for handwriting."""

    signers: tuple[tuple[str, str], ...]


Block = Para | Fields | Table | Figure | Signatures


@dataclass(frozen=True)
class Section:
    number: str
    title: str
    blocks: tuple[Block, ...]
    level: int = 1
    new_page: bool = False


@dataclass(frozen=True)
class Document:
    cert_id: str
    title: str
    subtitle: str
    laboratory: str
    issue_date: str
    verdict: str
    sections: tuple[Section, ...]
    footer: str
    end_text: str = "End of certificate"
    meta: dict[str, str] = field(default_factory=dict)
    watermark: str = ""  # printed across every page (a simulated run)

    def figures(self) -> list[Figure]:
        return [b for s in self.sections for b in s.blocks if isinstance(b, Figure)]
