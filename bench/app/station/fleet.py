"""The lab's benches on the station (issue 44): what each bench delivered to the lab's
PostgreSQL database (bench/app/fleet), worded for the pages.

Everything here is read from the database, never from a bench: a bench that disappears
mid-run stays on the page, marked silent with the age of its last event, and a station
with no bench connected shows an empty list. Ages are taken on the lab server's clock
(the deliveries' `received_utc` and `now()`), so the station's own clock does not enter.

`Notifications` follows the deliveries with LISTEN on `bench.app.fleet.CHANNEL`: the
live page is brought up to date when a bench delivers, not on a poll of the tables.
"""

from __future__ import annotations

import datetime as dt
import threading
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Protocol

import sqlalchemy as sa
from sqlalchemy.engine import Engine

from bench.app.db import away_text, engine_url, make_engine
from bench.app.fleet import CHANNEL
from bench.app.fleet.codec import stored_health
from bench.app.records import schema as s
from bench.app.records.extract import figures_of
from bench.app.station.live import ENDINGS, pair_rows, progress_of
from bench.app.station.state import PageState
from bench.app.station.view import (
    _age,
    _utc_text,
    log_line,
    progress_view,
    station_of,
)
from bench.core import events as ev
from bench.core import rundir_layout as layout
from bench.core.events import Event
from bench.core.journal import KILLED, SESSION_LOST
from bench.kind import declared_figures
from bench.report.codec import encode
from bench.report.figures import spec_for
from bench.report.result_frame import ResultFrame
from bench.report.station import rate_text, value_u
from drivers.json_types import JsonLike, JsonValue

#: a running bench delivers every 0.5 s (bench/app/fleet/courier.py); heard nothing for
#: this long, it is shown silent, with its last event's age
SILENT_S = 10.0
#: a FOG or drive raw file not written for this long, while the run runs, is a warning
#: (the same limits as the bench's own station page, live.py)
INSTRUMENT_SILENT_S = 2.0
#: live pages woken by one notification share one reading of the database this long
SHARED_S = 0.25
#: the kind-neutral events a bench's progress is read from, beside those of its log
PROGRESS_EVENTS: tuple[type[Event], ...] = (ev.Planned, ev.StepStarted, ev.StepDone)


def log_kinds() -> tuple[str, ...]:
    """The events a bench's log on its page shows: those each kind declares for the
    station's log (`Event.STATION_LOG`), and the bench's link to the lab."""
    return (*ev.station_log_kinds(), ev.kind_of(ev.LabLink))


def kinds_read() -> tuple[str, ...]:
    """The events a bench's row and page are built from, by tag for the database's query
    (the rest stay in the database)."""
    return (*log_kinds(), *(ev.kind_of(c) for c in PROGRESS_EVENTS), SESSION_LOST)


def _in_log(e: Event) -> bool:
    return e.STATION_LOG or isinstance(e, ev.LabLink)


class Notifications:
    """A counter that grows with each delivery any bench makes (LISTEN), for the live
    pages to wait on. A lost connection to the server is retried every second; while it
    is lost the pages fall back to their periodic refresh."""

    def __init__(self, url: str) -> None:
        self.url = url
        self.version = 0
        self.error: str | None = None
        self._cond = threading.Condition()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._listen, name="fleet-listen", daemon=True)

    def start(self) -> Notifications:
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()

    def wait(self, seen: int, timeout_s: float) -> int:
        """The version once it is past `seen`, or as it is after `timeout_s`."""
        with self._cond:
            self._cond.wait_for(lambda: self.version != seen, timeout=timeout_s)
            return self.version

    def _bump(self) -> None:
        with self._cond:
            self.version += 1
            self._cond.notify_all()

    def _listen(self) -> None:
        import psycopg

        dsn = sa.engine.make_url(engine_url(self.url)).set(
            drivername="postgresql").render_as_string(hide_password=False)
        while not self._stop.is_set():
            try:
                with psycopg.connect(dsn, autocommit=True, connect_timeout=5) as conn:
                    conn.execute(f"LISTEN {CHANNEL}")
                    self.error = None
                    self._bump()          # whatever was delivered while not listening
                    while not self._stop.is_set():
                        for _ in conn.notifies(timeout=1.0):
                            self._bump()
            except Exception as e:  # noqa: BLE001 - the server away: retry, say so
                self.error = away_text(self.url, e)
                self._stop.wait(1.0)


