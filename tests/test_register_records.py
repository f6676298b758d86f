"""The records a lab keeps in its register (issue 55): withdrawal without a re-issue, every
calibration of an item with how it was found, deviations with limits that can be revoked,
and items that are identified but never calibrated.

On a real SQLite register (tests/registers.py); the runs are real runs on the twins (a
one-rate ladder, about 12 s) and the session's demo run, copied; the station through its
WSGI application; a real stand pointed at `bench sim` for the identity-only drive.
"""

from __future__ import annotations

import datetime as dt
import json
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest

from bench.app.register import AuthError, Register, RegisterError
from bench.app.register.gate import start_gate
from bench.core.config import Traced
from tests.conftest import ROOT, cli
from tests.registers import authorise, cli_in, lab_file, password, sqlite_register

TODAY = dt.datetime.now(dt.UTC).date()
QM = "Q. Manager"


def _quality(reg: Register) -> Any:
    return reg.authenticate(QM, password(QM), "quality")


def _traced(serial: str) -> Traced:
    return Traced("axes.outer.counter", "counter (outer)", None, None, None, None,
                  serial=serial)


# -- 1. a certificate withdrawn without a re-issue ---------------------------------------------

def test_a_withdrawn_certificate_reads_withdrawn_everywhere(demo_run: Any,
                                                             tmp_path: Path) -> None:
    from bench.app.records.extract import run_uid
    from bench.app.station.app import StationSettings, create_app

    assert demo_run.status == 0, demo_run.stderr[-3000:]
    run = demo_run.copy_to(tmp_path / "runs")
    url = sqlite_register(tmp_path / "reg")
    lab = lab_file(tmp_path / "lab", url)
    assert authorise(run, "P. Petrov", lab).returncode == 0
    with Register.open(url, migrate=False) as reg:
        number = reg.number_of_run(run_uid(json.loads((run / "meta.json").read_text()),
                                           run.name))
    assert number is not None
    why = "The customer's table serial was recorded wrongly on the certificate."
    args = ("register", "withdraw", number, "--register", url, "--password-stdin")
    refused = cli_in(password("A. Ivanova") + "\n", *args, "--reason", why,
                     "--as", "A. Ivanova")
    assert refused.returncode == 2 and "neither the quality nor the signatory" in refused.stderr
    refused = cli_in(password(QM) + "\n", *args, "--reason", ".", "--as", QM)
    assert refused.returncode == 2 and "in a sentence" in refused.stderr
    done = cli_in(password(QM) + "\n", *args, "--reason", why, "--as", QM)
    assert done.returncode == 0, done.stderr
    again = cli_in(password(QM) + "\n", *args, "--reason", why, "--as", QM)
    assert again.returncode == 2 and "withdrawn already" in again.stderr
    issued = run / "issued" / number
    for name in ("certificate.pdf", "certificate.dcc.xml"):
        got = cli("verify", str(issued / name), "--register", url, "--no-result")
        assert got.returncode == 1, got.stdout
        assert f"withdrawn: certificate {number}" in got.stdout
        assert f"by {QM}: {why}" in got.stdout and "verify: OK" not in got.stdout
    with Register.open(url, migrate=False) as reg:
        assert any(r.action == "withdrawn" and r.actor == QM for r in reg.audit_rows())
    # the station's run page
    page = create_app(StationSettings(run.parent, "t0ken", register_url=url)).test_client() \
        .get(f"/run/{run.name}").get_data(as_text=True)
    assert f"Withdrawn: certificate {number}" in page and why.replace("'", "&#39;") in page
    # the records' history
    serial = json.loads((run / "result.json").read_text())["stand"]["serial"]
    assert cli("records", "import", str(run.parent)).returncode == 0
    hist = cli("history", serial, "--runs", str(run.parent), "--lab", str(lab))
    assert hist.returncode == 0, hist.stderr
    assert "certificate: WITHDRAWN" in hist.stdout and why in hist.stdout


