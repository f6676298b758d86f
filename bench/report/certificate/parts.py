"""What a procedure kind builds its part of the certificate from, and what it is asked.

The certificate (build.py) writes the sections every certificate has and asks the
procedure kind for the rest through `CertificateParts`, whose answers here are neutral: a
kind inherits it and overrides what it has to say (its method, its results sections, its
item). The kind builds its blocks from the document model (model.py), the rounding rules
(rounding.py), the plots (plots.py) and the helpers below, which the certificate uses too,
so that both print a value the same way. Nothing here names a procedure.
"""

from __future__ import annotations

import contextvars
from collections.abc import Callable, Mapping, Sequence
from typing import Protocol, TypeVar

from bench.analysis.finite import finite_number as num
from bench.core.yamlfile import YamlValue
from bench.report.certificate.model import Block, Figure, Para, Section
from bench.report.certificate.rounding import MINUS, RelUnit, format_value_u
from bench.report.certificate.sources import Sources as Sources
from bench.report.certificate.sources import StandIdentity
from bench.report.result_frame import Check, JsonValue

NOT_RECORDED = "not recorded"

M = TypeVar("M")


# -- the inputs ----------------------------------------------------------------------------
# Sources (the run directory decoded: bench/report/certificate/sources.py) is named here too,
# where every kind's certificate and DCC part has always imported it from.

def stand_of(src: Sources) -> StandIdentity:
    """The stand's identity: the stand file's, with what result.json says over it
    (decoded once, `Sources.stand`)."""
    return src.stand


# -- values as printed ---------------------------------------------------------------------



UNIT_SUFFIXES = {"c": "°C", "deg": "°", "pct": "%", "hpa": "hPa", "hz": "Hz", "s": "s",
                 "dps": "°/s", "dph": "°/h", "dps2": "°/s²", "v": "V", "rel": "fraction"}


def label_of(key: str) -> str:
    """`static_record_s` -> 'Static record, s'."""
    words = str(key).split("_")
    unit = UNIT_SUFFIXES.get(words[-1].lower()) if len(words) > 1 else None
    text = " ".join(words[:-1] if unit else words)
    text = text[:1].upper() + text[1:]
    return f"{text}, {unit}" if unit else text


def text_of(value: YamlValue) -> str:
    """Any recorded value as text; nothing recorded says so."""
    if value is None or value == "":
        return NOT_RECORDED
    if isinstance(value, float):
        return f"{value:.6g}"
    if isinstance(value, list | tuple):
        return ", ".join(text_of(v) for v in value)
    if isinstance(value, dict):
        return "; ".join(_key_value(k, v) for k, v in value.items())
    return str(value).replace("+/-", "±")


def _key_value(key: str, value: YamlValue) -> str:
    """`max_rate_dps: 400` -> 'max rate: 400 °/s'."""
    words = str(key).split("_")
    unit = UNIT_SUFFIXES.get(words[-1].lower()) if len(words) > 1 else None
    if unit and unit != "fraction":
        return f"{' '.join(words[:-1])}: {text_of(value)} {unit}"
    return f"{' '.join(words)}: {text_of(value)}"


def rate_text(x: JsonValue) -> str:
    """A signed rate as written: '+10', '−10'."""
    v = num(x)
    if v is None:
        return NOT_RECORDED
    return f"{v:+g}".replace("-", MINUS)


def vu_text(value: JsonValue, u: JsonValue, unit: RelUnit | None = None,
            signed: bool = False) -> str:
    """'value ± U' under the rounding rules, in `unit` (relative) or as given."""
    scale = unit.scale if unit else 1.0
    return format_value_u(num(value), num(u), scale, signed).joined()


def verdict_label(verdict: str | None, rule: str | None = None,
                  inside_tolerance: bool = False) -> str:
    """How a verdict is printed; a guard-band refusal says so."""
    v = str(verdict or "").strip().lower()
    if v == "pass":
        return "PASS"
    if v in ("conditional", "conditional-pass"):
        return "CONDITIONAL"
    if v in ("fail-guard-band", "guard-band", "not-passed"):
        return "FAIL (guard band)"
    if v == "fail":
        return "FAIL (guard band)" if rule == "guard-band" and inside_tolerance else "FAIL"
    if v == "incomplete":
        return "INCOMPLETE"
    if v == "not-assessed":
        return "NOT ASSESSED"
    return v.upper() or "—"


