"""The certificate as PDF with fpdf2 (pure Python; no system packages).

The DejaVu fonts that ship inside matplotlib carry every glyph the certificate uses
(ω, σ, √, ≤, ±, °), so no font has to be installed on the machine. Every page carries
the certificate number and "Page i of n"; the last page ends with "End of certificate".
"""

from __future__ import annotations

import contextlib
import dataclasses
import io
import struct
from collections.abc import Callable, Hashable, Iterator, Sequence
from importlib.util import find_spec
from pathlib import Path

import fpdf.fpdf
from fpdf import FPDF, FontFace
from fpdf.enums import Align, TableCellFillMode, WrapMode, XPos, YPos
from fpdf.errors import FPDFException
from fpdf.fonts import TTFFont
from fpdf.line_break import (
    BREAKING_SPACE_SYMBOLS_STR,
    FORM_FEED,
    NBSP,
    NEWLINE,
    SOFT_HYPHEN,
    Fragment,
    MultiLineBreak,
    TextLine,
)
from fpdf.table import Cell, RowLayoutInfo
from fpdf.table import Table as FpdfTable
from fpdf.util import FloatTolerance, Padding

from bench.app.certificate.html import is_bad
from bench.report.certificate.model import Document, Fields, Figure, Para, Signatures, Table


def _matplotlib_fonts() -> Path:
    """matplotlib's fonts folder (`matplotlib.get_data_path()`), found without importing
    matplotlib (its import is most of a second, and the PDF needs only its fonts)."""
    spec = find_spec("matplotlib")
    if spec is None or spec.origin is None:
        raise ModuleNotFoundError("matplotlib, whose DejaVu fonts the certificate's PDF uses")
    return Path(spec.origin).parent / "mpl-data" / "fonts" / "ttf"


FONT_DIR = _matplotlib_fonts()
SANS, MONO = "DejaVu", "DejaVuMono"
ALIGN = {"l": "LEFT", "r": "RIGHT", "c": "CENTER"}
HEAD_FILL = (232, 236, 242)
BAD = FontFace(emphasis="BOLD", color=(139, 0, 0), fill_color=(251, 229, 229))
BODY_PT, SMALL_PT, TABLE_PT = 9.5, 7.5, 7.5


def _png_size(png: bytes) -> tuple[int, int]:
    if png[:8] != b"\x89PNG\r\n\x1a\n":
        raise ValueError("a certificate figure must be a PNG")
    w, h = struct.unpack(">II", png[16:24])
    return w, h


def _state_key(fragment: Fragment) -> Hashable:
    """What fpdf's line breaking reads of a fragment: its characters, its graphics state
    field by field (font, size, spacing, style, colours; a dict as its items), its scale
    and link. TypeError for a state that cannot be a key (text shaping's settings)."""
    gs = fragment.graphics_state
    names = _STATE_FIELDS.get(type(gs))
    if names is None:
        names = _STATE_FIELDS[type(gs)] = tuple(f.name for f in dataclasses.fields(gs))
    state = tuple(tuple(sorted(v.items())) if isinstance(v := getattr(gs, n), dict) else v
                  for n in names)
    if gs.text_shaping is not None:
        raise TypeError("text shaping")
    return "".join(fragment.characters), state, fragment.k, fragment.link


_STATE_FIELDS: dict[type, tuple[str, ...]] = {}


#: characters fpdf's line breaking treats otherwise than as a glyph or a space to break at
_NOT_PLAIN = frozenset(BREAKING_SPACE_SYMBOLS_STR) - {" "} | {FORM_FEED, NBSP, SOFT_HYPHEN}


