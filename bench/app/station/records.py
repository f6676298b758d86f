"""The records half of the station view: tables, their runs, due dates and trends.

Read through the lab's records database (bench.app.records' read API), the one place where
every run of a table is registered. The view never creates or migrates a database: an
SQLite file that does not exist yet is shown as "no records yet", with the command that
makes it.
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from bench.app.db import away_text
from bench.app.records import Records, RecordsError, target
from bench.app.records.control import OUT_OF_CONTROL, all_statuses, instrument_status
from bench.app.records.control_plot import control_png
from bench.app.records.extract import figures_of, kind_name
from bench.app.records.store import DueItem
from bench.app.records.trend import trend_png
from bench.app.station.drafts import Draft, drafts
from bench.app.station.live import DOWNLOADS
from bench.core import rundir_layout as layout
from bench.kind import declared_figures
from bench.report.certificate.sources import read_frame
from bench.report.figures import spec_for
from bench.report.result_frame import ResultFrame
from drivers.json_types import JsonLike


def _iso(t: dt.datetime | dt.date | None) -> str | None:
    return None if t is None else t.isoformat()


def run_figures(run_path: Path) -> dict[str, JsonLike]:
    """A finished run's figures, read by its procedure kind from result.json (the rows
    the records keep) with the words and units the kind declares; none before the end."""
    frame = read_frame(run_path / layout.RESULT)
    if frame is not None and not frame.doc:
        frame = None
    kind = kind_name(frame, run_path) if frame is not None else ""
    specs = declared_figures([kind]) if kind else ()
    rows: list[JsonLike] = []
    for f in figures_of(frame, kind) if frame is not None else []:
        spec = spec_for(f.quantity, specs)
        rows.append({"axis": f.axis, "quantity": f.quantity, "set_rate_dps": f.set_rate_dps,
                     "value": f.value, "U": f.u, "unit": f.unit,
                     "name": spec.name if spec else f.quantity,
                     "description": spec.description if spec else "",
                     "tolerance": f.tolerance, "verdict": f.verdict,
                     "upper_limit": f.is_limit})
    return {"run": run_path.name, "procedure": kind or None,
            "verdict": ResultFrame.conform(frame.doc)[0].verdict if frame is not None else None,
            "figures": rows}


class RecordsView:
    """Tables and histories for the pages. Each call opens the database and closes it, so
    a database that goes away (a lab server restarted) costs one page, not the server."""

    def __init__(self, runs: Path, records_url: str | None = None) -> None:
        self.runs = runs
        self.where = target(runs, records_url, warn=lambda text: None)
        self.error: str | None = None

    @property
    def url(self) -> str:
        url: str = self.where.url
        return url

    def _absent(self) -> bool:
        """A default SQLite file not made yet: nothing recorded, and nothing to create."""
        if not self.url.startswith("sqlite:///"):
            return False
        return not Path(self.url.removeprefix("sqlite:///")).exists()

    @contextmanager
    def _open(self) -> Iterator[Records | None]:
        self.error = None
        if self._absent():
            self.error = (f"no records database yet ({self.url}); runs register when they "
                          f"end, or `bench records import {self.runs}`")
            yield None
            return
        try:
            rec = Records.open(self.url)
        except RecordsError as e:
            self.error = str(e)
            yield None
            return
        try:
            yield rec
        finally:
            rec.close()

    def _due(self, rec: Records) -> dict[str, DueItem]:
        return {d.table.serial: d for d in rec.due(intervals=self.where.interval_for,
                                                   everything=True)}

    def tables(self) -> list[dict[str, JsonLike]]:
        with self._open() as rec:
            if rec is None:
                return []
            due = self._due(rec)
            out = []
            for t in rec.tables():
                d = due.get(t.serial)
                runs = rec.runs(t.serial)
                out.append({"serial": t.serial, "maker": t.maker, "model": t.model,
                            "runs": t.runs, "last_date_utc": _iso(t.last_run_utc),
                            "last_verdict": runs[-1].verdict if runs else None,
                            "last_certificate": t.last_certificate,
                            "due_utc": _iso(d.due_date) if d else None,
                            "due_status": d.status if d else "no interval set",
                            "overdue": bool(d and d.days_left is not None and d.days_left < 0)})
            return out

    def due_list(self, within_days: int = 30) -> list[dict[str, JsonLike]]:
        """Tables due within `within_days` or overdue (bench due), for the lab page."""
        with self._open() as rec:
            if rec is None:
                return []
            items = rec.due(within_days=within_days, intervals=self.where.interval_for)
        return [{"serial": d.table.serial,
                 "table": " ".join(x for x in (d.table.maker, d.table.model) if x),
                 "last_pass": d.table.last_pass_utc.date().isoformat()
                 if d.table.last_pass_utc else None,
                 "due": _iso(d.due_date), "status": d.status,
                 "overdue": d.days_left is not None and d.days_left < 0} for d in items]

    def lab_drafts(self, limit: int = 50, simulated: bool = False) -> list[Draft] | None:
        """Every bench's drafts (drafts.py), newest first; None when the records cannot be
        read now (the page says it does not know, never "no draft")."""
        with self._open() as rec:
            if rec is None:
                return [] if self._absent() else None
            try:
                return drafts(rec.engine, limit, simulated)
            except Exception as e:  # noqa: BLE001 - the server away: the page says so
                self.error = away_text(self.url, e)
                return None

    def lab_instruments(self, register_url: str | None, serials: list[str]
                        ) -> tuple[list[dict[str, JsonLike]], list[str]]:
        """The benches' instruments (`serials`) with their control status (the records'
        charts), and every item of the lab register's inventory with its calibration (due
        date, overdue without a deviation in force); with the notes of what could not be
        read. Only the benches' own instruments are charted here: a lab's history holds
        hundreds, and /records lists them all."""
        notes: list[str] = []
        rows: dict[str, dict[str, JsonLike]] = {}
        with self._open() as rec:
            for serial in serials:
                st = instrument_status(rec, serial) if rec is not None else None
                if st is not None:
                    rows[serial] = {"serial": serial, "model": st.model,
                                    "control": st.line or st.state,
                                    "out": st.state == OUT_OF_CONTROL,
                                    "calibration": None, "cal_overdue": False}
        if self.error:
            notes.append(self.error)
        if register_url:
            from bench.app.register import RegisterError
            from bench.app.register.store import Register

            today = dt.datetime.now(dt.UTC).date()
            try:
                with Register.open(register_url, migrate=False) as reg:
                    equipment = reg.equipment()
            except RegisterError as e:
                equipment = []
                notes.append(f"register: {e}")
            for q in equipment:
                row = rows.setdefault(q.serial, {"serial": q.serial, "model": q.model,
                                                 "control": None, "out": False})
                problem = q.problem_on(today)
                cal = q.in_force(today)
                row["calibration"] = (
                    "identity only (no calibration)" if q.identity_only else
                    f"{cal.certificate} ({cal.issuer}), due {cal.due.isoformat()}"
                    if cal else "no calibration in force") + (f": {problem}" if problem else "")
                row["cal_overdue"] = bool(problem)
                row["model"] = row.get("model") or q.model
        else:
            notes.append("no lab register named (--register or --lab): calibration status "
                         "not shown")
        return [rows[k] for k in sorted(rows)], notes

    def history(self, serial: str) -> dict[str, JsonLike] | None:
        with self._open() as rec:
            if rec is None:
                return None
            t = rec.table(serial)
            if t is None:
                return None
            d = self._due(rec).get(serial)
            runs = []
            for r in rec.runs(serial):
                local = self.runs / r.run_dir
                runs.append({"run": r.run_dir, "title": r.title, "procedure": r.kind,
                             "date_utc": _iso(r.date_utc), "verdict": r.verdict,
                             "certificate_number": r.certificate_number,
                             "found_left": r.calibration_state,
                             "adjustment_note": r.adjustment_note,
                             "simulated": r.simulated,
                             "local": (local / layout.EVENTS).is_file(),
                             "files": [n for n in DOWNLOADS if (local / n).is_file()]})
            return {"serial": serial, "maker": t.maker, "model": t.model,
                    "location": t.location, "interval_days": t.interval_days,
                    "due_utc": _iso(d.due_date) if d else None,
                    "due_status": d.status if d else "no interval set",
                    "overdue": bool(d and d.days_left is not None and d.days_left < 0),
                    "runs": runs}

    def trend_png(self, serial: str) -> bytes | None:
        with self._open() as rec:
            if rec is None or rec.table(serial) is None:
                return None
            figures = declared_figures([r.kind for r in rec.runs(serial)])
            return trend_png(rec.trend(serial), f"table {serial}", figures)

    # -- measurement assurance (bench control's statuses and charts) -------------------------
    def instruments(self) -> list[dict[str, JsonLike]]:
        with self._open() as rec:
            if rec is None:
                return []
            return [{"serial": s.serial, "role": s.role, "model": s.model, "state": s.state,
                     "runs": s.runs, "rule": s.rule, "line": s.line,
                     "out": s.state == OUT_OF_CONTROL} for s in all_statuses(rec)]

    def control(self, serial: str) -> dict[str, JsonLike] | None:
        with self._open() as rec:
            if rec is None:
                return None
            st = instrument_status(rec, serial)
            if st is None:
                return None
            series = []
            for s in st.series:
                signals: dict[str, str] = {}
                for g in s.signals:
                    signals[g.run_uid] = "+".join(x for x in (signals.get(g.run_uid), g.rule)
                                                  if x)
                series.append({
                    "label": s.label, "baseline": s.baseline_text, "centre": s.centre,
                    "sigma": s.sigma, "sigma_source": s.sigma_source,
                    "points": [{"date_utc": _iso(p.date_utc), "run": p.run_dir,
                                "value": p.check.value, "u": p.check.u,
                                "ewma": s.ewma[i] if i < len(s.ewma) else None,
                                "signal": signals.get(p.run_uid)}
                               for i, p in enumerate(s.points)]})
            return {"serial": serial, "name": st.name, "state": st.state, "line": st.line,
                    "out": st.state == OUT_OF_CONTROL, "series": series,
                    "reviews": [{"utc": _iso(r.utc), "reviewer": r.reviewer, "text": r.text}
                                for r in st.reviews]}

    def control_png(self, serial: str) -> bytes | None:
        with self._open() as rec:
            st = instrument_status(rec, serial) if rec is not None else None
            return control_png(st) if st is not None else None
