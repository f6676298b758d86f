"""`bench impact`'s JSON <-> typed values (issue 60), by msgspec: the report `bench impact
--json` writes and `--report` lays out, its audit entry, the corrections file of the copy
analysed again, and what the assessment reads of a result.json.

Why a module of its own: it is the one place of the impact analysis where JSON meets typed
values (tests/test_json_boundary.py keeps JSON out of bench/app/impact.py and
impact_report.py). Encoding gives the builtins `json.dumps` writes (bench/report/codec.py:
its floats, tuples as lists), so the report's bytes are those of before; decoding refuses a
malformed document naming the key path in its own terms (`impact.json runs[0].figures[1]
.shift: expected a number, got str`).

A result.json is read kind-neutrally (bench/ names no kind): each rate and pair entry of
`axes.<axis>`, each gyro of `drift.axes` and `drift` itself, and in each the figures that
state an expanded U beside them under the key the kinds' models write it with
(`<name>_U_<unit>` beside `<name>_<unit>`, `<name>_U` beside `<name>`).
"""

from __future__ import annotations

import datetime as dt
import json
import math
import re
from collections.abc import Sequence
from typing import TypeVar

import msgspec

from bench.core import rundir_layout as layout
from bench.report.codec import encode
from drivers.json_types import JsonObject, JsonValue

#: a figure's unit by the suffix its U key carries (`rate_error_U_rel`: rel)
UNITS = {"rel": "1", "dps": "deg/s", "dps_per_h": "deg/s/h", "": "1", "deg": "deg",
         "s": "s", "hz": "Hz", "dph": "deg/h"}

#: the report's file name in the refusals it gets
REPORT = "impact.json"

T = TypeVar("T")

#: msgspec's type names, as a reader of the file says them
_TYPES = {"float": "a number", "int": "an integer", "bool": "true or false",
          "object": "an object", "array": "a list", "str": "text", "null": "null"}


class MalformedDocument(ValueError):
    """A JSON document that does not hold what its writer writes; the message names the
    file and the key path."""


# -- the report -----------------------------------------------------------------------------

class Finding(msgspec.Struct, frozen=True):
    """The item's as-found error and the span of runs it touches."""

    serial: str
    model: str
    certificate: str               # the calibration that found it
    issuer: str
    calibrated_on: dt.date | None
    found: str | None
    error: float
    error_u: float | None
    since: dt.date | None          # the last calibration that found it in tolerance
    since_certificate: str | None


class FigureShift(msgspec.Struct, frozen=True):
    """One figure of a run, issued and analysed again with the correction."""

    where: str                     # e.g. axes.outer.rates[+50 deg/s]
    name: str
    unit: str
    issued: float
    corrected: float
    shift: float
    u_issued: float                # the issued figure's expanded U
    shift_over_u: float
    marked: bool                   # |shift| > U/3


class CheckChange(msgspec.Struct, frozen=True):
    """A conformity statement whose outcome the correction changes."""

    axis: str
    set_rate_dps: float | None
    quantity: str
    issued: str
    corrected: str


class Customer(msgspec.Struct, frozen=True, omit_defaults=True):
    """The customer a run's result names (its certificate block), only what it states."""

    customer: str | None = None
    customer_address: str | None = None
    customer_contact: str | None = None


class RunImpact(msgspec.Struct, frozen=True, kw_only=True):
    """One run the finding touches: what the register holds of it, and what became of it."""

    uid: str
    registered_utc: str
    where: str                     # the item's place on the stand (axes.outer.counter)
    number: str | None             # the certificate number the register issued, if any
    revisions: tuple[str, ...] = ()
    folder: str | None = None
    status: str = ""               # re-analysed | raw data not found | not re-analysed: ...
    figures: tuple[FigureShift, ...] = ()
    checks_changed: tuple[CheckChange, ...] = ()
    customer: Customer | None = None
    #: of the figure that moved most against its U: derived from `figures`, never stated
    largest_shift_over_U: float | None = None       # noqa: N815

    def __post_init__(self) -> None:
        big = self.largest()
        msgspec.structs.force_setattr(self, "largest_shift_over_U",
                                      None if big is None else big.shift_over_u)

    @property
    def reanalysed(self) -> bool:
        return self.status == "re-analysed"

    def largest(self) -> FigureShift | None:
        return max(self.figures, key=lambda f: abs(f.shift_over_u), default=None)


class ImpactReport(msgspec.Struct, frozen=True):
    """The document `bench impact --json` writes: the register asked, the finding, the
    marking threshold and every run the finding touches."""

    register: str
    finding: Finding
    mark_fraction_of_U: float      # noqa: N815
    runs: tuple[RunImpact, ...]