def _plain_lines(fragments: Sequence[Fragment], max_width: float | Callable[[float], float],
                 margins: Sequence[float], align: Align) -> list[TextLine] | None:
    """The lines fpdf's `MultiLineBreak` makes of one fragment of plain text (spaces and
    newlines its only breaks), found as it finds them but without re-measuring the line
    so far at each character (most of a certificate's PDF time; issue 62); None for
    anything else, which fpdf breaks. Its rule: characters are added while the line's
    width and the next character's fit; a space that does not fit ends the line, else the
    line ends at its last space, else before the character. The same TextLines to the
    last bit: the widths summed as fpdf's TTF font sums them (whole glyph units, scaled
    once), `_lines_broken_once`'s tests compare them with fpdf's."""
    if len(fragments) != 1 or callable(max_width) or type(fragments[0]) is not Fragment:
        return None
    fragment = fragments[0]
    chars, gs, font = fragment.characters, fragment.graphics_state, fragment.font
    if (gs.text_shaping is not None or gs.char_spacing != 0 or gs.font_stretching != 100
            or not isinstance(font, TTFFont) or font.is_symbol
            or not _NOT_PLAIN.isdisjoint(chars)):
        return None
    fragment.get_width()    # fpdf's measuring notes the font's largest size
    cw, size_pt, k = font.cw, fragment.font_size_pt, fragment.k
    room = max_width
    for margin in margins:
        room -= float(margin)
    last_align = Align.L if align == Align.J else align
    height = fragment.font_size * 1.0

    def line(end: int, units: float, spaces: int, how: Align, added: bool, nl: bool = False
             ) -> TextLine:
        return TextLine(
            fragments=[fragment.clone(characters=chars[begin:end], link=fragment.link)]
            if added else [], text_width=0 + units * size_pt * 0.001 / k if added else 0,
            number_of_spaces=spaces, align=how, height=height if added or nl else 0,
            max_width=max_width - 0, trailing_nl=nl, trailing_form_feed=False, indent=0)

    lines: list[TextLine] = []
    i, n, forced = 0, len(chars), -1
    units: float     # whole glyph units (fpdf's widths), summed as fpdf sums them
    hint: tuple[int, int, float] | None     # the line's last space: where, spaces, units
    while i < n:
        begin, units, spaces, added, hint = i, 0, 0, False, None
        was_forced, forced = forced, -1
        while True:
            if i == n:
                if units * size_pt * 0.001 / k:     # fpdf keeps a line of some width
                    lines.append(line(i, units, spaces, last_align, added))
                break
            char = chars[i]
            unit = cw[ord(char)]
            if char == NEWLINE:
                lines.append(line(i, units, spaces, last_align, added, nl=True))
                i += 1
                break
            if FloatTolerance.greater_than(
                    (0 + units * size_pt * 0.001 / k if added else 0)
                    + unit * size_pt * 0.001 / k, room):
                if char == " ":
                    lines.append(line(i, units, spaces, align, added))
                    i += 1
                elif hint is not None:
                    lines.append(line(hint[0], hint[2], hint[1], align, True))
                    i = hint[0] + 1
                elif was_forced == i:
                    raise FPDFException("Not enough horizontal space to render a single character")
                else:
                    forced = i
                    lines.append(line(i, units, spaces, last_align, added))
                break
            if char == " ":
                hint = (i, spaces, units)
                spaces += 1
            units += unit
            added = True
            i += 1
    return lines


class _BrokenOnce:
    """fpdf's MultiLineBreak, whose lines for a text already broken at the same width, in
    the same fonts and state, are those of its first breaking (a table's cells are broken
    into lines twice: for the rows' heights, then to draw them; issue 62). The same
    TextLines, so the same PDF to the byte; a width given as a function (fpdf's `write`)
    is broken every time."""

    lines: dict[Hashable, list[TextLine]] = {}

    def __init__(self, fragments: Sequence[Fragment], max_width: float | Callable[[float], float],
                 margins: Sequence[float], **options: Align | WrapMode | bool | float) -> None:
        key: Hashable = None
        if not callable(max_width):
            try:
                key = (tuple(_state_key(f) for f in fragments), max_width,
                       tuple(margins), tuple(sorted(options.items())))
                hash(key)
            except TypeError:   # a state that cannot be a key (text shaping's dict)
                key = None
        lines = self.lines.get(key) if key is not None else None
        if lines is None:
            align = options.get("align", Align.L)
            lines = None
            if (set(options) <= {"align", "print_sh", "wrapmode"} and isinstance(align, Align)
                    and options.get("wrapmode", WrapMode.WORD) == WrapMode.WORD):
                lines = _plain_lines(fragments, max_width, margins, align)  # word-wrapped
            if lines is None:
                breaker = MultiLineBreak(fragments, max_width, margins, **options)  # type: ignore[arg-type]
                lines = list(iter(breaker.get_line, None))
            if key is not None:
                self.lines[key] = lines
        self._next = iter(lines)

    def get_line(self) -> TextLine | None:
        return next(self._next, None)