def _naive(stamp: str | None) -> dt.datetime | None:
    if stamp is None:
        return None
    try:
        t = dt.datetime.fromisoformat(stamp)
    except ValueError:
        return None
    return t.astimezone(dt.UTC).replace(tzinfo=None) if t.tzinfo else t


def _iso(t: dt.datetime | None) -> str | None:
    """A naive UTC time from the database as ISO text with its zone."""
    return None if t is None else t.replace(tzinfo=dt.UTC).isoformat()


class BenchRunRow(Protocol):
    """What the pages read of a `bench_runs` row (bench/app/records/schema.py)."""

    @property
    def bench(self) -> str: ...
    @property
    def uid(self) -> str: ...
    @property
    def run_dir(self) -> str: ...
    @property
    def title(self) -> str | None: ...
    @property
    def serial(self) -> str | None: ...
    @property
    def kind(self) -> str | None: ...
    @property
    def simulated(self) -> bool | None: ...
    @property
    def last_seq(self) -> int: ...
    @property
    def last_event_utc(self) -> dt.datetime | None: ...
    @property
    def health(self) -> JsonValue: ...
    @property
    def health_utc(self) -> dt.datetime | None: ...
    @property
    def received_utc(self) -> dt.datetime | None: ...
    @property
    def verdict(self) -> str | None: ...


def _seconds(a: dt.datetime | None, b: dt.datetime | None) -> float | None:
    return None if a is None or b is None else max(0.0, (a - b).total_seconds())


