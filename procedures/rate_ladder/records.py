"""What the rate ladder reports outside its certificate: its figures, declared (the
records, `bench history`, the trend plot, the station view read these), read from
result.json, and the cells of its certificate the console summary shows.

The kind's `records` part; bench/kind.py's `RecordsPart`, `SummarisesRun`,
`ChecksInstruments` (the FOG's check values), `HasSampleResult` and `HasStarterFiles` are
the questions it answers.
"""

from __future__ import annotations

import re
from collections.abc import Mapping

from bench.analysis.finite import finite_number as _num
from bench.analysis.random_part import std_u_rel
from bench.core.yamlfile import YamlValue
from bench.kind import SerialOf
from bench.report.certificate.model import Document, Table
from bench.report.figures import (
    FigureSpec,
    FigureValue,
    InstrumentCheck,
    SummaryCut,
    Trend,
    joined,
    tables_of,
)
from bench.report.result_frame import ResultFrame
from bench.report.sample_result import SampleResult
from procedures.rate_ladder import starter
from procedures.rate_ladder.axes_view import AxisRows, axes_of
from procedures.rate_ladder.codec import axes_in
from procedures.rate_ladder.sample import rate_ladder_result

_RATES = "axes.<axis>.rates[]."
_PAIRS = "axes.<axis>.pairs[]."
_RATE = "set_rate_dps"      # a rate entry's key: the signed set rate
_PAIR = "rate_dps"          # a pair entry's key: its magnitude

#: the ladder's figures, per signed set rate (CONTRACT §3) and per +/- pair
FIGURES = (
    FigureSpec("rate_error_rel", "rate error", "1",
               "(mean - set) / set from the counter's whole turns (docs/method.md A1, eq. 1)",
               _RATES + "rate_error_rel", "rate_error_u_rel", check="rate_error",
               shown_unit="ppm", scale=1e6, trend=Trend("sym", label="rate error δ, ppm"),
               listed=True, compared="rate error δ", rate_key=_RATE),
    FigureSpec("rate_instability_rel", "instability", "1",
               "relative std of the per-turn rates (eq. 2); an upper limit where not "
               "resolved above the counter's timing floor",
               _RATES + "rate_instability_rel", "rate_instability_u_rel",
               check="rate_instability", shown_unit="ppm", scale=1e6,
               trend=Trend("upper", label="per-turn instability σ, ppm"), listed=True,
               compared="per-turn instability σ", rate_key=_RATE),
    FigureSpec("intra_turn_instability_rel", "intra-turn instability", "1",
               "std of the random part of the FOG's rate within a turn / |set| (A2)",
               _RATES + "intra_turn_instability_rel", "intra_turn_instability_u_rel",
               check="intra_turn_instability", shown_unit="%", scale=100.0, rate_key=_RATE),
    FigureSpec("intra_turn_instability_corrected_rel", "intra-turn instability, floor-"
               "corrected", "1", "the same with the FOG's noise floor removed (A2)",
               _RATES + "intra_turn_instability_corrected_rel",
               check="intra_turn_instability_corrected", shown_unit="%", scale=100.0,
               rate_key=_RATE),
    FigureSpec("harmonic<order>_amplitude_rel", "harmonic amplitude", "1",
               "amplitude of the once-per-rev harmonic of that order / |set| (A2)",
               _RATES + "systematic.harmonics[].amplitude_rel", "amplitude_u_rel",
               shown_unit="ppm", scale=1e6, rate_key=_RATE),
    FigureSpec("mains_amplitude_dps", "mains ripple amplitude", "deg/s",
               "the rate ripple at the mains frequency (A2)",
               _RATES + "systematic.mains.amplitude_dps", "amplitude_u_dps", rate_key=_RATE),
    FigureSpec("k", "FOG scale k", "1", "FOG scale against the counter per +/- pair (A3, "
               "eq. 5)", _PAIRS + "k", "k_u", shown_unit="ppm", scale=1e6,
               trend=Trend("", offset=1.0, label="FOG scale k − 1, ppm (METHOD A3)"),
               rate_key=_PAIR, rate_is_magnitude=True),
    FigureSpec("w0_dps", "FOG bias w0", "deg/s", "FOG bias per +/- pair (A3, eq. 6)",
               _PAIRS + "w0_dps", "w0_u_dps", trend=Trend("", label="FOG bias w0, deg/s"),
               rate_key=_PAIR, rate_is_magnitude=True),
)

