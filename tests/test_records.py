"""The lab records (issue 16) against real databases: SQLite always, and a PostgreSQL
server this module starts itself (tests/pg_server.py; skipped, saying why, only where no
server can be started). Every test that touches a database runs on both.

The runs are real simulated runs (`bench run` in a subprocess, twins on real channels),
kept small: one axis, one rate, three turns.
"""

from __future__ import annotations

import csv
import dataclasses
import datetime as dt
import json
import shutil
import subprocess
import threading
import time
import uuid
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pypdfium2 as pdfium
import pytest
import sqlalchemy as sa
import yaml
from alembic.autogenerate import compare_metadata
from alembic.runtime.migration import MigrationContext

from bench.app.records import Records, record_of
from bench.app.records.extract import figures_of
from bench.app.records.hooks import target, warn_if_overdue
from bench.app.records.schema import metadata
from bench.app.records.store import TrendPoint
from bench.app.records.trend import trend_png
from bench.core.config import parse_stand
from bench.core.journal import sha256_file
from bench.report.result_frame import ResultFrame
from sims.stand import AxisTruth
from tests.conftest import CONFIGS, bench, bench_bg, cli
from tests.conftest import OUTER_SERIALS as OUTER
from tests.pg_server import PgServer
from tests.test_run_e2e import assert_within_u

SERIAL = "SIM-REC-1"
#: the outer axis's mean rate bias at each recertification: the table drifts by
#: +0.8 ppm, then is adjusted by +0.9 ppm (as-found -> as-left) -- far beyond U (~0.05 ppm)
BIAS_REL = (3.0e-7, 1.1e-6, 2.0e-6)
STATES: tuple[tuple[str, ...], ...] = ((), ("--as-found",),
                                       ("--as-left", "--adjustment", "rate loop gain trimmed"))


def _procedure(folder: Path, bias_rel: float, seed: int) -> tuple[Path, float]:
    """A one-rate procedure on the two-axis twin with the given truth; (file, truth)."""
    stand = yaml.safe_load((CONFIGS / "stands" / "sim-two-axis.yaml").read_text())
    stand["stand"]["serial"] = SERIAL
    stand["stand"]["recertification_interval_days"] = 365
    stand["sim"]["seed"] = seed
    stand["sim"]["axes"]["outer"]["rate_bias_rel"] = bias_rel
    sfile = folder / f"stand-{seed}.yaml"
    sfile.write_text(yaml.safe_dump(stand))
    proc = folder / f"recert-{seed}.yaml"
    proc.write_text(yaml.safe_dump({
        "procedure": "rate-ladder", "title": "Recertification (records test)",
        "stand": str(sfile), "turns": 3, "static_record_s": 10, "harmonics": 2,
        "axes": {"outer": {"rates_dps": [100]}},
        "tolerance": {"rate_error": [{"rel": 1e-5}], "rate_instability": [{"rel": 1e-5}]},
        "certificate": {"laboratory": "Records test lab"},
    }))
    truth = AxisTruth.from_mapping(stand["sim"]["axes"]["outer"]).mean_turn_rate_rel()
    return proc, truth


def _run_dir(out: subprocess.CompletedProcess[str]) -> Path:
    assert out.returncode == 0, out.stdout[-2000:] + out.stderr[-3000:]
    return Path(out.stdout.strip().splitlines()[-1])


# -- the databases ---------------------------------------------------------------------------

@dataclasses.dataclass
class Db:
    """One empty records database; `block`/`unblock` make it unreachable and back."""

    kind: str
    url: str
    block: Callable[[], None]
    unblock: Callable[[], None]


@pytest.fixture(params=["sqlite", "postgresql"])
def db(request: pytest.FixtureRequest, tmp_path: Path) -> Db:
    if request.param == "sqlite":
        path = tmp_path / "db" / "records.sqlite"
        aside = path.with_name("records.sqlite.aside")

        def block() -> None:       # the file is replaced by something no client can open
            path.rename(aside)
            path.mkdir()

        def unblock() -> None:
            path.rmdir()
            aside.rename(path)
        return Db("sqlite", f"sqlite:///{path}", block, unblock)
    server: PgServer = request.getfixturevalue("pg")
    name = f"records_{uuid.uuid4().hex[:10]}"
    return Db("postgresql", server.create_database(name), lambda: server.block(name),
              lambda: server.unblock(name))


