"""A lab at scale (issue 44; run on demand, not a test): many benches delivering to one
PostgreSQL server, the station following them, and years of history in the records.

    python benchmarks/bench_fleet.py [--benches 20] [--pace 10] [--history-runs 100000]
        [--tables 250] [--years 10] [--replay-s 60] [--url postgresql://...]

1. History: fills the records with `--history-runs` runs of `--tables` tables over
   `--years` years (bulk COPY, not `bench records import`: the point is the database the
   commands read, not a year of imports). Each run is the recorded run of
   tests/data/fleet/ladder-run (one outer-axis pair) widened to four rates, so 56
   figures, 24 check values and 3 certificate files per run, with the values scattered;
   each table has its own FOG, counter and drive serials; about 1 run in 8 fails.
2. Replay: `--benches` benches, each a thread writing the recorded run's event stream
   into a run directory of its own at `--pace` times its bench time (the events' `t_s`),
   touching its raw files as a running bench does, and run after run; beside each, the
   bench's real courier (bench/app/fleet/courier.py) delivering it to the lab database
   every 0.5 s. The station (`bench serve --records URL`, a subprocess) follows through
   LISTEN/NOTIFY; a client reads its live stream (/api/fleet/stream, what the lab page's
   script puts in place). Latency: from the moment a line was written to the bench's
   events.jsonl to the moment the stream showed that line's run at that sequence number
   or later.
3. Response times: `bench history SERIAL --records URL` and `bench due --records URL`,
   whole processes (as a person types them) and the database part alone; the lab page
   (GET /) as a whole.
4. Size: the lab database's size per run, and per table of it.

Without --url a throwaway PostgreSQL server is started (tests/pg_server.py) and removed.
Goals (issue 44): update latency p95 <= 2 s; history and due <= 0.5 s.
"""

from __future__ import annotations

import argparse
import datetime as dt
import hashlib
import http.client
import json
import os
import random
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import sqlalchemy as sa  # noqa: E402

from bench.app.fleet.courier import Courier  # noqa: E402
from bench.app.records.extract import record_of  # noqa: E402
from bench.app.records.store import Records  # noqa: E402
from bench.core.journal import RunDir  # noqa: E402

RECORDED = ROOT / "tests" / "data" / "fleet" / "ladder-run"
RATES_DPS = (10.0, 60.0, 200.0, 400.0)        # the recorded pair widened to four rates
GOALS = {"p95_s": 2.0, "history_s": 0.5, "due_s": 0.5}


def _copy_rows(raw: Any, table: str, columns: tuple[str, ...], rows: list[tuple[Any, ...]]
               ) -> None:
    with raw.cursor() as cur, cur.copy(
            f"COPY {table} ({', '.join(columns)}) FROM STDIN") as copy:
        for r in rows:
            copy.write_row(r)