#: the FOG's check values, their unit and what the control chart calls them
#: (`ChecksInstruments.check_quantities`)
CHECK_QUANTITIES: dict[str, tuple[str, str]] = {
    "k": ("1", "FOG scale k (eq. 5)"),
    "w0_dps": ("deg/s", "FOG bias w0 (eq. 6)"),
    "noise_floor_dps": ("deg/s", "FOG noise floor at rest, std"),
    "bias_at_rest_dps": ("deg/s", "FOG bias at rest, mean of the static record"),
}

# the console summary: (caption after "Axis <name>: ", header prefix, header shown)
LADDER_COLUMNS = (
    ("per-turn rate error", "Set rate", None),
    ("per-turn rate error", "Turns", None),
    ("per-turn rate error", "Rate error", None),
    ("per-turn rate error", "Instability", None),
    ("intra-turn instability", "Raw ± U", "Intra-turn raw ± U"),
    ("intra-turn instability", "Floor-corrected", None),
    ("per-turn rate error", "Verdict", None),
)
PAIR_COLUMNS = (
    ("FOG cross-calibration", "Pair", None),
    ("FOG cross-calibration", "k ± U", None),
    ("FOG cross-calibration", "ω0 ± U, °/s", None),
)


def _value(axis: str, quantity: str, rate: float | None, value: float | None, u: float | None,
           unit: str, check: str | None = None, upper_limit: bool = False) -> FigureValue | None:
    v = _num(value)
    return None if v is None else FigureValue(axis, quantity, rate, v, _num(u), unit, check,
                                              upper_limit)


def _axis_tables(doc: Document) -> dict[str, dict[str, Table]]:
    """Per axis, its certificate tables keyed by caption (the text after 'Axis <name>: ')."""
    out: dict[str, dict[str, Table]] = {}
    for t in tables_of(doc):
        m = re.match(r"Axis (\S+): (.*)", t.caption)
        if m:
            out.setdefault(m.group(1), {})[m.group(2)] = t
    return out


def _fog_checks(axis: str, axis_rows: AxisRows, serial: str, model: str | None
                ) -> list[InstrumentCheck]:
    """One axis's FOG check values: k and w0 per pair's |rate|; the std of the static
    record with the U of a std from its samples (chi-square, normal data), and its mean,
    whose standard uncertainty is no more than the Allan deviation at the longest
    averaging time computed (white and flicker noise: sigma_A(tau) falls or stays flat
    as tau grows), docs/method.md C1."""
    out = []

    def add(q: str, rate: float | None, v: float | None, u: float | None) -> None:
        x = _num(v)
        if x is not None:
            out.append(InstrumentCheck(serial, "fog", model, axis, q, rate, x, _num(u),
                                       CHECK_QUANTITIES[q][0]))

    for pair_entry in axis_rows.pairs:
        rate = abs(pair_entry.rate_dps)
        add("k", rate, pair_entry.k, pair_entry.k_U)
        add("w0_dps", rate, pair_entry.w0_dps, pair_entry.w0_U_dps)
    at_rest = axis_rows.noise_floor
    if at_rest is not None:
        std = _num(at_rest.sample_std_dps)
        if std is not None:
            add("noise_floor_dps", None, std, std_u_rel(std, at_rest.samples or 0))
        adev = [x for x in at_rest.allan_dev_dps if x]
        add("bias_at_rest_dps", None, at_rest.mean_dps, 2.0 * adev[-1] if adev else None)
    return out