# -- 2. recalibration: a history, each record with its as-found status ------------------------

def _mini(folder: Path, stand: Path) -> Path:
    proc = folder / "mini.yaml"
    proc.write_text(f"procedure: rate-ladder\ntitle: recalibration check\nstand: {stand}\n"
                    "turns: 2\nstatic_record_s: 2\nprompts: false\nmains_hz: 50\n"
                    "axes:\n  outer:\n    rates_dps: [50]\n")
    return proc


def _traceability(run: Path) -> str:
    """The traceability table's row of the outer counter, as the certificate prints it."""
    from lxml import html

    doc = html.fromstring((run / "certificate.html").read_text(encoding="utf-8"))
    rows = [" ".join(tr.text_content().split()) for tr in doc.iter("tr")]
    return " | ".join(r for r in rows if r.startswith("counter keysight-53230a (outer)"))


def test_runs_before_and_after_a_recalibration_print_the_record_in_force(
        tmp_path: Path) -> None:
    url = sqlite_register(tmp_path / "reg")
    with Register.open(url, migrate=False) as reg:
        reg.add_equipment(_quality(reg), "MY62000117", "Keysight 53230A", "C-OLD-117",
                          "Cal Lab", TODAY + dt.timedelta(days=300))
    lab = lab_file(tmp_path / "lab", url)
    stand = tmp_path / "stand.yaml"
    text = (ROOT / "configs" / "stands" / "sim-two-axis.yaml").read_text()
    stand.write_text(text.replace('model: keysight-53230a,', 'model: keysight-53230a, '
                                  'serial: MY62000117,', 1))
    proc = _mini(tmp_path, stand)

    def run(out: str) -> Path:
        done = cli("run", str(proc), "--lab", str(lab), "--yes", "--quiet", "--out",
                   str(tmp_path / out))
        assert done.returncode == 0, done.stdout + done.stderr[-3000:]
        return Path(done.stdout.strip().splitlines()[-1])

    before = run("before")
    table = _traceability(before)
    assert "C-OLD-117" in table and "SIM-CAL-53230A-0117" not in table, table
    assert "stand file disagrees with the inventory" in (before / "certificate.html"
                                                         ).read_text()
    done = cli_in(password(QM) + "\n", "register", "equipment", "update", "MY62000117",
                  "--certificate", "C-NEW-117", "--issuer", "Cal Lab 2", "--due",
                  (TODAY + dt.timedelta(days=365)).isoformat(), "--found", "out",
                  "--found-error", "3e-7,1e-8", "--register", url, "--as", QM,
                  "--password-stdin")
    assert done.returncode == 0, done.stderr
    after = run("after")
    table = _traceability(after)
    assert "C-NEW-117" in table and "Cal Lab 2" in table and "C-OLD-117" not in table
    # the earlier run, analysed again, keeps the calibration in force when it ran
    assert cli("analyze", str(before)).returncode == 0
    assert "C-OLD-117" in _traceability(before)
    hist = cli("register", "equipment", "history", "MY62000117", "--register", url)
    assert hist.returncode == 0, hist.stderr
    lines = [ln for ln in hist.stdout.splitlines() if "calibrated" in ln]
    assert len(lines) == 2 and "C-OLD-117" in lines[0] and "C-NEW-117" in lines[1]
    assert "found OUT of tolerance, as-found error 3e-07 +/- 1e-08" in lines[1]
    # by date: the record in force is the latest calibrated on or before the day (the
    # update's day, not the module's TODAY: a run across midnight UTC dates it a day later)
    today = dt.datetime.now(dt.UTC).date()
    with Register.open(url, migrate=False) as reg:
        [item] = reg.equipment("MY62000117")
    older = item.in_force(today - dt.timedelta(days=1))
    assert older is not None and older.certificate == "C-OLD-117"
    now = item.in_force(today)
    assert now is not None and now.certificate == "C-NEW-117" and now.found == "out"
    gate = start_gate(url, [_traced("MY62000117")], simulated=False, operator=None,
                      password=str, on=today - dt.timedelta(days=1))
    assert gate.equipment[0]["certificate"] == "C-OLD-117"


