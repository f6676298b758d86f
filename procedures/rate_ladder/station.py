"""The ladder's results on the station's pages (the kind's `station` part, bench/kind.py
`StationPart`): the first look per pair as it comes, and result.json's rates and pairs
per axis, worded and rounded as the certificate prints them (bench/report/station.py).
"""

from __future__ import annotations

from collections.abc import Sequence

from bench.core.events import LiveRow
from bench.report.certificate.parts import verdict_label
from bench.report.certificate.rounding import format_sig, present_std
from bench.report.result_frame import ResultFrame
from bench.report.station import (
    PageTable,
    StationParts,
    column_unit,
    number,
    page_table,
    rate_text,
    value_u,
)
from procedures.rate_ladder.axes_view import PairRow, RateRow, axes_of
from procedures.rate_ladder.events import ResultRow

LIVE_CAPTION = ("Results as they come (first look per pair; the certificate is computed "
                "again from the raw data)")


def _rates_table(axis: str, rates: Sequence[RateRow]) -> PageTable:
    """Each rate's error and instability with U and verdict (docs/method.md A1, D2)."""
    err = column_unit(*[r.rate_error_rel for r in rates],
                      *[r.rate_error_U_rel for r in rates])
    sig = column_unit(*[r.rate_instability_rel for r in rates],
                      *[r.rate_instability_upper_rel for r in rates])
    rows = []
    for r in rates:
        # docs/method.md D2, as the certificate prints it: the chi-square interval when
        # resolved above the timing floor, else '< L'
        sigma = present_std(number(r.rate_instability_rel), number(r.rate_instability_U_rel),
                            sig.scale, lower=number(r.rate_instability_lower_rel),
                            upper=number(r.rate_instability_upper_rel),
                            floor=number(r.rate_instability_floor_rel),
                            resolved=r.rate_instability_resolved)
        rows.append(([rate_text(r.set_rate_dps), "-" if r.turns is None else str(r.turns),
                      value_u(r.rate_error_rel, r.rate_error_U_rel, err.scale, signed=True),
                      sigma.text, verdict_label(r.verdict) if r.verdict else "-"],
                     str(r.verdict or "")))
    return page_table(f"rates-{axis}", f"Axis {axis}: rate error and instability per set rate",
                      ("set rate, deg/s", "turns", f"rate error δ ± U, {err.name}",
                       f"instability σ [interval] or < L, {sig.name}", "verdict"), rows)


def _pairs_table(axis: str, pairs: Sequence[PairRow]) -> PageTable:
    """Each ± pair's FOG scale factor k and bias ω0 with U (docs/method.md A3)."""
    rows = [([f"±{number(p.rate_dps) or 0:g}", value_u(p.k, p.k_U),
              value_u(p.w0_dps, p.w0_U_dps, signed=True)], "") for p in pairs]
    return page_table(f"pairs-{axis}",
                      f"Axis {axis}: FOG cross-calibration per ± pair (scale factor k, bias ω0)",
                      ("pair, deg/s", "k ± U", "ω0 ± U, deg/s"), rows)


def _ladder_row(row: LiveRow) -> ResultRow:
    """A live row of a ladder run is the ladder's own (`PairLooked.live_rows`); another
    kind's row here is the station asking the wrong kind, not data to guess at."""
    if not isinstance(row, ResultRow):
        raise TypeError(f"not a rate ladder row: {type(row).__name__}")
    return row


class LadderStation(StationParts):
    """The ladder's tables for the run pages and the lab's list of benches."""

    def live_table(self, rows: Sequence[LiveRow]) -> PageTable | None:
        """The first look per pair, from the `pair` events (`PairLooked.rows`): k and w0
        with their U, each direction's rate error with its U."""
        looked = [_ladder_row(row) for row in rows]
        if not looked:
            return None
        unit = column_unit(*[r.rate_error_rel for r in looked],
                           *[r.rate_error_U_rel for r in looked])
        sunit = column_unit(*[r.rate_instability_rel for r in looked])
        out = []
        for r in looked:
            sigma = number(r.rate_instability_rel)
            out.append(([r.axis or "-", rate_text(r.set_rate_dps), value_u(r.k, r.k_U),
                         value_u(r.w0_dps, r.w0_U_dps, signed=True),
                         value_u(r.rate_error_rel, r.rate_error_U_rel, unit.scale,
                                 signed=True),
                         "-" if sigma is None else format_sig(sigma * sunit.scale, 2),
                         "-" if r.turns is None else str(r.turns),
                         verdict_label(r.verdict) if r.verdict else "-"],
                        r.verdict or ""))
        return page_table("results-live", LIVE_CAPTION,
                          ("axis", "set rate, deg/s", "k ± U", "ω0 ± U, deg/s",
                           f"rate error δ ± U, {unit.name}",
                           f"instability σ, {sunit.name} (first look; U in the final results)",
                           "turns", "verdict"), out)

    def last_look(self, row: LiveRow) -> str | None:
        """'<axis> <rate> deg/s: rate error δ ± U ppm' of the newest direction looked at."""
        r = _ladder_row(row)
        error = value_u(r.rate_error_rel, r.rate_error_U_rel, 1e6, signed=True)
        return f"{r.axis} {rate_text(r.set_rate_dps)} deg/s: rate error {error} ppm"

    def result_tables(self, frame: ResultFrame) -> list[PageTable]:
        """Per axis (CONTRACT §3's `axes.<axis>.rates[]` and `pairs[]`): each rate's error
        and instability with U and verdict, then each ± pair's FOG scale factor k and bias
        ω0 with U."""
        tables: list[PageTable] = []
        for axis, body in axes_of(frame).items():
            if body.rates:
                tables.append(_rates_table(axis, body.rates))
            if body.pairs:
                tables.append(_pairs_table(axis, body.pairs))
        return tables

    def result_rows(self, frame: ResultFrame) -> list[LiveRow]:
        """Per axis and rate the figures the certificate prints (rate error +/- U,
        instability, verdict) with the pair's k and w0."""
        rows: list[LiveRow] = []
        for axis, body in axes_of(frame).items():
            by_rate = {entry.rate_dps: entry for entry in body.pairs}
            for r in body.rates:
                p = by_rate.get(abs(r.set_rate_dps))
                rows.append(ResultRow(
                    axis=axis, set_rate_dps=r.set_rate_dps, k=p.k if p else None,
                    k_U=p.k_U if p else None, w0_dps=p.w0_dps if p else None,
                    w0_U_dps=p.w0_U_dps if p else None, rate_error_rel=r.rate_error_rel,
                    rate_error_U_rel=r.rate_error_U_rel,
                    rate_instability_rel=r.rate_instability_rel, turns=r.turns,
                    verdict=r.verdict))
        return rows