class LadderRecords:
    """The ladder's answers to the records part (`RecordsPart`), `SummarisesRun`,
    `ChecksInstruments`, `HasSampleResult` and `HasStarterFiles` (bench/kind.py)."""

    figures = FIGURES

    check_quantities = CHECK_QUANTITIES

    def instrument_checks(self, frame: ResultFrame, stand: Mapping[str, YamlValue],
                          serial_of: SerialOf) -> list[InstrumentCheck]:
        """Each axis's FOG, as the run measured it: k and w0 per |rate| (eq. 5-6), its
        noise floor and bias at rest (docs/method.md C1), by the FOG's serial."""
        axes = axes_of(frame)
        stand_axes = stand.get("axes")
        out: list[InstrumentCheck] = []
        for axis, conf in (stand_axes.items() if isinstance(stand_axes, Mapping) else ()):
            fog = conf.get("fog") if isinstance(conf, Mapping) else None
            rows = axes.get(axis)
            if isinstance(fog, Mapping) and rows is not None:
                model = fog.get("model")
                out += _fog_checks(axis, rows, serial_of(axis, "fog", fog),
                                   None if model in (None, "") else str(model))
        return out

    def figure_values(self, frame: ResultFrame) -> list[FigureValue]:
        out: list[FigureValue | None] = []
        for axis, ax in axes_in(frame).items():
            for r in ax.rates:
                rate = _num(r.set_rate_dps)
                out.append(_value(axis, "rate_error_rel", rate, r.rate_error_rel,
                                  r.rate_error_u_rel, "1", "rate_error"))
                if r.rate_instability_resolved is False:
                    # not resolved above the counter's timing floor: the records keep what
                    # the certificate prints, the one-sided upper limit, with no U (the one
                    # rule for unresolved figures, docs/certificate.md)
                    out.append(_value(axis, "rate_instability_rel", rate,
                                      r.rate_instability_upper_rel, None, "1",
                                      "rate_instability", upper_limit=True))
                else:
                    out.append(_value(axis, "rate_instability_rel", rate,
                                      r.rate_instability_rel, r.rate_instability_u_rel, "1",
                                      "rate_instability"))
                out.append(_value(axis, "intra_turn_instability_rel", rate,
                                  r.intra_turn_instability_rel, r.intra_turn_instability_u_rel,
                                  "1", "intra_turn_instability"))
                out.append(_value(axis, "intra_turn_instability_corrected_rel", rate,
                                  r.intra_turn_instability_corrected_rel, None, "1",
                                  "intra_turn_instability_corrected"))
                for h in r.harmonics:
                    out.append(_value(axis, f"harmonic{h.order}_amplitude_rel", rate,
                                      h.amplitude_rel, h.amplitude_u_rel, "1"))
                mains = r.mains
                out.append(_value(axis, "mains_amplitude_dps", rate,
                                  mains.amplitude_dps if mains else None,
                                  mains.amplitude_u_dps if mains else None, "deg/s"))
            for p in ax.pairs:
                rate = _num(p.rate_dps)
                out.append(_value(axis, "k", rate, p.k, p.k_u, "1"))
                out.append(_value(axis, "w0_dps", rate, p.w0_dps, p.w0_u_dps, "deg/s"))
        return [f for f in out if f is not None]

    def starter_files(self, real: bool) -> dict[str, str]:
        """`bench init`'s stand and procedure (starter.py)."""
        return starter.starter_files(real)

    def sample_result(self) -> SampleResult:
        """A hand-made result for previews of the certificate (sample.py)."""
        return rate_ladder_result()

    def summary_cut(self, doc: Document) -> SummaryCut:
        """Per axis: the per-turn and intra-turn tables joined on the rate, and the FOG's
        cross-calibration per pair."""
        tables: list[Table] = []
        for axis, by_caption in _axis_tables(doc).items():
            def find(caption: str, mine: dict[str, Table] = by_caption) -> Table | None:
                return next((t for c, t in mine.items() if c.startswith(caption)), None)
            for title, columns in ((f"Axis {axis}", LADDER_COLUMNS),
                                   (f"Axis {axis}, FOG cross-calibration per ± pair",
                                    PAIR_COLUMNS)):
                t = joined(title, [(find(c), p, s) for c, p, s in columns])
                if t is not None and t.rows:
                    tables.append(t)
        return SummaryCut(tuple(tables))