# -- 3. deviations: only for an overdue item, limited, with a reason; revocable ---------------

def test_bad_deviations_are_refused_and_a_revoked_one_covers_nothing(tmp_path: Path) -> None:
    url = sqlite_register(tmp_path)
    soon = TODAY + dt.timedelta(days=10)
    reason = "Recalibration is booked; the check standard agrees within its limit."
    with Register.open(url, migrate=False) as reg:
        q = _quality(reg)
        reg.add_equipment(q, "LATE-1", "Keysight 53230A", "C-2024-1", "Cal Lab",
                          dt.date(2025, 1, 31))
        reg.add_equipment(q, "FINE-1", "Keysight 53230A", "C-2026-2", "Cal Lab",
                          dt.date(2040, 1, 1))
        for serial, expires, why, said in (
                ("LATE-1", dt.date(2099, 12, 31), reason, "more than 30 days"),
                ("LATE-1", dt.date(2001, 1, 1), reason, "not in the future"),
                ("LATE-1", TODAY, reason, "not in the future"),
                ("LATE-1", soon, ".", "in a sentence"),
                ("LATE-1", soon, "booked", "in a sentence"),
                ("FINE-1", soon, reason, "is in date"),
                ("NOWHERE", soon, reason, "not in the inventory")):
            with pytest.raises(RegisterError, match=said):
                reg.add_deviation(q, serial, why, expires)
        with pytest.raises(AuthError):
            reg.add_deviation(reg.authenticate("P. Petrov", password("P. Petrov")),
                              "LATE-1", reason, soon)
        gate = start_gate(url, [_traced("LATE-1")], simulated=False, operator=None,
                          password=str, on=TODAY)
        assert gate.refusal and "was due 2025-01-31" in gate.refusal[0]
        reg.add_deviation(q, "LATE-1", reason, soon)
        gate = start_gate(url, [_traced("LATE-1")], simulated=False, operator=None,
                          password=str, on=TODAY)
        assert gate.refusal == [] and reason in str(gate.equipment[0]["deviation"])
    done = cli_in(password(QM) + "\n", "register", "equipment", "deviation", "LATE-1",
                  "--revoke", "--register", url, "--as", QM, "--password-stdin")
    assert done.returncode == 0, done.stderr
    gate = start_gate(url, [_traced("LATE-1")], simulated=False, operator=None,
                      password=str, on=TODAY)
    assert gate.refusal and "was due 2025-01-31" in gate.refusal[0]
    done = cli_in(password(QM) + "\n", "register", "equipment", "deviation", "LATE-1",
                  "--revoke", "--register", url, "--as", QM, "--password-stdin")
    assert done.returncode == 2 and "no deviation in force" in done.stderr
    hist = cli("register", "equipment", "history", "LATE-1", "--register", url)
    assert "REVOKED" in hist.stdout and "OVERDUE" in hist.stdout
    with Register.open(url, migrate=False) as reg:
        acts = [r.action for r in reg.audit_rows() if r.object == "LATE-1"]
    assert acts.count("deviation recorded") == 1 and acts.count("deviation revoked") == 1


# -- 4. identity-only items: a drive is identified, never calibrated --------------------------

