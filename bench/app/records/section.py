"""The certificate's history section: the table's earlier certificates and the trend.

A certificate read alone says whether the table is in tolerance today; with its history it
also says whether it is drifting towards the limit, and whether it was adjusted (the
as-found and as-left results side by side).
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Sequence

from bench.app.records.extract import FigureRecord, RunRecord
from bench.app.records.store import Records, RunInfo, TrendPoint
from bench.kind import declared_figures
from bench.report.certificate.model import Block, Fields, Figure, Para, Table
from bench.report.certificate.rounding import format_value_u
from bench.report.figures import FigureSpec, spec_for

TITLE = "History of this table"


def _vu(f: FigureRecord | None, scale: float) -> str:
    if f is None:
        return "—"
    r = format_value_u(f.value, f.u, scale, signed=True)
    return r.value if r.u is None else f"{r.value} ± {r.u}"


def _date(r: RunInfo) -> str:
    return r.date_utc.strftime("%Y-%m-%d %H:%M UTC") if r.date_utc else "not recorded"


def _earlier(rec: Records, current: RunRecord) -> list[RunInfo]:
    mine = current.date_utc
    return [r for r in rec.runs(current.serial) if r.uid != current.uid and (
        mine is None or r.date_utc is None or r.date_utc.replace(tzinfo=None) <= mine)]


def _as_found(earlier: list[RunInfo]) -> RunInfo | None:
    """The as-found run this as-left run follows: the latest as-found since the last
    run that was not as-found (a plain or as-left run closes the previous cycle)."""
    last = earlier[-1] if earlier else None
    return last if last is not None and last.calibration_state == "as-found" else None


def _comparison(rec: Records, found: RunInfo, current: RunRecord,
                figures: Sequence[FigureSpec]) -> Table:
    """The figures the kind compares (`FigureSpec.compared`), as found and as left."""
    before = {(f.axis, f.quantity, f.set_rate_dps): f for f in rec.figures(found.uid)}
    rows = []
    for f in current.figures:
        spec = spec_for(f.quantity, figures)
        if spec is None or not spec.compared:
            continue
        name, scale, unit = spec.compared, spec.scale, spec.shown
        rate = "" if f.set_rate_dps is None else f"{f.set_rate_dps:+g}"
        rows.append((f.axis, rate, f"{name}, {unit}",
                     _vu(before.get((f.axis, f.quantity, f.set_rate_dps)), scale),
                     _vu(f, scale)))
    return Table(("Axis", "Rate, deg/s", "Quantity", "As found ± U", "As left ± U"),
                 tuple(rows), widths=(1.0, 1.0, 2.4, 2.0, 2.0), align="lrlrr",
                 caption=f"As found (certificate {found.certificate_number}, {_date(found)}) "
                         f"and as left (this certificate); U with k = 2")


def history_section(rec: Records, current: RunRecord, where: str
                    ) -> list[tuple[str, tuple[Block, ...]]]:
    """[(title, blocks)] for the certificate; [] when the records hold no earlier run."""
    earlier = _earlier(rec, current)
    blocks: list[Block] = []
    if current.calibration_state:
        state = [("Calibration state of this run", current.calibration_state)]
        if current.adjustment_note:
            state.append(("Adjustment", current.adjustment_note))
        blocks.append(Fields(tuple(state)))
    if not earlier:
        return [(TITLE, tuple(blocks))] if blocks else []
    prev = earlier[-1]
    blocks.append(Para(
        f"The laboratory's records ({where}) hold {len(earlier)} earlier run(s) of table "
        f"serial {current.serial}. The previous run, its certificate if one was issued, and "
        f"the digests by which the issued files can be checked:"))
    rows = [("Previous certificate number", prev.certificate_number or
             "none issued (the previous run has a draft only, which is cited nowhere)"),
            ("Its date", _date(prev)),
            ("Its verdict", prev.verdict.upper()),
            ("Its calibration state", prev.calibration_state or "not stated")]
    rows += [(f"SHA-256 of its {name}", digest) for name, digest in sorted(
        prev.cert_files.items())]
    blocks.append(Fields(tuple(rows)))
    figures = declared_figures([current.kind, *(r.kind for r in earlier)])
    found = _as_found(earlier) if current.calibration_state == "as-left" else None
    if found is not None:
        blocks.append(_comparison(rec, found, current, figures))
    shown = {r.uid for r in earlier}
    points = [p for p in rec.trend(current.serial) if p.run_uid in shown] + [
        TrendPoint(current.uid, _aware(current), current.certificate_number,
                   current.calibration_state, f) for f in current.figures]
    # matplotlib only here, with an earlier run to plot: a table's first run (and the
    # demo's every run in a fresh folder) never loads it for the records (issue 62)
    from bench.app.records.trend import trend_png

    png = trend_png(points, f"Table {current.serial}: trend across recertifications", figures)
    if png is not None:
        blocks.append(Figure(png, "Trend across recertifications: each recorded run of this "
                                  "table (this one last), with U (k = 2) bars and the "
                                  "tolerance band"))
    blocks.append(Table(
        ("Date", "Certificate", "State", "Verdict", "Run directory"),
        tuple((_date(r), r.certificate_number or "—", r.calibration_state or "—",
               r.verdict.upper(), r.run_dir) for r in earlier),
        widths=(1.8, 2.2, 1.0, 1.0, 2.6), align="lllll", caption="Earlier runs of this table"))
    return [(TITLE, tuple(blocks))]


def _aware(current: RunRecord) -> dt.datetime | None:
    d = current.date_utc
    return None if d is None else d.replace(tzinfo=dt.UTC)