@contextlib.contextmanager
def _lines_broken_once() -> Iterator[None]:
    """While one PDF is rendered, fpdf breaks each text into lines once (`_BrokenOnce`);
    fpdf as it was after (another fpdf, without that name: as it is)."""
    if getattr(fpdf.fpdf, "MultiLineBreak", None) is not MultiLineBreak:
        yield
        return
    fpdf.fpdf.MultiLineBreak = _BrokenOnce  # type: ignore[misc,assignment]
    try:
        yield
    finally:
        fpdf.fpdf.MultiLineBreak = MultiLineBreak  # type: ignore[misc]
        _BrokenOnce.lines.clear()


class _Table(FpdfTable):
    """fpdf's table, whose rows' heights are found without drawing each cell unseen.

    fpdf lays a table out twice: each cell's `multi_cell` run with writing switched off,
    for its height, then again to draw it (issue 62: half a table's time). Here the first
    pass breaks the cell's text into lines only, as `multi_cell` would (the same
    fragments, width, margins and options, so `_BrokenOnce` gives the drawing the same
    lines), takes its height as `multi_cell` adds it up, and picks the glyphs it would
    have picked (the fonts' subsets, so the PDF is the same to the byte). A cell this
    does not know (an image, markdown, text shaping, a span) is measured as fpdf does."""

    def _render_table_cell(self, i: int, j: int, cell: Cell, row_height: float,
                           cell_height_info: RowLayoutInfo | None = None,
                           cell_x_positions: Sequence[float] | None = None,
                           **kwargs: bool | float | str | None) -> tuple[bool, float, float]:
        pdf = self._fpdf
        if (cell_height_info is not None or kwargs or cell.img or not cell.text
                or self._markdown or pdf.text_shaping or cell.colspan != 1
                or row_height != self._line_height):
            return super()._render_table_cell(
                i, j, cell, row_height, cell_height_info, cell_x_positions, **kwargs)
        style = self._initial_style
        assert style is not None
        if self._cell_fill_mode.should_fill_cell(i, j) and self._cell_fill_color:
            style = style.replace(fill_color=self._cell_fill_color)
        if i < self._num_heading_rows:
            style = FontFace.combine(style, self._headings_style)
        style = FontFace.combine(FontFace.combine(style, self.rows[i].style), cell.style)
        padding = Padding.new(cell.padding) if cell.padding else self._padding
        align = cell.align or self._text_align
        if not isinstance(align, Align | str):
            align = align[j]
        width = self._get_col_width(i, j) - padding.right - padding.left
        margins = [pdf.c_margin] * ((not padding.left) + (not padding.right))
        assert style is not None
        with pdf.use_font_face(style):
            fragments = pdf._preload_font_styles(  # noqa: SLF001 - multi_cell's own step
                pdf.normalize_text(cell.text).replace("\r", ""), False)
            breaker = fpdf.fpdf.MultiLineBreak(fragments, width, margins, align=Align.coerce(align),
                                               print_sh=False, wrapmode=self._wrapmode)
            lines = list(iter(breaker.get_line, None))
        for line in lines:      # the glyphs, in the order fpdf's unseen drawing picked them
            for fragment in line.get_ordered_fragments():
                if isinstance(font := fragment.font, TTFFont):
                    for char in fragment.string:
                        font.subset.pick(ord(char))
        total: float = 0
        for _ in range(max(len(lines), 1)):     # no text: one empty line
            total += row_height                 # as multi_cell sums it
        return False, 0, max(total, row_height) + padding.top + padding.bottom