def fill_history(url: str, runs: int, tables: int, years: float, seed: int = 44) -> float:
    """The records of a lab's past; returns the seconds it took."""
    t0 = time.monotonic()
    template = record_of(RECORDED)
    rng = random.Random(seed)
    with Records.open(url) as rec:
        raw = rec.engine.raw_connection()
        try:
            cur = raw.cursor()
            now = dt.datetime(2026, 11, 1)
            start = now - dt.timedelta(days=365.25 * years)
            table_rows = [(f"LAB-{i:04d}", "Simulated Tables Ltd", f"ST-{1 + i % 4}A",
                           f"hall {1 + i % 3}", 365, start, now) for i in range(tables)]
            _copy_rows(raw, "tables", ("serial", "maker", "model", "location",
                                       "interval_days", "first_seen_utc", "last_seen_utc"),
                       table_rows)
            cur.execute("SELECT id, serial FROM tables WHERE serial LIKE 'LAB-%'")
            table_ids = dict(cur.fetchall())
            instruments = []
            for serial in table_ids.values():
                for role, model in (("fog", "KVH DSP-1760"), ("counter", "keysight-53230a"),
                                    ("drive", None)):
                    instruments.append((f"{serial}/{role}", role, model, start, now))
            _copy_rows(raw, "instruments", ("serial", "role", "model", "first_seen_utc",
                                            "last_seen_utc"), instruments)
            cur.execute("SELECT serial, id FROM instruments WHERE serial LIKE 'LAB-%'")
            inst_ids = dict(cur.fetchall())
            roles = {c.serial: c.role for c in template.checks}
            cur.execute("SELECT coalesce(max(id), 0) FROM runs")
            next_id = int(cur.fetchone()[0]) + 1
            span_s = (now - start).total_seconds()
            tids = list(table_ids)
            chunk = 5000
            for base in range(0, runs, chunk):
                run_rows, fig_rows, chk_rows, file_rows = [], [], [], []
                for i in range(base, min(runs, base + chunk)):
                    run_id = next_id + i
                    tid = tids[i % tables]
                    serial = table_ids[tid]
                    when = start + dt.timedelta(seconds=span_s * (i + rng.random()) / runs)
                    verdict = "fail" if rng.random() < 0.125 else "pass"
                    uid = hashlib.sha256(f"history-{seed}-{i}".encode()).hexdigest()[:32]
                    number = (f"CAL-{when.year}-{i:06d}" if rng.random() < 0.97 else None)
                    run_rows.append((run_id, uid, tid, "rate-ladder", template.title,
                                     f"{when:%Y%m%d-%H%M%S}-recert", None, "bench-host",
                                     "recert.yaml", "0" * 64, "0" * 64, f"{i:064x}",
                                     when, when, when + dt.timedelta(hours=3), now,
                                     "operator", verdict, None, None, number, False, 1,
                                     False, "0.1.0"))
                    for rate in RATES_DPS:
                        for f in template.figures:
                            sign = 1.0 if (f.set_rate_dps or 0) >= 0 else -1.0
                            fig_rows.append((run_id, f.axis, f.quantity,
                                             None if f.set_rate_dps is None else sign * rate,
                                             f.value * (1 + 0.2 * rng.gauss(0, 1)), f.u,
                                             f.unit, 1e-6, verdict, "guard-band"))
                        for c in template.checks:
                            chk_rows.append((run_id, inst_ids[f"{serial}/{roles[c.serial]}"],
                                             c.axis, c.quantity, rate,
                                             c.value * (1 + 1e-4 * rng.gauss(0, 1)), c.u, c.unit))
                    for name in ("certificate.pdf", "certificate.html", "certificate.dcc.xml"):
                        file_rows.append((run_id, name, f"{i:060x}{len(name):04x}", 250_000))
                _copy_rows(raw, "runs", (
                    "id", "uid", "table_id", "kind", "title", "run_dir", "run_path", "host",
                    "procedure_name", "procedure_sha256", "stand_sha256", "result_sha256",
                    "created_utc", "started_utc", "completed_utc", "registered_utc",
                    "operator", "verdict", "calibration_state", "adjustment_note",
                    "certificate_number", "simulated", "sessions", "aborted",
                    "bench_version"), run_rows)
                _copy_rows(raw, "figures", ("run_id", "axis", "quantity", "set_rate_dps",
                                            "value", "u", "unit", "tolerance", "verdict",
                                            "rule"), fig_rows)
                _copy_rows(raw, "checks", ("run_id", "instrument_id", "axis", "quantity",
                                           "set_rate_dps", "value", "u", "unit"), chk_rows)
                _copy_rows(raw, "cert_files", ("run_id", "name", "sha256", "bytes"),
                           file_rows)
                raw.commit()
                print(f"  history: {min(runs, base + chunk)} of {runs} runs", flush=True)
            cur.execute("SELECT setval(pg_get_serial_sequence('runs', 'id'), "
                        "(SELECT max(id) FROM runs))")
            cur.execute("ANALYZE")
            raw.commit()
        finally:
            raw.close()
    return time.monotonic() - t0