class AuditRun(msgspec.Struct, frozen=True):
    """A run as the audit entry of the assessment names it."""

    uid: str
    number: str | None
    status: str
    largest_shift_over_U: float | None        # noqa: N815
    checks_changed: int


class ImpactAudit(msgspec.Struct, frozen=True, kw_only=True, omit_defaults=True):
    """The audit entry's detail (ISO/IEC 17025 7.10): the finding, the runs and the
    certificates it touched, and each report file's SHA-256 when a report was written."""

    nonconforming_work: str
    report: dict[str, str] | None = None
    finding: Finding
    runs: tuple[AuditRun, ...]
    certificates: tuple[str, ...]


def encode_report(report: ImpactReport) -> str:
    """The report as `bench impact --json` writes it."""
    return json.dumps(encode(report), indent=2) + "\n"


def _refusal(what: str, err: msgspec.ValidationError | msgspec.DecodeError) -> MalformedDocument:
    """msgspec's `Expected `float`, got `str` - at `$.runs[0].shift`` as `what runs[0].shift:
    expected ...`."""
    text = str(err)
    at = re.search(r" - at `\$(?P<path>[^`]*)`$", text)
    path = at["path"].lstrip(".") if at else ""
    text = text[:at.start()] if at else text
    if m := re.match(r"^Object missing required field `(?P<key>[^`]+)`", text):
        path, text = f"{path}.{m['key']}".lstrip("."), "missing"
    elif m := re.match(r"^Expected `(?P<want>[^`]+)`, got `(?P<got>[^`]+)`", text):
        want = " or ".join(_TYPES.get(t, t) for t in m["want"].split(" | "))
        text = f"expected {want}, got {_TYPES.get(m['got'], m['got'])}"
    return MalformedDocument(f"{what}{' ' + path if path else ''}: {text}")


def _decode(data: str | bytes, model: type[T], what: str) -> T:
    """`data` as `model`, or MalformedDocument naming `what` and the key path."""
    try:
        return msgspec.json.decode(data, type=model)
    except (msgspec.ValidationError, msgspec.DecodeError) as err:
        raise _refusal(what, err) from None


def decode_report(data: str | bytes) -> ImpactReport:
    """A report as `encode_report` wrote it, or MalformedDocument naming the key path."""
    return _decode(data, ImpactReport, REPORT)


def audit_detail(audit: ImpactAudit) -> JsonObject:
    """The audit entry's detail as the register stores it (its hash chain covers the bytes
    of this mapping's encoding: keys in the Structs' order, as before)."""
    return encode(audit)


# -- the corrections file of the copy analysed again ------------------------------------------

class CorrectionEntry(msgspec.Struct, frozen=True):
    """One correction as a run folder's corrections file states it (the kinds' analyses
    read it; bench/report/corrections.py reads what a result says it applied)."""

    where: str
    serial: str
    model: str
    quantity: str
    value: float
    U: float | None                # noqa: N815
    source: str


class _Corrections(msgspec.Struct, frozen=True):
    corrections: tuple[CorrectionEntry, ...]


def encode_corrections(entries: tuple[CorrectionEntry, ...]) -> str:
    """The corrections file's text."""
    return json.dumps(encode(_Corrections(entries)), indent=2) + "\n"


class ReasonedCorrection(CorrectionEntry, frozen=True):
    """A correction as a corrected re-issue's corrections file states it: with why it is
    applied (null: no reason given), which the result then states beside it."""

    reason: str | None


class _Reasoned(msgspec.Struct, frozen=True):
    corrections: tuple[ReasonedCorrection, ...]


def encode_reasoned_corrections(entries: Sequence[CorrectionEntry], reason: str | None
                                ) -> str:
    """The corrections file of a corrected re-issue (bench/app/certificate/corrected.py):
    each entry with `reason` last, the bytes the re-issue wrote before."""
    return json.dumps(encode(_Reasoned(tuple(
        ReasonedCorrection(**msgspec.structs.asdict(e), reason=reason) for e in entries))),
        indent=2) + "\n"


# -- what the assessment reads of a run folder and a result.json -------------------------------

class _Meta(msgspec.Struct, frozen=True):
    run_uid: str | None = None
    bench_version: str | None = None


class RunMeta(msgspec.Struct, frozen=True):
    """What a run folder's meta.json says of the run's identity."""

    run_uid: str
    bench_version: str


def json_tree(data: str | bytes) -> JsonValue:
    """A whole JSON document as plain values (what a byte-for-byte comparison walks)."""
    tree: JsonValue = json.loads(data)
    return tree