class _Pdf(FPDF):
    def __init__(self, doc: Document, png_of: Callable[[Figure], bytes]) -> None:
        super().__init__(orientation="P", unit="mm", format="A4")
        self.doc = doc
        self.png_of = png_of
        self.add_font(SANS, "", FONT_DIR / "DejaVuSans.ttf")
        self.add_font(SANS, "B", FONT_DIR / "DejaVuSans-Bold.ttf")
        self.add_font(SANS, "I", FONT_DIR / "DejaVuSans-Oblique.ttf")
        self.add_font(MONO, "", FONT_DIR / "DejaVuSansMono.ttf")
        self.add_font(MONO, "B", FONT_DIR / "DejaVuSansMono-Bold.ttf")
        self.set_margins(15, 22, 15)
        self.set_auto_page_break(True, margin=18)
        self.set_title(f"{doc.title} {doc.cert_id}")
        self.set_author(doc.laboratory)
        self.set_subject(doc.subtitle)
        self.set_creator("ratebench")

    def header(self) -> None:
        self.set_y(9)
        self.set_font(SANS, "", 8)
        self.set_text_color(60, 60, 60)
        self.cell(0, 4, self.doc.laboratory, new_x=XPos.LMARGIN, new_y=YPos.TOP)
        label = self.doc.meta.get("header_label")     # a document not a certificate
        self.cell(0, 4, label or (("Certificate No. " if self.doc.issue_date else "Draft ")
                                  + self.doc.cert_id), align="R",
                  new_x=XPos.LMARGIN, new_y=YPos.NEXT)
        issued = (f"issued {self.doc.issue_date}" if self.doc.issue_date
                  else "DRAFT, NOT AUTHORISED, not issued")
        if label:
            issued = self.doc.issue_date
        self.cell(0, 4, f"{self.doc.title}, {issued}",
                  new_x=XPos.LMARGIN, new_y=YPos.TOP)
        self.cell(0, 4, f"Page {self.page_no()} of {{nb}}", align="R",
                  new_x=XPos.LMARGIN, new_y=YPos.NEXT)
        self.set_draw_color(34, 51, 68)
        self.set_line_width(0.4)
        self.line(self.l_margin, self.get_y() + 1, self.w - self.r_margin, self.get_y() + 1)
        self.set_text_color(0, 0, 0)
        if self.doc.watermark:
            self._watermark()
        self.set_y(22)

    def _watermark(self) -> None:
        """Across the page, light, under the content drawn after it; and in the header."""
        y = self.get_y()
        self.set_font(SANS, "B", 34)
        self.set_text_color(238, 200, 200)
        marks = self.doc.watermark.split(" / ")     # one mark per line across the page
        with self.rotation(45, x=self.w / 2, y=self.h / 2):
            for i, mark in enumerate(marks):
                self.set_xy(0, self.h / 2 - 8 + (i - (len(marks) - 1) / 2) * 18)
                self.cell(self.w, 16, mark, align="C")
        self.set_font(SANS, "B", 7.5)
        self.set_text_color(139, 0, 0)
        self.set_xy(self.l_margin, y + 1.5)
        self.cell(0, 3.5, self.doc.watermark, align="C")
        self.set_text_color(0, 0, 0)

    def footer(self) -> None:
        self.set_y(-14)
        self.set_draw_color(150, 150, 170)
        self.set_line_width(0.2)
        self.line(self.l_margin, self.get_y(), self.w - self.r_margin, self.get_y())
        self.set_font(SANS, "", 6.5)
        self.set_text_color(80, 80, 80)
        self.multi_cell(0, 3, self.doc.footer, new_x=XPos.LMARGIN, new_y=YPos.NEXT)
        self.set_text_color(0, 0, 0)

    @contextlib.contextmanager
    def laid_out(self, table: FpdfTable) -> Iterator[FpdfTable]:
        """fpdf's `table` context for a table made here (a `_Table`: laid out once; its
        keywords typed by fpdf's Table)."""
        yield table
        table.render()

    # -- blocks ----------------------------------------------------------------------------
    @property
    def text_w(self) -> float:
        return self.w - self.l_margin - self.r_margin

    def para(self, p: Para) -> None:
        if p.style == "formula":
            self.set_font(MONO, "", 8.5)
            self.set_x(self.l_margin + 8)
            self.multi_cell(self.text_w - 8, 4.4, p.text, new_x=XPos.LMARGIN, new_y=YPos.NEXT)
        else:
            style = "B" if p.style == "strong" else ""
            size = SMALL_PT + 0.5 if p.style == "note" else BODY_PT
            self.set_font(SANS, style, size)
            self.multi_cell(0, size * 0.48, p.text, new_x=XPos.LMARGIN, new_y=YPos.NEXT)
        self.ln(1.2)

    def fields(self, f: Fields) -> None:
        self.set_font(SANS, "", 8.5)
        label = FontFace(emphasis="BOLD", fill_color=(244, 246, 249))
        with self.laid_out(_Table(self, col_widths=(1.0, 2.4), first_row_as_headings=False,
                                  # one alignment per column, as fpdf's Table takes
                                  # them (its hint names one)
                                  line_height=4.2,
                                  text_align=("LEFT", "LEFT"),  # type: ignore[arg-type]
                                  padding=(0.8, 1.5),
                                  cell_fill_mode=TableCellFillMode.NONE)) as t:
            for k, v in f.rows:
                row = t.row()
                row.cell(k, style=label)
                row.cell(v, style=BAD if is_bad(v) else None)
        self.ln(2)

    def caption(self, text: str) -> None:
        self.set_font(SANS, "I", 8)
        self.multi_cell(0, 3.8, text, new_x=XPos.LMARGIN, new_y=YPos.NEXT)
        self.ln(0.6)

    def table_block(self, tb: Table) -> None:
        if self.will_page_break(22):
            self.add_page()
        if tb.caption:
            self.caption(tb.caption)
        n = len(tb.header)
        widths = tb.widths if len(tb.widths) == n else (1.0,) * n
        align = tuple(ALIGN.get(a, "LEFT") for a in (tb.align or "l" * n).ljust(n, "l"))
        head = FontFace(emphasis="BOLD", fill_color=HEAD_FILL, size_pt=TABLE_PT)
        self.set_font(MONO if tb.mono else SANS, "", 6.3 if tb.mono else TABLE_PT)
        with self.laid_out(_Table(self, col_widths=widths, line_height=3.6,
                                  text_align=align,  # type: ignore[arg-type] # per column
                                  headings_style=head, repeat_headings=1, padding=(0.6, 1.0),
                                  cell_fill_mode=TableCellFillMode.NONE)) as t:
            hrow = t.row()
            for h in tb.header:
                hrow.cell(h, align="CENTER")
            for cells in tb.rows:
                row = t.row()
                for c in cells:
                    row.cell(c, style=BAD if is_bad(c) else None)
        self.set_font(SANS, "", SMALL_PT)
        for note in tb.notes:
            self.multi_cell(0, 3.4, note, new_x=XPos.LMARGIN, new_y=YPos.NEXT)
        self.ln(2.5)

    def figure(self, fig: Figure, number: int) -> None:
        png = self.png_of(fig)
        w_px, h_px = _png_size(png)
        w = self.text_w * fig.width_frac
        h = w * h_px / w_px
        room = self.h - self.b_margin - self.get_y()
        if h + 9 > room and 0.7 * h + 9 <= room:  # shrink a little rather than leave a gap
            h = room - 9
            w = h * w_px / h_px
        elif h + 9 > room:
            self.add_page()
            room = self.h - self.b_margin - self.get_y()
        if h + 9 > room:  # taller than a page: shrink to fit
            h = room - 9
            w = h * w_px / h_px
        self.image(io.BytesIO(png), x=self.l_margin + (self.text_w - w) / 2, w=w, h=h)
        self.ln(1)
        self.set_font(SANS, "I", 8)
        self.multi_cell(0, 3.8, f"Figure {number}: {fig.caption}", align="C",
                        new_x=XPos.LMARGIN, new_y=YPos.NEXT)
        self.ln(3)

    def signatures(self, s: Signatures) -> None:
        if self.will_page_break(32):
            self.add_page()
        self.ln(12)
        n = len(s.signers)
        gap = 10.0
        col = (self.text_w - gap * (n - 1)) / max(n, 1)
        y = self.get_y()
        for i, (role, name) in enumerate(s.signers):
            x = self.l_margin + i * (col + gap)
            self.set_draw_color(0, 0, 0)
            self.line(x, y, x + col, y)
            self.set_xy(x, y + 1)
            self.set_font(SANS, "", 8)
            text = f"{name + ', ' if name else ''}{role}\nSignature and date"
            self.multi_cell(col, 3.8, text, align="L")
        self.set_y(y + 12)