class FleetView:
    """The benches and their runs as the lab database holds them."""

    def __init__(self, url: str, runs: Path | None = None) -> None:
        self.url = url
        self.runs = runs
        self._engine: Engine | None = None
        self._lock = threading.Lock()
        self._cache: tuple[tuple[int, int], dict[str, JsonLike]] | None = None
        self.error: str | None = None

    @property
    def engine(self) -> Engine:
        if self._engine is None:
            self._engine = make_engine(self.url)
        return self._engine

    def _local(self, run_dir: str) -> bool:
        """The run directory is in this station's runs folder (its files can be linked)."""
        return self.runs is not None and (self.runs / run_dir / layout.EVENTS).is_file()

    # -- every bench --------------------------------------------------------------------
    def benches(self, version: int | None = None) -> dict[str, JsonLike]:
        """Each bench with its newest run: status, progress and ETA, health, the last
        result. `version` (Notifications) lets the live pages that wake on one
        notification share one reading (within SHARED_S); without it, a fresh one."""
        with self._lock:
            if version is not None and self._cache is not None \
                    and self._cache[0] == (version, int(time.monotonic() / SHARED_S)):
                return self._cache[1]
        state: dict[str, JsonLike]
        try:
            state = self._benches()
            self.error = None
        except Exception as e:  # noqa: BLE001 - the server away: the page says so
            self.error = away_text(self.url, e)
            state = {"benches": [], "now_utc": None, "error": self.error}
        if version is not None:
            with self._lock:
                self._cache = ((version, int(time.monotonic() / SHARED_S)), state)
        return state

    def _benches(self) -> dict[str, JsonLike]:
        b, r, e = s.benches.c, s.bench_runs.c, s.bench_events.c
        newest = sa.select(sa.func.max(r.id)).group_by(r.bench_id).scalar_subquery()
        with self.engine.connect() as conn:
            now = conn.execute(sa.select(sa.func.timezone("UTC", sa.func.now()))).scalar()
            # every column but the result itself (a result.json is 100 kB of JSON)
            listed = [col for col in s.bench_runs.c if col.name != "result"]
            rows = conn.execute(sa.select(*listed, b.name.label("bench"))
                                .join(s.benches, b.id == r.bench_id)
                                .where(r.id.in_(newest)).order_by(b.name)).all()
            events: dict[int, list[Event]] = {}
            if rows:
                for x in conn.execute(sa.select(e.run_id, e.body)
                                      .where(e.run_id.in_([x.id for x in rows]),
                                             e.event.in_(kinds_read()))
                                      .order_by(e.run_id, e.seq)):
                    events.setdefault(x.run_id, []).append(ev.decode(x.body))
        return {"now_utc": _iso(now), "error": None,
                "benches": [self._run_state(x, events.get(x.id, []), now) for x in rows]}

    def _run_state(self, x: BenchRunRow, events: list[Event], now: dt.datetime | None
                   ) -> dict[str, JsonLike]:
        starts = ev.of_kind(events, ev.SessionStarted)
        session_no = starts[-1].session if starts else None
        session = [e for e in events if e.session == session_no]
        exit_ev = ev.last(session, ev.Exited)
        lost = ev.first(session, ev.SessionLost)
        heard_s = _seconds(now, x.received_utc)
        last_event_s = _seconds(now, x.last_event_utc)
        cause = None
        if exit_ev is not None:
            status = ENDINGS.get(exit_ev.status, "ended")
            if status == "aborted" and not exit_ev.cause:
                status = "incomplete"
            cause = exit_ev.cause
        elif not starts:
            status = "created"
        elif lost is not None:     # its bench found its process gone (bench/app/fleet/lost.py)
            status = "stopped"
            cause = (f"ended: {KILLED} (the bench process is gone without an end; "
                     f"found by `{lost.found_by or 'the bench'}`)")
        else:
            status = "running"
        silent = status in ("running", "created") and heard_s is not None and heard_s > SILENT_S
        prog = progress_of(session)
        view_state = PageState(status=status, progress=prog, cause=cause,
                               sessions=len(starts), session=session_no,
                               ended_utc=exit_ev.utc if exit_ev else (
                                   lost.last_utc if lost else None), later=[])
        health = self._health(x, now, status == "running" and not silent)
        pairs = pair_rows(events)
        last = pairs[-1] if pairs else None
        verdict = x.verdict if status != "running" else None
        looked = station_of(x.kind).last_look(last) if last is not None else None
        if looked is not None:
            last_text = looked
        elif verdict:
            last_text = f"verdict {verdict}"
        else:
            last_text = "-"
        words = progress_view(view_state)
        if silent:
            words = {**words, "line": f"SILENT: nothing heard for {heard_s:.0f} s; last event "
                     f"{_age(last_event_s)} ({words['line']})"}
        return {
            "bench": x.bench, "uid": x.uid, "run": x.run_dir, "title": x.title,
            "serial": x.serial, "kind": x.kind, "simulated": bool(x.simulated),
            "status": "silent" if silent else status, "run_status": status, "cause": cause,
            "seq": int(x.last_seq), "heard_s": heard_s, "last_event_s": last_event_s,
            "last_event_utc": _iso(x.last_event_utc),
            "progress": encode(prog), "words": words, "health": health, "last_result": last_text,
            "verdict": verdict, "local": self._local(x.run_dir),
        }

    def _health(self, x: BenchRunRow, now: dt.datetime | None, live: bool
                ) -> dict[str, JsonLike]:
        """The bench's last health sample, aged to now on the server's clock."""
        sample = stored_health(x.health)
        since = _seconds(now, x.health_utc) if live else 0.0
        rows: list[JsonLike] = []
        warnings: list[JsonLike] = []
        sampled_utc = sample["sampled_utc"] if sample is not None else None
        sampled = _naive(sampled_utc)
        ages = sorted(sample["files"].items()) if sample is not None else []
        for name, age in ages:
            age_now = float(age) + (since or 0.0)
            # a finished run's files are quiet by design: when each was last written
            text = (_age(age_now) if live or sampled is None else
                    (sampled - dt.timedelta(seconds=float(age))).strftime("%Y-%m-%d %H:%M:%S")
                    + " UTC")
            rows.append({"file": name, "age_s": age_now, "text": text})
            instrument = name.rsplit(".", 1)[0]
            if live and instrument.endswith(("-fog", "-drive")) \
                    and age_now > INSTRUMENT_SILENT_S:
                warnings.append(f"{instrument}: not heard for {age_now:.0f} s")
        return {"files": rows, "warnings": warnings, "sampled_utc": sampled_utc}

    def instrument_serials(self) -> list[str]:
        """The instruments of the lab's benches: those with check values in each bench's
        newest run registered in the records (a bench's next run uses the same ones)."""
        br, r, c, i = s.bench_runs.c, s.runs.c, s.checks.c, s.instruments.c
        newest = (sa.select(sa.func.max(br.id)).join(s.runs, r.uid == br.uid)
                  .group_by(br.bench_id).scalar_subquery())
        try:
            with self.engine.connect() as conn:
                return list(conn.execute(
                    sa.select(i.serial).distinct()
                    .join(s.checks, c.instrument_id == i.id)
                    .join(s.runs, r.id == c.run_id)
                    .join(s.bench_runs, br.uid == r.uid)
                    .where(br.id.in_(newest)).order_by(i.serial)).scalars())
        except Exception as e:  # noqa: BLE001 - the page says why the list is empty
            self.error = away_text(self.url, e)
            return []

    # -- one run ------------------------------------------------------------------------
    def run(self, bench: str, uid: str) -> dict[str, JsonLike] | None:
        """One run's page: its state as in the list, the first look per pair, the final
        figures from its result, the milestones and faults; None if the database has no
        such run."""
        b, r, e = s.benches.c, s.bench_runs.c, s.bench_events.c
        with self.engine.connect() as conn:
            now = conn.execute(sa.select(sa.func.timezone("UTC", sa.func.now()))).scalar()
            x = conn.execute(sa.select(s.bench_runs, b.name.label("bench"))
                             .join(s.benches, b.id == r.bench_id)
                             .where(b.name == bench, r.uid == uid)).first()
            if x is None:
                return None
            events = [ev.decode(y.body) for y in conn.execute(
                sa.select(e.body).where(e.run_id == x.id, e.event.in_(kinds_read()))
                .order_by(e.seq))]
            count = conn.execute(sa.select(sa.func.count()).select_from(s.bench_events)
                                 .where(e.run_id == x.id)).scalar_one()
        state = self._run_state(x, events, now)
        result = x.result if isinstance(x.result, dict) else None
        final: list[JsonLike] = []
        if result is not None and state["run_status"] != "running":
            kind = x.kind or ResultFrame.conform(result)[0].procedure or ""
            specs = declared_figures([kind]) if kind else ()
            for f in figures_of(ResultFrame.of(result), kind or None):
                spec = spec_for(f.quantity, specs)
                scale = spec.scale if spec else 1.0
                final.append({"axis": f.axis, "name": spec.name if spec else f.quantity,
                              "rate": "-" if f.set_rate_dps is None else rate_text(f.set_rate_dps),
                              "value": ("< " + f"{f.value * scale:.3g}" if f.is_limit
                                        else value_u(f.value, f.u, scale)),
                              "unit": spec.shown if spec else f.unit,
                              "verdict": f.verdict or "-"})
        state.update({
            "events_delivered": int(count),
            "live": station_of(x.kind).live_table(pair_rows(events)) or {},
            "final": final,
            "log": [log_line(e) for e in events if _in_log(e)][-40:],
            "received_utc": _utc_text(_iso(x.received_utc)),
        })
        return state


def fleet_json(state: Mapping[str, JsonLike]) -> list[dict[str, JsonLike]]:
    """The few fields a script (the browser test, the load generator) reads off the
    live stream: which run each bench shows, how far it is delivered, its status."""
    benches = state.get("benches")
    rows = [x for x in benches if isinstance(x, Mapping)] \
        if isinstance(benches, Sequence) and not isinstance(benches, str) else []
    return [{"bench": x["bench"], "uid": x["uid"], "run": x["run"], "seq": x["seq"],
             "status": x["status"], "verdict": x["verdict"],
             "fraction": _fraction(x["progress"])} for x in rows]


def _fraction(progress: JsonLike) -> JsonLike:
    return progress.get("fraction") if isinstance(progress, Mapping) else None