# -- three recertifications of one table -----------------------------------------------------

@pytest.fixture(scope="module")
def recerts(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """Three runs of one table, the truth drifting between them, registered as they end
    into the default records (records.sqlite in the runs folder)."""
    folder = tmp_path_factory.mktemp("recerts")
    runs_dir = folder / "runs"
    dirs, truths, outs = [], [], []
    for i, (bias, state) in enumerate(zip(BIAS_REL, STATES, strict=True)):
        proc, truth = _procedure(folder, bias, seed=11 + i)
        out = bench("run", str(proc), "--yes", "--out", str(runs_dir), *state)
        dirs.append(_run_dir(out))
        truths.append(truth)
        outs.append(out)
    return {"runs": runs_dir, "dirs": dirs, "truths": truths, "outs": outs}


def _history_csv(tmp_path: Path, *where: str) -> list[dict[str, str]]:
    out = cli("history", SERIAL, *where, "--csv", str(tmp_path / "h.csv"),
                "--plot", str(tmp_path / "h.png"))
    assert out.returncode == 0, out.stderr
    assert (tmp_path / "h.png").read_bytes()[:4] == b"\x89PNG"
    with open(tmp_path / "h.csv", newline="") as fh:
        return list(csv.DictReader(fh))


def _check_drift(rows: list[dict[str, str]], recerts: dict[str, Any]) -> None:
    """Per run, each rate error within U of that run's truth; the drift is seen."""
    uids = [record_of(d).uid for d in recerts["dirs"]]
    errors = [r for r in rows if r["quantity"] == "rate_error_rel"]
    assert {r["run_uid"] for r in errors} == set(uids)
    checked = []
    means = []
    for uid, truth in zip(uids, recerts["truths"], strict=True):
        mine = [r for r in errors if r["run_uid"] == uid]
        assert sorted(float(r["set_rate_dps"]) for r in mine) == [-100.0, 100.0]
        checked += [(f"run {uid[:6]} {r['set_rate_dps']}", abs(float(r["value"]) - truth),
                     float(r["u"])) for r in mine]
        means.append(sum(float(r["value"]) for r in mine) / len(mine))
    assert_within_u(checked)
    # the history is in date order and follows the truth's drift
    assert [r["run_uid"] for r in errors][::2] == uids
    steps = [b - a for a, b in zip(means, means[1:], strict=False)]
    truth_steps = [b - a for a, b in zip(recerts["truths"], recerts["truths"][1:],
                                         strict=False)]
    for seen, true in zip(steps, truth_steps, strict=True):
        assert abs(seen - true) < 0.25 * true, (steps, truth_steps)


@pytest.mark.timeout(600)
def test_three_recertifications_show_the_drift_and_the_third_certificate_its_history(
        recerts: dict[str, Any], tmp_path: Path) -> None:
    runs_dir, dirs = recerts["runs"], recerts["dirs"]
    assert (runs_dir / "records.sqlite").is_file()    # the default: in the runs folder
    rows = _history_csv(tmp_path, "--runs", str(runs_dir))
    _check_drift(rows, recerts)

    # the first certificate has no history; the third has the trend plot and states that
    # the second run has no issued certificate: a draft is cited nowhere (issue 42;
    # tests/test_register.py checks that an issued revision is cited with its digests)
    first = (dirs[0] / "certificate.html").read_text(encoding="utf-8")
    assert "History of this table" not in first
    third = (dirs[2] / "certificate.html").read_text(encoding="utf-8")
    assert "History of this table" in third
    assert 'alt="Trend across recertifications' in third
    second = record_of(dirs[1])
    assert second.certificate_number is None and second.cert_files == ()
    assert "none issued (the previous run has a draft only" in third
    assert sha256_file(dirs[1] / "certificate.pdf") not in third
    assert "As found ± U" in third and "rate loop gain trimmed" in third
    pdf = pdfium.PdfDocument(dirs[2] / "certificate.pdf")
    text = " ".join(p.get_textpage().get_text_range() for p in pdf)
    assert "History of this table" in text and "Trend across recertifications" in text

    # as-found / as-left and the adjustment are in the records
    with Records.open(target(runs_dir).url) as rec:
        runs = rec.runs(SERIAL)
        assert [r.calibration_state for r in runs] == [None, "as-found", "as-left"]
        assert runs[2].adjustment_note == "rate loop gain trimmed"
        assert runs[2].cert_files == {}          # drafts: no certificate files recorded
        assert all(r.operator for r in runs)
        assert all(r.procedure_sha256 == json.loads((d / "meta.json").read_text())[
            "procedure_sha256"] for r, d in zip(runs, dirs, strict=True))


@pytest.mark.timeout(600)
def test_import_is_idempotent_and_history_reads_the_database(
        recerts: dict[str, Any], db: Db, tmp_path: Path) -> None:
    first = cli("records", "import", str(recerts["runs"]), "--records", db.url)
    assert first.returncode == 0, first.stderr
    assert "3 new, 0 updated, 0 already recorded" in first.stdout
    again = cli("records", "import", str(recerts["runs"]), "--records", db.url)
    assert "0 new, 0 updated, 3 already recorded" in again.stdout, again.stdout
    rows = _history_csv(tmp_path, "--records", db.url)
    _check_drift(rows, recerts)
    with Records.open(db.url) as rec:
        assert rec.revision() == "r0004"
        (t,) = rec.tables()
        assert (t.serial, t.runs, t.interval_days) == (SERIAL, 3, 365)
        # every figure of result.json is kept, with its U and verdict
        result = json.loads((recerts["dirs"][0] / "result.json").read_text())
        uid = record_of(recerts["dirs"][0]).uid
        kept = {(f.quantity, f.set_rate_dps): f for f in rec.figures(uid)}
        r = result["axes"]["outer"]["rates"][0]
        f = kept[("rate_error_rel", r["set_rate_dps"])]
        assert (f.value, f.u, f.verdict, f.tolerance) == (
            r["rate_error_rel"], r["rate_error_u_rel"], r["verdict"], 1e-5)
        p = result["axes"]["outer"]["pairs"][0]
        assert kept[("k", 100.0)].value == p["k"] and kept[("k", 100.0)].u == p["k_u"]
    missing = cli("history", "NO-SUCH-TABLE", "--records", db.url)
    assert missing.returncode == 1 and "no run of table" in missing.stderr


def test_the_migrations_build_exactly_the_schema(db: Db) -> None:
    with Records.open(db.url) as rec:
        Records.open(db.url).close()                 # a second open finds it migrated
        with rec.engine.connect() as conn:
            diff = compare_metadata(MigrationContext.configure(
                conn, opts={"version_table": "records_alembic_version"}), metadata)
        assert diff == []
        names = set(sa.inspect(rec.engine).get_table_names())
        assert {"tables", "runs", "figures", "cert_files", "instruments", "checks",
                "reviews", "benches", "bench_runs", "bench_events",
                "records_alembic_version"} <= names
        assert rec.revision() == "r0004"


def test_a_database_of_r0001_is_upgraded_and_import_adds_the_check_values(
        recerts: dict[str, Any], db: Db) -> None:
    """Runs registered before r0002 (no check values) get them from `records import`."""
    from alembic import command
    from alembic.config import Config as AlembicConfig

    from bench.app.db import make_engine
    from bench.app.records.store import MIGRATIONS

    engine = make_engine(db.url)
    cfg = AlembicConfig()
    cfg.set_main_option("script_location", str(MIGRATIONS))
    with engine.begin() as conn:
        cfg.attributes["connection"] = conn
        command.upgrade(cfg, "r0001")
    old = Records(engine, db.url)            # the r0001 schema, as an older bench left it
    assert old.revision() == "r0001"
    for d in recerts["dirs"]:
        assert old.register(dataclasses.replace(record_of(d), checks=())) == "new"
    engine.dispose()
    out = cli("records", "import", str(recerts["runs"]), "--records", db.url)
    assert "0 new, 3 updated, 0 already recorded" in out.stdout, out.stdout + out.stderr
    with Records.open(db.url) as rec:
        assert rec.revision() == "r0004"
        assert len({p.run_uid for p in rec.checks(OUTER["fog"])}) == 3


def test_check_values_and_reviews_on_both_databases(recerts: dict[str, Any], db: Db) -> None:
    """Each run's check values land per instrument serial, in run order, with U; a review
    is journaled with who, why and what it covers (issue 28)."""
    from bench.app.records.control import NOT_ENOUGH, instrument_status

    fog = OUTER["fog"]
    with Records.open(db.url) as rec:
        for d in recerts["dirs"]:
            assert rec.register(record_of(d)) == "new"
            assert rec.register(record_of(d)) == "unchanged"
        assert {i.serial for i in rec.instruments()} == {
            fog, OUTER["counter"], OUTER["drive"]}
        pts = [p for p in rec.checks(fog) if p.check.quantity == "k"]
        pairs = [json.loads((d / "result.json").read_text())["axes"]["outer"]["pairs"][0]
                 for d in recerts["dirs"]]
        assert [(p.check.value, p.check.u, p.check.set_rate_dps) for p in pts] == [
            (q["k"], q["k_u"], 100.0) for q in pairs]
        noise = [p for p in rec.checks(fog) if p.check.quantity == "noise_floor_dps"]
        assert len(noise) == 3 and all(0.008 < p.check.value < 0.012 for p in noise)
        status = instrument_status(rec, fog)
        assert status is not None and status.state == NOT_ENOUGH and status.runs == 3
        rec.add_review(fog, "Q. Manager", "scale re-checked", status.line, pts[-1].date_utc)
        (r,) = rec.reviews(fog)
        assert (r.reviewer, r.text, r.through_utc) == ("Q. Manager", "scale re-checked",
                                                       pts[-1].date_utc)


def test_concurrent_registrations_of_a_new_table_lose_nothing(
        recerts: dict[str, Any], db: Db) -> None:
    """Eight writers register eight runs of one not-yet-recorded table at once: the
    first row of the table is raced for, and every run ends up recorded."""
    base = record_of(recerts["dirs"][0])
    records = [dataclasses.replace(base, uid=f"{base.uid[:24]}{i:08d}", serial="RACE-1")
               for i in range(8)]
    Records.open(db.url).close()                     # migrated before the race
    barrier = threading.Barrier(len(records))
    errors: list[BaseException] = []

    def write(rec_: Any) -> None:
        try:
            with Records.open(db.url) as rec:
                barrier.wait(timeout=60)
                assert rec.register(rec_) == "new"
        except BaseException as e:  # noqa: BLE001 - reported below
            errors.append(e)
            barrier.abort()
    threads = [threading.Thread(target=write, args=(r,)) for r in records]
    for t in threads:
        t.start()
    for t in threads:
        t.join(120)
    assert not errors, errors
    with Records.open(db.url) as rec:
        assert {r.uid for r in rec.runs("RACE-1")} == {r.uid for r in records}
        assert [t.serial for t in rec.tables()] == ["RACE-1"]


def _old_copy(run_dir: Path, folder: Path, when: str) -> Path:
    """A copy of a run dated `when` (a recertification recorded long ago)."""
    old = folder / f"old-{run_dir.name}"
    shutil.copytree(run_dir, old)
    for name in ("result.json", "meta.json"):
        data = json.loads((old / name).read_text())
        if name == "result.json":
            data["dates"] = {k: when for k in data["dates"]}
        else:
            data["created_utc"] = when
        (old / name).write_text(json.dumps(data))
    return old


@pytest.mark.timeout(600)
def test_due_dates_and_the_overdue_warning_at_a_run_start(
        recerts: dict[str, Any], db: Db, tmp_path: Path) -> None:
    old = _old_copy(recerts["dirs"][0], tmp_path / "old", "2024-03-01T10:00:00+00:00")
    assert cli("records", "import", str(tmp_path / "old"), "--records", db.url
                 ).returncode == 0
    due = cli("due", "--records", db.url, "--today", "2025-03-10")
    assert due.returncode == 0 and SERIAL in due.stdout and "OVERDUE by 9 d" in due.stdout
    soon = cli("due", "--records", db.url, "--today", "2025-02-20")
    assert "due in 9 d" in soon.stdout
    quiet = cli("due", "--records", db.url, "--today", "2024-06-01")
    assert SERIAL not in quiet.stdout
    stand = yaml.safe_load((old / "stand.yaml").read_text())
    said: list[str] = []
    where = target(tmp_path, db.url)
    assert warn_if_overdue(parse_stand(stand).identity, where, said.append) is not None
    assert "overdue" in said[0] and SERIAL in said[0]
    # a lab settings file overrides the stand's interval
    lab = tmp_path / "lab.yaml"
    lab.write_text(yaml.safe_dump(
        {"records": db.url, "recertification": {"tables": {SERIAL: 10000}}}))
    assert warn_if_overdue(parse_stand(stand).identity, target(tmp_path, lab_file=lab),
                           said.append) is None
    # one rule for the lab file (issue 57): a lab.yaml in the runs folder is not read; the
    # command says so instead of ignoring it
    ignored = cli("due", "--runs", str(tmp_path))
    assert ignored.returncode == 2 and "a lab file in the runs folder is not read" in \
        ignored.stderr and f"--lab {lab}" in ignored.stderr
    lab.write_text("recertification: {tables: {X: -1}}\n")
    bad = cli("due", "--runs", str(tmp_path), "--lab", str(lab))
    assert bad.returncode == 2 and "lab.yaml:1: recertification.tables.X" in bad.stderr


@pytest.fixture
def pg_db(pg: PgServer) -> Db:
    name = f"records_{uuid.uuid4().hex[:10]}"
    return Db("postgresql", pg.create_database(name), lambda: pg.block(name),
              lambda: pg.unblock(name))


@pytest.mark.timeout(600)
def test_two_benches_register_at_once_and_an_overdue_table_is_said_at_the_start(
        recerts: dict[str, Any], pg_db: Db, tmp_path: Path) -> None:
    """Two runs of one overdue table write into one lab PostgreSQL database at the same
    time (SQLite's writers are raced in the threaded test above)."""
    db = pg_db
    _old_copy(recerts["dirs"][0], tmp_path / "old", "2024-01-01T10:00:00+00:00")
    assert cli("records", "import", str(tmp_path / "old"), "--records", db.url
                 ).returncode == 0
    procs = []
    for i in range(2):
        proc, _ = _procedure(tmp_path, BIAS_REL[0], seed=31 + i)
        procs.append(bench_bg("run", str(proc), "--yes", "--out", str(tmp_path / f"b{i}"),
                              "--records", db.url))
    dirs = []
    for p in procs:
        stdout, stderr = p.communicate(timeout=300)
        assert p.returncode == 0, stderr[-3000:]
        assert "overdue for recertification" in stderr
        assert "not registered" not in stderr, stderr
        dirs.append(Path(stdout.strip().splitlines()[-1]))
    with Records.open(db.url) as rec:
        uids = {r.uid for r in rec.runs(SERIAL)}
    assert {record_of(d).uid for d in dirs} <= uids and len(uids) == 3
    events = [json.loads(x) for x in (dirs[0] / "events.jsonl").read_text().splitlines()]
    assert any(e["event"] == "records_overdue" for e in events)


@pytest.mark.timeout(600)
def test_a_database_lost_mid_run_warns_and_a_later_import_registers_the_run(
        db: Db, tmp_path: Path) -> None:
    proc, _ = _procedure(tmp_path, BIAS_REL[0], seed=41)
    out_dir = tmp_path / "runs"
    run = bench_bg("run", str(proc), "--yes", "--out", str(out_dir), "--records", db.url)
    deadline = time.monotonic() + 120
    blocked = False
    while time.monotonic() < deadline and run.poll() is None:
        logs = list(out_dir.glob("*/events.jsonl"))
        if logs and '"action":"acquire"' in logs[0].read_text():
            db.block()
            blocked = True
            break
        time.sleep(0.05)
    stdout, stderr = run.communicate(timeout=300)
    assert blocked, "the run ended before the database could be taken away"
    assert run.returncode == 0, stderr[-3000:]
    assert "WARNING: records: the run was not registered" in stderr
    assert "bench records import" in stderr
    run_dir = Path(stdout.strip().splitlines()[-1])
    for name in ("result.json", "certificate.pdf", "certificate.html"):
        assert (run_dir / name).is_file(), name
    db.unblock()
    with Records.open(db.url) as rec:
        assert rec.runs(SERIAL) == []
    later = cli("records", "import", str(out_dir), "--records", db.url)
    assert later.returncode == 0 and "1 new" in later.stdout, later.stdout + later.stderr
    with Records.open(db.url) as rec:
        (r,) = rec.runs(SERIAL)
        assert r.uid == record_of(run_dir).uid and r.verdict == "pass"
        assert r.cert_files == {} and r.certificate_number is None    # a draft


def test_drift_pulse_figures_are_recorded_with_u_and_verdict() -> None:
    """A drift-pulse result.json's binding keys (CONTRACT §3) become figures."""
    result = {
        "procedure": "drift-pulse", "verdict": "pass",
        "checks": [{"axis": "x", "quantity": "own_drift", "value_dph": 0.1, "u_dph": 0.02,
                    "tolerance_dph": 0.5, "rule": "simple", "verdict": "pass"}],
        "drift": {"axes": {"x": {"own_dph": 0.1, "own_u_dph": 0.02, "apparent_dph": 0.89,
                                 "apparent_u_dph": 0.03},
                           "y": {"own_dph": -0.2, "own_u_dph": 0.02, "apparent_dph": -5.06,
                                 "apparent_u_dph": 0.03}},
                  "azimuth_deg": 80.0, "azimuth_u_deg": 0.05},
    }
    figs = {(f.axis, f.quantity): f for f in figures_of(ResultFrame.of(result))}
    assert set(figs) == {("x", "own_drift_dph"), ("x", "apparent_drift_dph"),
                         ("y", "own_drift_dph"), ("y", "apparent_drift_dph"),
                         ("platform", "azimuth_deg")}
    x = figs[("x", "own_drift_dph")]
    assert (x.value, x.u, x.unit, x.tolerance, x.verdict) == (0.1, 0.02, "deg/h", 0.5, "pass")
    assert figs[("y", "own_drift_dph")].verdict is None     # no check was made of it
    assert figs[("platform", "azimuth_deg")].u == 0.05


def test_an_unresolved_sigma_is_kept_and_drawn_as_its_upper_limit() -> None:
    """The one rule for unresolved figures (issue 18) reaches the records: a sigma not
    resolved above the timing floor is kept as the certificate prints it, '< limit', and
    the trend plot draws a limit marker, not a point with U bars."""
    import datetime as dt



    result = {"procedure": "rate-ladder", "verdict": "pass", "checks": [
        {"axis": "outer", "set_rate_dps": 50.0, "quantity": "rate_instability",
         "verdict": "not-assessed", "rule": "guard-band", "tolerance_rel": 1e-5}],
        "axes": {"outer": {"rates": [
            {"set_rate_dps": 50.0, "rate_error_rel": 1e-7, "rate_error_u_rel": 4e-8,
             "rate_instability_rel": 2e-8, "rate_instability_u_rel": 3e-8,
             "rate_instability_resolved": False, "rate_instability_upper_rel": 7.3e-8}]}}}
    (sig,) = [f for f in figures_of(ResultFrame.of(result)) if f.quantity == "rate_instability_rel"]
    assert sig.is_limit and sig.value == 7.3e-8 and sig.u is None
    assert sig.verdict == "not-assessed"
    (err,) = [f for f in figures_of(ResultFrame.of(result)) if f.quantity == "rate_error_rel"]
    assert not err.is_limit and err.u == 4e-8
    day = dt.datetime(2026, 1, 1)
    png = trend_png([TrendPoint("a", day, "C-1", None, sig), TrendPoint("a", day, "C-1",
                                                                          None, err)])
    assert png is not None and png[:4] == b"\x89PNG"


def test_a_run_without_any_reachable_database_still_completes(tmp_path: Path) -> None:
    """Records named at a port nobody listens on: the run warns and is complete."""
    with socket_port() as port:
        url = f"postgresql://bench@127.0.0.1:{port}/records"
    proc, _ = _procedure(tmp_path, BIAS_REL[0], seed=51)
    out = bench("run", str(proc), "--yes", "--out", str(tmp_path / "runs"), "--records", url)
    run_dir = _run_dir(out)
    assert "cannot check the due date" in out.stderr
    assert "the run was not registered" in out.stderr
    assert (run_dir / "certificate.pdf").is_file()
    assert "History of this table" not in (run_dir / "certificate.html").read_text()
    assert dt.date.today().isoformat()  # the run's own date is today's, nothing to fake


class socket_port:
    """A port that was free a moment ago (nothing listens on it)."""

    def __enter__(self) -> int:
        import socket

        self.s = socket.socket()
        self.s.bind(("127.0.0.1", 0))
        return int(self.s.getsockname()[1])

    def __exit__(self, *exc: object) -> None:
        self.s.close()