# -- the replayed benches -------------------------------------------------------------------

@dataclass
class Written:
    """When each line was written: (bench, run uid) -> {seq: wall time}."""

    lines: dict[tuple[str, str], dict[int, float]] = field(default_factory=dict)
    lock: threading.Lock = field(default_factory=threading.Lock)

    def add(self, bench: str, uid: str, seq: int, t: float) -> None:
        with self.lock:
            self.lines.setdefault((bench, uid), {})[seq] = t


class ReplayedBench(threading.Thread):
    """One bench replaying the recorded event stream, run after run, with its courier."""

    def __init__(self, name: str, folder: Path, url: str, pace: float, written: Written,
                 stop: threading.Event) -> None:
        super().__init__(name=name, daemon=True)
        self.bench, self.folder, self.url, self.pace = name, folder, url, pace
        self.written, self.stop_at = written, stop
        self.events = [json.loads(x) for x in (RECORDED / "events.jsonl").read_text()
                       .splitlines()]
        self.runs = 0
        self.warnings: list[str] = []

    def run(self) -> None:
        from bench.app.records.extract import run_uid

        while not self.stop_at.is_set():
            self.runs += 1
            path = self.folder / f"20261127-000000-{self.bench}-{self.runs:03d}"
            path.mkdir(parents=True)
            meta = json.loads((RECORDED / "meta.json").read_text())
            meta["created_utc"] = dt.datetime.now(dt.UTC).isoformat(timespec="milliseconds")
            (path / "meta.json").write_text(json.dumps(meta))
            shutil.copyfile(RECORDED / "procedure.yaml", path / "procedure.yaml")
            stand = (RECORDED / "stand.yaml").read_text().replace(
                "serial: SIM-0001", f"serial: FLEET-{self.bench}", 1)
            (path / "stand.yaml").write_text(stand + f"\nbench: {{name: {self.bench}}}\n")
            (path / "events.jsonl").touch()
            raw = path / "raw" / "s1"
            raw.mkdir(parents=True)
            uid = run_uid(meta, path.name)
            courier = Courier(RunDir(path), self.url, self.bench, self.warnings.append).start()
            t_first = self.events[0].get("t_s") or 0.0
            t0 = time.monotonic()
            with open(path / "events.jsonl", "a", encoding="utf-8") as log:
                for seq, e in enumerate(self.events, 1):
                    due = t0 + ((e.get("t_s") or t_first) - t_first) / self.pace
                    while time.monotonic() < due:
                        time.sleep(min(0.05, due - time.monotonic()))
                        if e.get("axis"):   # the instruments stream while the run runs
                            with open(raw / f"{e['axis']}-fog.bin", "ab") as fog:
                                fog.write(b"\0" * 36)
                    e = {**e, "utc": dt.datetime.now(dt.UTC).isoformat(timespec="milliseconds")}
                    log.write(json.dumps(e, separators=(",", ":")) + "\n")
                    log.flush()
                    self.written.add(self.bench, uid, seq, time.time())
            shutil.copyfile(RECORDED / "result.json", path / "result.json")
            courier.finish()


class StreamClient(threading.Thread):
    """The lab page's live stream, read as the page's script reads it: each update's
    (bench, run, sequence number) with the wall time it arrived."""

    def __init__(self, port: int) -> None:
        super().__init__(daemon=True)
        self.port = port
        self.updates: list[tuple[float, list[dict[str, Any]]]] = []
        self.stop_at = threading.Event()

    def run(self) -> None:
        while not self.stop_at.is_set():
            conn = http.client.HTTPConnection("127.0.0.1", self.port, timeout=30)
            conn.request("GET", "/api/fleet/stream")
            resp = conn.getresponse()
            event = None
            while not self.stop_at.is_set():
                line = resp.readline()
                if not line:
                    break
                text = line.decode().rstrip("\n")
                if text.startswith("event: "):
                    event = text[7:]
                elif text.startswith("data: ") and event == "fleet":
                    self.updates.append((time.time(), json.loads(text[6:])["benches"]))
            conn.close()