def test_identity_only_items_are_never_overdue(tmp_path: Path) -> None:
    url = sqlite_register(tmp_path)
    add = ("register", "equipment", "add", "41001", "--model", "Simulated CiA 402 drive",
           "--register", url, "--as", QM, "--password-stdin")
    refused = cli_in(password(QM) + "\n", *add)
    assert refused.returncode == 2 and "--identity-only" in refused.stderr
    done = cli_in(password(QM) + "\n", *add, "--identity-only")
    assert done.returncode == 0, done.stderr
    listed = cli("register", "equipment", "list", "--register", url)
    row = next(ln for ln in listed.stdout.splitlines() if ln.startswith("41001"))
    assert "identity only (no calibration)" in row and "none" not in row.lower().split()[2]
    with Register.open(url, migrate=False) as reg:
        q = _quality(reg)
        with pytest.raises(RegisterError, match="identity-only"):
            reg.add_deviation(q, "41001", "A deviation for a drive makes no sense at all.",
                              TODAY + dt.timedelta(days=5))
        with pytest.raises(RegisterError, match="identity-only"):
            reg.update_equipment(q, "41001", "C-1", "Lab", TODAY + dt.timedelta(days=90))
    for day in (TODAY, dt.date(2099, 1, 1)):
        gate = start_gate(url, [_traced("41001")], simulated=False, operator=None,
                          password=str, on=day)
        assert gate.refusal == [] and gate.equipment[0]["identity_only"] == "yes"


def test_a_real_stand_with_an_identity_only_drive_starts(tmp_path: Path) -> None:
    """Issue 40's set-up: a stand without `sim:` pointing at `bench sim` is a real stand.
    The counter and the drive state their serials; the inventory holds the counter in date
    and the drive as identity-only: the run starts (and is stopped by SIGINT)."""
    from tests.test_simserve import SimProcess, _real_stand

    sim = SimProcess()
    try:
        sim.read_lines(6)
        stand = _real_stand(sim, tmp_path / "stand.yaml", " level_v: 2.5, serial: MY62000117,")
        stand.write_text(stand.read_text().replace("node_id: 2,", "node_id: 2, serial: '41001',"))
        url = sqlite_register(tmp_path / "reg")
        lab = lab_file(tmp_path / "lab", url)
        proc = tmp_path / "ladder.yaml"
        proc.write_text(f"procedure: rate-ladder\ntitle: identity-only drive\nstand: {stand}\n"
                        "turns: 2\nstatic_record_s: 2\nprompts: false\nmains_hz: 50\n"
                        "axes:\n  table:\n    rates_dps: [50]\n")
        with Register.open(url, migrate=False) as reg:
            reg.add_equipment(_quality(reg), "MY62000117", "Keysight 53230A", "C-2026-117",
                              "Cal Lab", TODAY + dt.timedelta(days=200))
        cmd = [sys.executable, "-m", "bench", "run", str(proc), "--lab", str(lab), "--yes",
               "--out", str(tmp_path / "runs")]
        out = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=120)
        assert out.returncode == 2 and "41001" in out.stderr and "not in the lab's" \
            in out.stderr, out.stderr          # the drive unknown: refused
        shutil.rmtree(tmp_path / "runs", ignore_errors=True)
        assert cli_in(password(QM) + "\n", "register", "equipment", "add", "41001",
                      "--model", "CiA 402 drive", "--identity-only", "--register", url,
                      "--as", QM, "--password-stdin").returncode == 0
        p = subprocess.Popen(cmd, cwd=ROOT, text=True, stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE)
        try:
            deadline = time.monotonic() + 90
            started = False
            while time.monotonic() < deadline and p.poll() is None and not started:
                logs = list((tmp_path / "runs").glob("*/events.jsonl"))
                started = bool(logs) and '"step_start"' in logs[0].read_text()
                time.sleep(0.2)
            assert started, (p.poll(), p.stderr.read() if p.poll() is not None and p.stderr
                             else "")
        finally:
            if p.poll() is None:
                p.send_signal(signal.SIGINT)
                p.wait(timeout=60)
        events = (next((tmp_path / "runs").glob("*/events.jsonl"))).read_text()
        assert '"refused"' not in events
        meta = json.loads(next((tmp_path / "runs").glob("*/meta.json")).read_text())
        drive = next(s for s in meta["equipment_status"] if s["serial"] == "41001")
        assert drive["problem"] is None and drive["identity_only"] == "yes"
    finally:
        sim.stop()