def _png(fig: Figure) -> bytes:
    return fig.png


def render_pdf(doc: Document, png_of: Callable[[Figure], bytes] = _png) -> bytes:
    """The PDF of `doc`; `png_of(figure)` gives each figure's PNG as it is placed (the
    figures drawn beside the tables: bench/app/certificate/figures.py)."""
    with _lines_broken_once():
        return _rendered(doc, png_of)


def _rendered(doc: Document, png_of: Callable[[Figure], bytes]) -> bytes:
    pdf = _Pdf(doc, png_of)
    pdf.add_page()
    pdf.set_font(SANS, "B", 18)
    pdf.cell(0, 10, doc.title, new_x=XPos.LMARGIN, new_y=YPos.NEXT)
    pdf.set_font(SANS, "", 11)
    pdf.multi_cell(0, 5.5, doc.subtitle, new_x=XPos.LMARGIN, new_y=YPos.NEXT)
    if doc.meta.get("run_title"):
        pdf.set_font(SANS, "I", 9.5)
        pdf.multi_cell(0, 5, doc.meta["run_title"], new_x=XPos.LMARGIN, new_y=YPos.NEXT)
    pdf.ln(2)
    if doc.verdict:     # a document without a verdict (an impact report) has no box
        colours = {"pass": ((216, 239, 216), (18, 77, 18)),
                   "fail": ((246, 210, 210), (139, 0, 0))}
        fill, ink = colours.get(doc.verdict, ((247, 236, 201), (107, 75, 0)))
        pdf.set_fill_color(*fill)
        pdf.set_text_color(*ink)
        pdf.set_font(SANS, "B", 11)
        pdf.cell(60, 7, f"Result: {doc.verdict.upper()}", fill=True, align="C",
                 new_x=XPos.LMARGIN, new_y=YPos.NEXT)
        pdf.set_text_color(0, 0, 0)
        pdf.set_fill_color(255, 255, 255)
        pdf.ln(1)
    if doc.meta.get("scope"):
        pdf.set_font(SANS, "", 8.5)
        pdf.multi_cell(0, 4.2, doc.meta["scope"], new_x=XPos.LMARGIN, new_y=YPos.NEXT)
    if doc.meta.get("replaces"):
        pdf.set_font(SANS, "B", 8.5)
        pdf.multi_cell(0, 4.2, f"Revision {doc.meta.get('revision')}: replaces certificate "
                               f"{doc.meta['replaces']}, which is withdrawn.",
                       new_x=XPos.LMARGIN, new_y=YPos.NEXT)
    pdf.ln(2)
    figure_no = 0
    for s in doc.sections:
        keep = 75 if any(isinstance(b, Signatures) for b in s.blocks) else 25
        if s.new_page or pdf.will_page_break(keep):  # a heading stays with what follows
            pdf.add_page()
        pdf.set_font(SANS, "B", 12 if s.level == 1 else 10.5)
        pdf.ln(2 if s.level == 1 else 1)
        pdf.cell(0, 6.5, f"{s.number} {s.title}", new_x=XPos.LMARGIN, new_y=YPos.NEXT)
        if s.level == 1:
            pdf.set_draw_color(150, 150, 170)
            pdf.set_line_width(0.2)
            pdf.line(pdf.l_margin, pdf.get_y(), pdf.w - pdf.r_margin, pdf.get_y())
        pdf.ln(1.5)
        for b in s.blocks:
            if isinstance(b, Para):
                pdf.para(b)
            elif isinstance(b, Fields):
                pdf.fields(b)
            elif isinstance(b, Table):
                pdf.table_block(b)
            elif isinstance(b, Figure):
                figure_no += 1
                pdf.figure(b, figure_no)
            elif isinstance(b, Signatures):
                pdf.signatures(b)
            else:
                raise TypeError(f"unknown certificate block {type(b).__name__}")
    pdf.ln(6)
    pdf.set_font(SANS, "B", 10)
    pdf.cell(0, 6, f"— {doc.end_text} {doc.cert_id} —", align="C",
             new_x=XPos.LMARGIN, new_y=YPos.NEXT)
    return bytes(pdf.output())