def latencies(written: Written, updates: list[tuple[float, list[dict[str, Any]]]]
              ) -> list[float]:
    """Per written line: the first update showing its run at that sequence or later."""
    shown: dict[tuple[str, str], list[tuple[float, int]]] = {}
    for t, benches in updates:
        for b in benches:
            shown.setdefault((b["bench"], b["uid"]), []).append((t, int(b["seq"])))
    out = []
    for key, lines in written.lines.items():
        seen = shown.get(key, [])
        for seq, t_written in lines.items():
            t_shown = next((t for t, s in seen if s >= seq and t >= t_written), None)
            if t_shown is not None:
                out.append(t_shown - t_written)
    return out


def _timed(cmd: list[str], repeat: int = 3) -> tuple[float, str]:
    best, out = float("inf"), ""
    for _ in range(repeat):
        t0 = time.monotonic()
        done = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
        best = min(best, time.monotonic() - t0)
        out = done.stdout if done.returncode == 0 else done.stderr
    return best, out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--benches", type=int, default=20)
    ap.add_argument("--pace", type=float, default=10.0, help="times the recorded bench time")
    ap.add_argument("--history-runs", type=int, default=100_000)
    ap.add_argument("--tables", type=int, default=250)
    ap.add_argument("--years", type=float, default=10.0)
    ap.add_argument("--replay-s", type=float, default=60.0, help="wall seconds of replay")
    ap.add_argument("--url", help="a lab database to use (default: a throwaway server)")
    ap.add_argument("--history-only", action="store_true",
                    help="fill the history into --url and stop (then measure it with "
                         "--no-history as often as needed)")
    ap.add_argument("--no-history", action="store_true",
                    help="the records of --url hold the history already")
    args = ap.parse_args()
    print(f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores", flush=True)
    server = None
    url = args.url
    if url is None:
        from tests.pg_server import PgServer
        server = PgServer().start()
        url = server.create_database("lab")
    tmp = Path(tempfile.mkdtemp(prefix="bench-fleet-"))
    station = None
    try:
        Records.open(url).close()
        if not args.no_history:
            print(f"filling {args.history_runs} runs of {args.tables} tables over "
                  f"{args.years:g} years ...", flush=True)
            fill_s = fill_history(url, args.history_runs, args.tables, args.years)
            print(f"history filled in {fill_s:.0f} s", flush=True)
        if args.history_only:
            return 0
        (tmp / "station-runs").mkdir()
        station = subprocess.Popen([sys.executable, "-m", "bench", "serve", "--runs",
                                    str(tmp / "station-runs"), "--records", url,
                                    "--port", "0"], cwd=ROOT, text=True,
                                   stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
        assert station.stdout is not None
        m = re.search(r":(\d+)/", station.stdout.readline())
        assert m, "the station did not start"
        port = int(m.group(1))
        t0 = time.monotonic()
        conn = http.client.HTTPConnection("127.0.0.1", port, timeout=120)
        conn.request("GET", "/")
        page = conn.getresponse()
        page.read()
        page_s = time.monotonic() - t0
        print(f"lab page (GET /, {page.status}) with 0 benches: {page_s:.2f} s", flush=True)
        client = StreamClient(port)
        client.start()
        written, stop = Written(), threading.Event()
        benches = [ReplayedBench(f"bench-{i:02d}", tmp / f"bench-{i:02d}" / "runs", url,
                                 args.pace, written, stop) for i in range(args.benches)]
        for b in benches:
            b.start()
        time.sleep(args.replay_s)
        stop.set()
        for b in benches:
            b.join(timeout=120)
        time.sleep(3.0)          # the last deliveries reach the page
        client.stop_at.set()
        lat = sorted(latencies(written, client.updates))
        lines = sum(len(v) for v in written.lines.values())
        warnings = [w for b in benches for w in b.warnings]
        print(f"replay: {args.benches} benches at {args.pace:g}x for {args.replay_s:g} s: "
              f"{sum(b.runs for b in benches)} runs, {lines} event lines, "
              f"{len(client.updates)} page updates, {len(lat)} lines seen on the page"
              + (f"; {len(warnings)} courier warnings, first: {warnings[0]}" if warnings
                 else ""))
        if lat:
            p95 = lat[int(0.95 * (len(lat) - 1))]
            print(f"page update latency (event written -> shown): median "
                  f"{statistics.median(lat):.3f} s, p95 {p95:.3f} s, max {lat[-1]:.3f} s "
                  f"(goal p95 <= {GOALS['p95_s']} s)")
        t0 = time.monotonic()
        conn = http.client.HTTPConnection("127.0.0.1", port, timeout=120)
        conn.request("GET", "/")
        page = conn.getresponse()
        page.read()
        print(f"lab page (GET /, {page.status}) with {args.benches} benches: "
              f"{time.monotonic() - t0:.2f} s", flush=True)

        serial = "LAB-0007"
        plot = tmp / "history.png"
        history_s, out = _timed([sys.executable, "-m", "bench", "history", serial,
                                 "--records", url, "--plot", str(plot)])
        n_runs = re.search(r"(\d+) run\(s\)", out)
        due_s, due_out = _timed([sys.executable, "-m", "bench", "due", "--records", url])
        t0 = time.monotonic()
        history_db, due_db = [], []
        with Records.open(url) as rec:
            open_s = time.monotonic() - t0
            for _ in range(5):              # median of 5: the machine is shared
                t1 = time.monotonic()
                runs = rec.runs(serial)       # what `bench history` asks, in its order
                rec.trend(serial, runs_of_table=runs)
                rec.table(serial)
                t2 = time.monotonic()
                items = rec.due()
                history_db.append(t2 - t1)
                due_db.append(time.monotonic() - t2)
        print(f"bench history {serial} ({n_runs.group(1) if n_runs else '?'} runs, with "
              f"its plot): {history_s:.2f} s as a process; database part (runs, trend, "
              f"table) median {statistics.median(history_db):.3f} s, max "
              f"{max(history_db):.3f} s (goal {GOALS['history_s']} s)")
        print(f"bench due ({len(due_out.splitlines()) - 1} lines): {due_s:.2f} s as a "
              f"process; database part median {statistics.median(due_db):.3f} s, max "
              f"{max(due_db):.3f} s, {len(items)} tables due; open and migration check "
              f"{open_s:.3f} s (goal {GOALS['due_s']} s)")
        with Records.open(url) as rec, rec.engine.connect() as c:
            size = c.execute(sa.text("SELECT pg_database_size(current_database())")).scalar()
            n = c.execute(sa.text("SELECT count(*) FROM runs")).scalar()
            parts = c.execute(sa.text(
                "SELECT relname, pg_total_relation_size(c.oid) FROM pg_class c "
                "JOIN pg_namespace n ON n.oid = c.relnamespace WHERE n.nspname = 'public' "
                "AND c.relkind = 'r' ORDER BY 2 DESC")).all()
            fleet_runs = c.execute(sa.text("SELECT count(*) FROM bench_runs")).scalar()
        print(f"database: {size / 1e6:.0f} MB for {n} runs: {size / max(n, 1) / 1e3:.1f} kB "
              f"per run")
        for name, b in parts:
            per = (b / max(fleet_runs or 1, 1) if name.startswith("bench_")
                   else b / max(n, 1))
            unit = "per delivered run" if name.startswith("bench_") else "per run"
            print(f"  {name:<24} {b / 1e6:8.1f} MB  {per / 1e3:7.2f} kB {unit}")
    finally:
        if station is not None:
            station.terminate()
            station.wait(timeout=30)
        shutil.rmtree(tmp, ignore_errors=True)
        if server is not None:
            server.stop()
    return 0


if __name__ == "__main__":
    sys.exit(main())