def run_meta(data: str | bytes) -> RunMeta:
    """meta.json's uid and version, or MalformedDocument."""
    meta = _decode(data, _Meta, layout.META)
    return RunMeta(meta.run_uid or "", meta.bench_version or "")


class Figure(msgspec.Struct, frozen=True):
    """A figure that states its expanded U beside it, in its unit."""

    value: float
    U: float                       # noqa: N815
    unit: str


class Outcome(msgspec.Struct, frozen=True):
    """A conformity statement of a result: what it judged and the verdict."""

    axis: str
    quantity: str
    verdict: str
    set_rate_dps: float | None = None


class ResultView(msgspec.Struct, frozen=True):
    """What the assessment compares of a result: each entry's figures by where it is
    (`axes.outer.rates[+50 deg/s]`, `drift.axes.x`, `drift`), the conformity statements,
    and the customer its certificate block names."""

    figures: dict[str, dict[str, Figure]]
    outcomes: tuple[Outcome, ...]
    customer: Customer | None

    def verdicts(self) -> dict[tuple[str, float | None, str], str]:
        """Each statement's verdict by (axis, rate, quantity)."""
        return {(c.axis, c.set_rate_dps, c.quantity): c.verdict for c in self.outcomes}


Entry = dict[str, msgspec.Raw]


class _Axis(msgspec.Struct, frozen=True):
    rates: tuple[Entry, ...] = ()
    pairs: tuple[Entry, ...] = ()


class _Certificate(msgspec.Struct, frozen=True):
    customer: str | None = None
    customer_address: str | None = None
    customer_contact: str | None = None


class _Result(msgspec.Struct, frozen=True):
    checks: tuple[Outcome, ...] = ()
    axes: dict[str, _Axis] = {}
    drift: Entry | None = None
    certificate: _Certificate | None = None


def _number(raw: msgspec.Raw | None) -> float | None:
    """A finite number, None for anything else (null, text, a container)."""
    if raw is None:
        return None
    try:
        x = msgspec.json.decode(raw, type=float)
    except (msgspec.ValidationError, msgspec.DecodeError):
        return None
    return x if math.isfinite(x) else None


def figures_of(entry: Entry) -> dict[str, tuple[float, float, str]]:
    """An entry's figures that state a U beside them: name: (value, U, unit)."""
    out: dict[str, tuple[float, float, str]] = {}
    for key, u in entry.items():
        if "_U_" in key:
            name, unit = key.replace("_U_", "_", 1), key.split("_U_", 1)[1]
        elif key.endswith("_U"):
            name, unit = key[:-2], ""
        else:
            continue
        value, big_u = _number(entry.get(name)), _number(u)
        if value is not None and big_u is not None and big_u > 0:
            out[name] = (value, big_u, UNITS.get(unit, unit))
    return out


def _rate(entry: Entry, key: str, path: str) -> float:
    rate = _number(entry.get(key))
    if rate is None:
        raise MalformedDocument(f"{layout.RESULT} {path}.{key}: expected a number")
    return rate


def _entries(doc: _Result) -> dict[str, Entry]:
    """Each rate and pair entry of a result by where it is."""
    out: dict[str, Entry] = {}
    for axis, a in doc.axes.items():
        for i, r in enumerate(a.rates):
            rate = _rate(r, "set_rate_dps", f"axes.{axis}.rates[{i}]")
            out[f"axes.{axis}.rates[{rate:+g} deg/s]"] = r
        for i, p in enumerate(a.pairs):
            out[f"axes.{axis}.pairs[{_rate(p, 'rate_dps', f'axes.{axis}.pairs[{i}]'):g} "
                "deg/s]"] = p
    if doc.drift is not None:      # the drift kind: each gyro's figures, the platform's
        gyros = _decode(bytes(doc.drift["axes"]), dict[str, Entry],
                        f"{layout.RESULT} drift.axes") if "axes" in doc.drift else {}
        for gyro, g in gyros.items():
            out[f"drift.axes.{gyro}"] = g
        out["drift"] = doc.drift
    return out


def result_view(data: str | bytes) -> ResultView:
    """A result.json read for the assessment, or MalformedDocument naming the key path."""
    doc = _decode(data, _Result, layout.RESULT)
    cert = doc.certificate
    customer = Customer(cert.customer or None, cert.customer_address or None,
                        cert.customer_contact or None) if cert else None
    return ResultView({where: {name: Figure(*f) for name, f in figures_of(e).items()}
                       for where, e in _entries(doc).items()}, doc.checks,
                      None if customer is None or customer == Customer() else customer)