class FigureDrawer(Protocol):
    """Draws a certificate's figures elsewhere while the certificate is built and laid out
    (bench/app/certificate/figures.py: in worker processes, beside the PDF's tables)."""

    def blocks(self, caption: str, draw: Callable[..., bytes | None], args: tuple[object, ...],
               width_frac: float) -> list[Block] | None:
        """What `figure_of` returns for this figure, or None: `figure_of` draws it here."""


#: the drawer of the certificate being built, if it is not drawn figure by figure here
FIGURE_DRAWER: contextvars.ContextVar[FigureDrawer | None] = contextvars.ContextVar(
    "figure_drawer", default=None)


def figure_of(caption: str, draw: Callable[..., bytes | None], *args: object,
              width_frac: float = 1.0) -> list[Block]:
    """A plot as a figure block; data that cannot be drawn give a note, not a crash.
    `draw(*args)` gives the PNG, here or, while a `FIGURE_DRAWER` is set, as it says."""
    drawer = FIGURE_DRAWER.get()
    if drawer is not None and (found := drawer.blocks(caption, draw, args, width_frac)) is not None:
        return found
    try:
        png = draw(*args)
    except (ValueError, TypeError, KeyError, IndexError, ZeroDivisionError) as e:
        return [Para(f"Figure not drawn ({caption}): its data are malformed ({e}).", "note")]
    return [Figure(png, caption, width_frac)] if png else []


# -- what the certificate asks a procedure kind --------------------------------------------

#: an annex or other section the kind adds after the records: title and blocks
TitledBlocks = tuple[str, tuple[Block, ...]]


class CertificateParts:
    """The certificate's questions to a procedure kind, with neutral answers.

    A kind's `certificate` part is one of these (a subclass that overrides
    what it has to say); the certificate asks through these only and names no kind. A kind
    that says nothing still gets a certificate: identification, instruments, conditions,
    conformity with its checks, records and signatures.
    """

    #: the Identification's 'Procedure' row (empty: the kind's registered name)
    certificate_procedure_name: str = ""
    #: (procedure ID, the part of docs/method.md it follows, the reference that part
    #: follows; bench/report/certificate/methods.py): the Method's ID, revision and validation rows
    certificate_procedure_id: tuple[str, str, str] | None = None
    #: the Instruments' row that identifies the laboratory's stand
    certificate_stand_label: str = "Test stand used (the laboratory's)"
    #: what the procedure measures that a datasheet may specify: (quantity key, words);
    #: those no check covers are listed as not assessed
    certificate_measured: tuple[tuple[str, str], ...] = ()
    #: the checks' quantity keys in words (others are printed from the key)
    certificate_quantities: Mapping[str, str] = {}
    #: quantities printed without a sign in the conformity table (magnitudes)
    certificate_unsigned: frozenset[str] = frozenset()

    def certificate_recognises(self, src: Sources) -> bool:
        """Whether a result that names no procedure is this kind's (an older result)."""
        return False

    def certificate_item(self, src: Sources) -> tuple[str, str]:
        """(what was calibrated, its serial); by default the stand named in the stand file."""
        stand = stand_of(src)
        return f"{text_of(stand.maker)} {text_of(stand.model)}", text_of(stand.serial)

    def certificate_identification(self, src: Sources) -> Sequence[tuple[str, str]]:
        """Rows added to the Identification after the item's serial number."""
        return ()

    def certificate_method(self, src: Sources) -> Sequence[Block]:
        """The method statement, printed before the procedure file's settings."""
        return ()

    def certificate_method_deviations(self, src: Sources) -> Sequence[Block]:
        """How the method departs from its source, before the run's own deviations."""
        return ()

    def certificate_run_deviations(self, src: Sources) -> Sequence[str]:
        """The kind's deviations in this run, one sentence each."""
        return ()

    def certificate_checks(self, src: Sources) -> list[Check]:
        """The checks when result.json carries no checks[] (read from the kind's results)."""
        return []

    def certificate_sections(self, src: Sources, number: str,
                             checks: Sequence[Check]) -> list[Section]:
        """The results: the section numbered `number` and any subsections (`number`.n)."""
        return [Section(number, "Results", (Para(
            "The procedure kind states no results of its own on the certificate; they are "
            "in result.json."),))]

    def certificate_annexes(self, src: Sources) -> Sequence[TitledBlocks]:
        """Sections after the records (per-turn data and the like)."""
        return ()

    def certificate_statements(self, statements: Sequence[str]) -> list[str]:
        """The closing statements that apply to this kind's results."""
        return list(statements)
