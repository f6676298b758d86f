"""What the drift-pulse kind reports outside its certificate: its figures, declared (the
records, `bench history`, the trend plot, the station view read them at these paths),
its gyros' own drift as check values of the gyros (measurement assurance), and the
cells of its certificate the console summary shows.

The kind's `records` part; bench/kind.py's `RecordsPart`, `ChecksInstruments`,
`SummarisesRun` and `HasSampleResult` are the questions it answers.
"""

from __future__ import annotations

from collections.abc import Mapping

from bench.analysis.finite import finite_number as _num
from bench.core.yamlfile import YamlValue
from bench.kind import SerialOf
from bench.report.certificate.model import Document, Table
from bench.report.figures import (
    DeclaredFigures,
    FigureSpec,
    InstrumentCheck,
    SummaryCut,
    Trend,
    column,
    fields_of,
    tables_of,
)
from bench.report.result_frame import ResultFrame
from bench.report.sample_result import SampleResult
from procedures.drift_pulse.codec import MalformedResult, drift_in
from procedures.drift_pulse.sample import drift_pulse_result

#: CONTRACT §3's binding keys of a drift-pulse result, per gyro and for the platform
FIGURES = (
    FigureSpec("own_drift_dph", "own drift", "deg/h",
               "the gyro's own drift, from the positions' mean (docs/method.md B)",
               "drift.axes.<axis>.own_dph", "own_u_dph", check="own_drift",
               trend=Trend("sym"), listed=True, compared="own drift"),
    FigureSpec("apparent_drift_dph", "apparent drift", "deg/h",
               "the apparent drift at position 0 (the Earth's rate on the input axis, B)",
               "drift.axes.<axis>.apparent_dph", "apparent_u_dph", check="apparent_drift",
               trend=Trend(""), listed=True),
    FigureSpec("azimuth_deg", "platform azimuth", "deg",
               "the X input axis's azimuth from two horizontal axes (B)",
               "drift.azimuth_deg", "azimuth_u_deg", axis="platform"),
)

DRIFT_CAPTION = "Own and apparent drift per axis"
DRIFT_HEADERS = ("Axis", "Own drift", "Apparent drift")
AZIMUTH_FIELD = "Platform azimuth"


def _block(x: YamlValue | None) -> Mapping[str, YamlValue]:
    """A block of the stand file, or nothing when it is not one."""
    return x if isinstance(x, Mapping) else {}


def _opt(x: YamlValue | None) -> str | None:
    return None if x in (None, "") else str(x)


class DriftRecords(DeclaredFigures):
    """The drift-pulse kind's answers to `RecordsPart`, `ChecksInstruments` and
    `SummarisesRun`."""

    figures = FIGURES
    check_quantities = {"own_drift_dph": ("deg/h", "drift platform's own drift")}

    def instrument_checks(self, frame: ResultFrame, stand: Mapping[str, YamlValue],
                          serial_of: SerialOf) -> list[InstrumentCheck]:
        """Each gyro's own drift, by the gyro's serial (the stand file's
        `platform.gyros.<gyro>.serial`, else PLATFORM-SERIAL/gyro: a gyro is no axis
        instrument, so `serial_of`, which places by axis and role, is not asked)."""
        try:
            drift = drift_in(frame)
        except MalformedResult:
            return []   # no figures to take check values from (its certificate refuses it)
        platform = _block(stand.get("platform"))
        gyros = _block(platform.get("gyros"))
        # the stand's serial as the run reported it, else as its stand file states it
        stated = frame.stand.get("serial")
        ident = stated if stated is not None else _block(stand.get("stand")).get("serial")
        plat = _block(platform.get("identity")).get("serial") or ident or "stand"
        out = []
        for g, ax in drift.axes.items():
            conf = _block(gyros.get(g))
            v = _num(ax.own_dph)
            if v is not None:
                out.append(InstrumentCheck(_opt(conf.get("serial")) or f"{plat}/{g}", "gyro",
                                           _opt(conf.get("model")), g, "own_drift_dph", None,
                                           v, _num(ax.own_U_dph), "deg/h"))
        return out

    def sample_result(self) -> SampleResult:
        """A hand-made result for previews of the certificate (sample.py)."""
        return drift_pulse_result()

    def summary_cut(self, doc: Document) -> SummaryCut:
        """Own and apparent drift per gyro, and the platform azimuth."""
        tables: list[Table] = []
        drift = next((t for t in tables_of(doc) if t.caption.startswith(DRIFT_CAPTION)),
                     None)
        if drift is not None:
            idx = [i for p in DRIFT_HEADERS for i in (column(drift, p),) if i is not None]
            tables.append(Table(tuple(drift.header[i] for i in idx),
                                tuple(tuple(r[i] for i in idx) for r in drift.rows),
                                align="".join(drift.align[i] if i < len(drift.align)
                                              else "r" for i in idx), caption="Drift"))
        fields = tuple((k, v) for k, v in fields_of(doc).items()
                       if k.startswith(AZIMUTH_FIELD))
        return SummaryCut(tuple(tables), fields)
