"""People, not the bench, hold the authority (issue 53): the register service is the one
process that checks a person's password and issues; the benches' and the station's
database roles only read.

Against a real PostgreSQL the test starts (tests/pg_server.py) with separate roles for the
owner, the service, two benches and the station, and the service itself started as
`bench register serve` on 127.0.0.1. Each finding of the issue is reproduced as the
attacker would try it (the bench's database role, raw HTTP with the bench's network
access, guessed passwords) and shown refused or recorded.
"""

from __future__ import annotations

import concurrent.futures
import contextlib
import datetime as dt
import json
import os
import stat
import subprocess
import sys
import time
import urllib.error
import urllib.request
import uuid
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
import sqlalchemy as sa

from bench.app.register import AuthError, Register, RegisterError
from bench.app.register.client import ServiceRegister
from bench.app.register.store import MEANING_ISSUE
from tests.conftest import ROOT
from tests.registers import ACCOUNTS, ISSUER, cli_in, enrol, password, sqlite_register

DIGESTS = {"result.json": "a" * 64, "certificate.pdf": "b" * 64,
           "certificate.dcc.xml": "c" * 64, "certificate.html": "d" * 64}
LOCK_S = 3          # the lock, shortened for the test (a register setting, audited)


@dataclass
class Lab:
    owner: str          # database URLs, one per role
    service: str
    hall1: str
    hall2: str
    station: str
    url: str            # the service
    roles: dict[str, str]


def _engine(url: str) -> sa.Engine:
    return sa.create_engine(url.replace("postgresql://", "postgresql+psycopg://"))


@pytest.fixture(scope="module")
def lab(pg: Any) -> Iterator[Lab]:
    sfx = uuid.uuid4().hex[:8]
    roles = {k: f"{k}_{sfx}" for k in ("svc", "hall1", "hall2", "station")}
    owner = pg.create_database(f"register_{sfx}")
    pg.admin(*(f'CREATE ROLE "{r}" LOGIN' for r in roles.values()))
    done = cli_in(password("admin") + "\n", "register", "init", owner, "--admin", "admin",
                  "--service-role", roles["svc"], "--bench-role", roles["hall1"],
                  "--bench-role", roles["hall2"], "--station-role", roles["station"],
                  "--password-stdin")
    assert done.returncode == 0, done.stderr
    with Register.open(owner) as reg:
        admin = reg.authenticate("admin", password("admin"), "admin")
        for name, (pw, rl, full, function) in ACCOUNTS.items():
            if name != "admin":
                reg.add_account(admin, name, full, rl, pw + "-initial", function)
                reg.change_password(name, pw + "-initial", pw)
        reg.set_setting(admin, "lockout_s", str(LOCK_S))
        for key, value in ISSUER.items():
            reg.set_setting(admin, key, value)
    as_role = {k: owner.replace(f"//{pg.user}@", f"//{r}@") for k, r in roles.items()}
    with _service(as_role["svc"]) as url:
        yield Lab(owner, as_role["svc"], as_role["hall1"], as_role["hall2"],
                  as_role["station"], url, roles)


@contextlib.contextmanager
def _service(db: str, *args: str, env: dict[str, str] | None = None) -> Iterator[str]:
    """`bench register serve` on a free port of 127.0.0.1; yields its URL."""
    proc = subprocess.Popen([sys.executable, "-m", "bench", "register", "serve", "--db", db,
                             "--port", "0", *args], cwd=ROOT, text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            env={**os.environ, **(env or {})})
    try:
        assert proc.stdout is not None
        line = proc.stdout.readline()
        assert line.startswith("register service on http://127.0.0.1:"), \
            line + (proc.stderr.read() if proc.stderr else "")
        yield line.split()[3]
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:     # a SIGTERM inherited as ignored
            proc.kill()
            proc.wait(timeout=10)


def _post(url: str, op: str, **body: object) -> tuple[int, Any]:
    """Raw HTTP, as anyone with the bench's network access could send it."""
    req = urllib.request.Request(f"{url}/v1/{op}", data=json.dumps(body).encode(),
                                 method="POST", headers={"Content-Type": "application/json",
                                                         "X-Ratebench-Via": "bench hall-1"})
    try:
        with urllib.request.urlopen(req, timeout=30) as r:
            return r.status, json.loads(r.read())
    except urllib.error.HTTPError as e:
        return e.code, json.loads(e.read())


# -- 1. the benches' and the station's roles forge nothing ---------------------------------

FORGERIES = (
    "SELECT reg_issue('RT-2026-00001', 1, 'P. Petrov', 'authorised for issue', '', "
    "'2020-01-01T00:00:00Z', 'a', 'b', 'c', 'd', '{}')",
    "SELECT reg_allocate('run-forged', 'ACME-ACCREDITED', 'nobody-at-all')",
    "SELECT reg_audit_append('quality1', 'deviation recorded', 'x', '')",
    "SELECT password_hash FROM reg_accounts",
    "SELECT * FROM reg_accounts",
    "SELECT * FROM reg_logins",
    "UPDATE reg_accounts SET roles = 'admin,signatory'",
    "INSERT INTO reg_accounts (name, full_name, roles, password_hash, created_utc) "
    "VALUES ('ghost', 'Ghost', 'signatory', 'x', 'now')",
    "INSERT INTO reg_revisions (number, revision, issued_utc, signatory, signatory_name, "
    "meaning, result_sha256, pdf_sha256, dcc_sha256, html_sha256) VALUES "
    "('RT-1', 2, 'not-a-date', 'P. Petrov', 'P. Petrov', 'reviewed only', 'a', 'b', 'c', 'd')",
    "UPDATE reg_revisions SET withdrawn_utc = 'now'",
    "INSERT INTO reg_audit VALUES (999, 'now', 'admin', 'account added', 'ghost', '', "
    "'x', 'y', 'z')",
    "DELETE FROM reg_audit", "UPDATE reg_audit_head SET seq = 1",
    "INSERT INTO reg_certificates VALUES ('X-1', 99, 'run-x', 'now')",
    "INSERT INTO reg_equipment VALUES ('S', 'm', 'c', 'i', '2099-01-01', 'n', 'x')",
    "INSERT INTO reg_settings VALUES ('lockout_attempts', '1000')",
    # issue 54: a run's record is the register's, written through the service only
    "INSERT INTO reg_runs (uid, bench, version, simulated, inputs, items, registered_utc, "
    "via, raw) VALUES ('forged', 'b', '0', false, '{}', '[]', '2020-01-01', 'x', '{}')",
    "UPDATE reg_runs SET result = '{}', result_sha256 = 'x'",
    "DELETE FROM reg_runs",
    "INSERT INTO reg_run_events (uid, utc, kind, detail) VALUES ('x', 'now', 'start', '{}')",
)


@pytest.mark.parametrize("who", ["hall1", "hall2", "station"])
def test_bench_and_station_roles_are_refused_by_the_server(lab: Lab, who: str) -> None:
    eng = _engine(getattr(lab, who))
    try:
        for q in FORGERIES:
            with pytest.raises(sa.exc.ProgrammingError, match="permission denied"), \
                    eng.begin() as c:
                c.exec_driver_sql(q)
        with eng.connect() as c:        # reading what a bench needs still works
            names = {r[0] for r in c.exec_driver_sql("SELECT name FROM reg_accounts")}
            c.exec_driver_sql("SELECT * FROM reg_revisions").all()
        assert "P. Petrov" in names
    finally:
        eng.dispose()
    # and the register library, pointed at the database with that role, says why
    with Register.open(getattr(lab, who), migrate=False) as reg, \
            pytest.raises(RegisterError, match="cannot check passwords"):
        reg.authenticate("P. Petrov", password("P. Petrov"), "signatory")


def test_the_service_stores_no_client_time_meaning_or_actor(lab: Lab) -> None:
    # without a login nothing is allocated, issued or appended
    for op, body in (("allocate", {"run_uid": "r", "prefix": "RT"}),
                     ("issue", {"number": "RT-2026-00001", "revision": 1, "digests": DIGESTS,
                                "detail": {}}),
                     ("append", {"action": "control review", "object": "x"})):
        code, got = _post(lab.url, op, **body)
        assert code == 403 and got["kind"] == "auth", (op, got)
    code, got = _post(lab.url, "authenticate", name="P. Petrov",
                      password=password("P. Petrov"), role="signatory")
    assert code == 200
    token = got["ok"]["token"]
    # the audit trail is the register's: a client appends only its two actions
    for action in ("issue", "account added", "deviation recorded", "authenticated"):
        code, got = _post(lab.url, "append", token=token, action=action, object="ghost")
        assert code == 409 and "a client adds only" in got["error"]
    code, number = _post(lab.url, "allocate", token=token, run_uid="run-claims",
                         prefix="RT", actor="nobody-at-all")
    assert code == 200
    number = number["ok"]
    before = dt.datetime.now(dt.UTC)
    code, got = _post(lab.url, "issue", token=token, number=number, revision=1,
                      digests=DIGESTS, reason="", detail={"run_dir": "x"},
                      issued_utc="2020-01-01T00:00:00Z", meaning="reviewed only",
                      signatory="admin", signatory_name="Somebody Else")
    assert code == 200, got
    rev = got["ok"]
    issued = dt.datetime.strptime(rev["issued_utc"], "%Y-%m-%dT%H:%M:%SZ").replace(
        tzinfo=dt.UTC)
    assert abs((issued - before).total_seconds()) < 60      # the service's clock
    assert rev["meaning"] == MEANING_ISSUE
    assert rev["signatory"] == "P. Petrov" and rev["signatory_name"] == "P. Petrov"
    with Register.open(lab.owner, migrate=False) as reg:
        rows = reg.audit_rows()
    alloc = next(r for r in rows if r.action == "number allocated" and r.object == number)
    assert alloc.actor == "P. Petrov" and alloc.db_user == lab.roles["svc"]
    entry = next(r for r in rows if r.action == "issue" and str(r.object)
                 .startswith(number))
    assert entry.actor == "P. Petrov" and entry.db_user == lab.roles["svc"]
    assert json.loads(str(entry.detail))["via"] == "bench hall-1 at 127.0.0.1"
    # a successful signatory login is in the trail too
    assert any(r.action == "authenticated" and r.actor == "P. Petrov" for r in rows)


# -- 2. guessing is limited where the password is checked -----------------------------------

def _actions(lab: Lab, name: str) -> list[str]:
    with Register.open(lab.owner, migrate=False) as reg:
        return [str(r.action) for r in reg.audit_rows() if r.object == name]


def test_the_sixth_attempt_meets_a_lock_even_with_the_right_password(lab: Lab) -> None:
    name = "A. Tester"
    reg = ServiceRegister.connect(lab.url, "bench hall-2")
    with reg:
        messages = []
        for i in range(5):
            with pytest.raises(AuthError) as e:
                reg.authenticate(name, f"guess-number-{i}", "signatory")
            messages.append(str(e.value))
        assert "now locked until" in messages[-1] and "locked" not in messages[0]
        with pytest.raises(AuthError, match="locked after 5 failed attempts"):
            reg.authenticate(name, password(name), "signatory")
        time.sleep(LOCK_S + 0.5)
        assert reg.authenticate(name, password(name), "signatory").name == name
    acts = _actions(lab, name)
    assert acts.count("authentication refused") == 6 and acts.count("account locked") == 1
    assert acts.index("account locked") < acts.index("account unlocked") \
        < len(acts) - 1 - acts[::-1].index("authenticated")


def test_the_command_line_is_locked_out_too(lab: Lab) -> None:
    name = "Q. Manager"
    args = ("register", "equipment", "list", "--register", lab.url)
    assert cli_in("", *args).returncode == 0
    for i in range(5):
        done = cli_in(f"wrong-{i}-password\n", "register", "equipment", "deviation", "SER-1",
                      "--reason", "Recalibration is booked for next week.", "--expires",
                      "2026-12-31", "--register", lab.url, "--as", name, "--password-stdin")
        assert done.returncode == 2 and "wrong password" in done.stderr
    assert "now locked" in done.stderr
    done = cli_in(password(name) + "\n", "register", "equipment", "deviation", "SER-1",
                  "--reason", "x", "--expires", "2026-12-31", "--register", lab.url,
                  "--as", name, "--password-stdin")
    assert done.returncode == 2 and "locked after 5 failed attempts" in done.stderr
    time.sleep(LOCK_S + 0.5)


# -- 3. the account lifecycle -----------------------------------------------------------------

def test_account_lifecycle_through_the_service(lab: Lab) -> None:
    reg = ServiceRegister.connect(lab.url, "bench hall-1")
    with reg:
        admin = reg.authenticate("admin", password("admin"), "admin")
        for bad, why in (("12345678", "at least 12"), ("password1234", "most common"),
                         ("kpopov-is-my-name", "account's name")):
            with pytest.raises(RegisterError, match=why):
                reg.add_account(admin, "kpopov", "K. Popov", ["signatory"], bad)
        with pytest.raises(RegisterError, match="already printed under signatures"):
            reg.add_account(admin, "admin2", "P. Petrov", ["signatory"], "a-long-fresh-phrase")
        with pytest.raises(RegisterError, match="never held by one account"):
            reg.add_account(admin, "boss", "B. Oss", ["admin", "signatory"], "a-long-phrase-9")
        with pytest.raises(RegisterError, match="never held by one account"):
            reg.set_role(admin, "admin", "signatory", grant=True)
        reg.add_account(admin, "kpopov", "K. Popov", ["signatory"], "set-by-the-admin-7")
        # the admin knows this password: it opens only its own change
        with pytest.raises(AuthError, match="set by an admin"):
            reg.authenticate("kpopov", "set-by-the-admin-7", "signatory")
    done = cli_in("set-by-the-admin-7\nmy-own-secret-phrase\n", "register", "user", "passwd",
                  "kpopov", "--as", "kpopov", "--register", lab.url, "--password-stdin")
    assert done.returncode == 0, done.stderr
    reg = ServiceRegister.connect(lab.url)
    with reg:
        assert reg.authenticate("kpopov", "my-own-secret-phrase", "signatory").name == "kpopov"
        admin = reg.authenticate("admin", password("admin"), "admin")
        reg.set_active(admin, "kpopov", False)
        with pytest.raises(AuthError):
            reg.authenticate("kpopov", "my-own-secret-phrase")
        reg.set_active(admin, "kpopov", True)
        reg.set_role(admin, "kpopov", "reviewer", grant=True)
        reg.set_role(admin, "kpopov", "reviewer", grant=False)
        # an expired password: older than the register's maximum age
        eng = _engine(lab.owner)
        with eng.begin() as c:
            c.exec_driver_sql("UPDATE reg_accounts SET password_changed_utc = "
                              "'2020-01-01T00:00:00.000000Z' WHERE name = 'kpopov'")
        eng.dispose()
        with pytest.raises(AuthError, match="older than 180 days"):
            reg.authenticate("kpopov", "my-own-secret-phrase", "signatory")
    acts = _actions(lab, "kpopov")
    for a in ("account added", "password changed", "account disabled", "account enabled",
              "role granted", "role revoked"):
        assert a in acts, (a, acts)
    with Register.open(lab.owner, migrate=False) as own:
        rows = [r for r in own.audit_rows() if r.object == "kpopov"]
    granted = json.loads(str(next(r for r in rows if r.action == "role granted").detail))
    assert granted["old"] == ["signatory"] and granted["new"] == ["reviewer", "signatory"]


# -- 4. twelve issuers at once, through the service --------------------------------------------

def test_twelve_concurrent_issuers_through_the_service(lab: Lab) -> None:
    def one(i: int) -> str:
        with ServiceRegister.connect(lab.url, f"bench {i}") as reg:
            signer = reg.authenticate("P. Petrov", password("P. Petrov"), "signatory")
            number = reg.allocate(f"concurrent-{i}", "RT", signer.name)
            reg.begin_issue(signer, number)
            reg.issue(number, 1, signer, DIGESTS, None, {"run_dir": f"r{i}"})
            return number

    with concurrent.futures.ThreadPoolExecutor(12) as pool:
        numbers = list(pool.map(one, range(12)))
    assert len(set(numbers)) == 12
    with Register.open(lab.owner, migrate=False) as reg:
        report = reg.audit_check()
        assert report.ok, report.problems
        for n in numbers:
            assert [r.revision for r in reg.revisions(n)] == [1]


def test_an_unreachable_service_refuses(tmp_path: Path) -> None:
    done = cli_in("x\n", "register", "user", "list", "--register", "http://127.0.0.1:9")
    assert done.returncode == 2 and "cannot be reached" in done.stderr


# -- one bench without a server: the SQLite register ---------------------------------------

def test_sqlite_register_is_readable_by_its_owner_alone(tmp_path: Path) -> None:
    path = tmp_path / "reg" / "register.sqlite"
    done = cli_in(password("admin") + "\n", "register", "init", f"sqlite:///{path}",
                  "--admin", "admin", "--password-stdin")
    assert done.returncode == 0, done.stderr
    assert stat.S_IMODE(os.stat(path).st_mode) == 0o600
    # a command that reads a register never creates one
    missing = tmp_path / "nowhere" / "register.sqlite"
    done = cli_in("", "register", "audit", "--register", f"sqlite:///{missing}")
    assert done.returncode == 2 and "no such file" in done.stderr and not missing.exists()


def test_sqlite_register_locks_out_guessing(tmp_path: Path) -> None:
    url = sqlite_register(tmp_path)
    with Register.open(url, migrate=False) as reg:
        admin = reg.authenticate("admin", password("admin"), "admin")
        reg.set_setting(admin, "lockout_s", "2")
        for i in range(5):
            with pytest.raises(AuthError):
                reg.authenticate("P. Petrov", f"guess-{i}-guess")
        with pytest.raises(AuthError, match="locked"):
            reg.authenticate("P. Petrov", password("P. Petrov"))
        time.sleep(2.5)
        assert reg.authenticate("P. Petrov", password("P. Petrov")).name == "P. Petrov"
        changed = next(r for r in reg.audit_rows() if r.action == "setting changed"
                       and r.object == "lockout_s")
        assert json.loads(str(changed.detail)) == {"old": "900 (default)", "new": "2"}


# -- the station: sign through the service in a browser; guessing limited there too ---------

def _login_form(base: str, name: str, pw: str, token: str | None = None) -> tuple[int, str,
                                                                                  str]:
    """GET /login, then POST it (a form's token once, unless `token` replays one)."""
    import re
    import urllib.parse

    with urllib.request.urlopen(f"{base}/login", timeout=30) as r:
        page = r.read().decode()
    fresh = re.search(r'name="token" value="([^"]+)"', page)
    assert fresh, page[-500:]
    used = token or fresh.group(1)
    req = urllib.request.Request(f"{base}/login", method="POST", data=urllib.parse.urlencode(
        {"name": name, "password": pw, "token": used, "next": "/"}).encode())
    try:
        with urllib.request.urlopen(req, timeout=30) as r:
            return r.status, r.read().decode(), used
    except urllib.error.HTTPError as e:
        return e.code, e.read().decode(), used


@pytest.mark.timeout(300)
def test_the_station_signs_through_the_service_and_cannot_issue_itself(
        lab: Lab, demo_run: Any, tmp_path: Path) -> None:
    from selenium.webdriver.common.by import By

    from bench.app.records.extract import run_uid
    from tests.conftest import unavailable
    from tests.test_station import _browser, _chromium, _stop, _wait

    found = _chromium()
    if found is None:
        unavailable("chromium and chromium-driver are not installed (Debian packages "
                    "`chromium chromium-driver`; .ci/run installs them)")
    assert demo_run.status == 0, demo_run.stderr[-3000:]
    run = demo_run.copy_to(tmp_path / "runs")
    lab_yaml = tmp_path / "lab.yaml"
    lab_yaml.write_text(f"laboratory: Service Lab\nregister: {lab.url}\n")
    enrol(run, lab.url)     # registered through the service, as at the run's start
    env = {k: v for k, v in os.environ.items() if k != "BENCH_LAB_SETTINGS"}
    proc = subprocess.Popen([sys.executable, "-m", "bench", "serve", "--runs",
                             str(run.parent), "--port", "0", "--token", "t0ken-for-stop",
                             "--lab", str(lab_yaml)], cwd=ROOT, text=True, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    driver = None
    try:
        assert proc.stdout is not None
        first = proc.stdout.readline()
        base = first.split(" on ")[-1].strip().rstrip("/")
        assert base.startswith("http://127.0.0.1:"), first + proc.stdout.read()
        # a replayed login form is refused; guessing at the station meets the register's lock
        code, page, used = _login_form(base, "A. Ivanova", "wrong-at-the-station")
        assert code == 401
        code, page, _ = _login_form(base, "A. Ivanova", password("A. Ivanova"), token=used)
        assert code == 403 and "expired" in page
        for i in range(4):
            code, page, _ = _login_form(base, "A. Ivanova", f"guess-{i}-at-the-station")
        assert code == 401 and "locked" in page
        code, page, _ = _login_form(base, "A. Ivanova", password("A. Ivanova"))
        assert code == 401 and "locked after 5 failed attempts" in page
        assert _actions(lab, "A. Ivanova").count("authentication refused") >= 6

        run_url = f"{base}/run/{run.name}"
        driver = _browser(found, height=1400)
        driver.get(run_url)
        driver.find_element(By.ID, "sign-login").click()
        driver.find_element(By.ID, "login-name").send_keys("P. Petrov")
        driver.find_element(By.ID, "login-password").send_keys(password("P. Petrov"))
        driver.find_element(By.ID, "login-submit").click()
        _wait(lambda: driver.current_url == run_url and driver.find_elements(By.ID, "who"),
              20, "the signatory's login back to the run's page")
        driver.find_element(By.ID, "sign-password").send_keys(password("P. Petrov"))
        driver.find_element(By.ID, "sign").click()
        title = _wait(lambda: next((e.text for e in driver.find_elements(By.ID, "sign-title")),
                                   None), 120, "the sign request's answer")
        assert title == "Issued", driver.find_element(By.TAG_NAME, "main").text
    finally:
        if driver is not None:
            driver.quit()
        _stop(proc)
    uid = run_uid(json.loads((run / "meta.json").read_text()), run.name)
    with Register.open(lab.owner, migrate=False) as reg:
        number = reg.number_of_run(uid)
        assert number is not None
        [rev] = reg.revisions(number)
        rows = reg.audit_rows()
    assert rev.signatory == "P. Petrov"
    issued = run / "issued" / number
    import hashlib
    assert rev.pdf_sha256 == hashlib.sha256((issued / "certificate.pdf").read_bytes()
                                            ).hexdigest()
    entry = next(r for r in rows if r.action == "issue" and str(r.object)
                 .startswith(number))
    assert entry.db_user == lab.roles["svc"]
    detail = json.loads(str(entry.detail))      # the run and the bench (issue 57)
    assert detail["run_uid"] == uid and detail["bench"] and "station" not in detail["bench"]
    # the station's own database role: unable to issue, allocate or append by itself
    eng = _engine(lab.station)
    try:
        for q in (f"SELECT reg_issue('{number}', 2, 'P. Petrov', 'authorised for issue', "
                  "'again', 'now', 'a', 'b', 'c', 'd', '{}')",
                  "SELECT reg_allocate('station-run', 'RT', 'P. Petrov')",
                  "SELECT reg_audit_append('P. Petrov', 'issue', 'x', '')"):
            with pytest.raises(sa.exc.ProgrammingError, match="permission denied"), \
                    eng.begin() as c:
                c.exec_driver_sql(q)
    finally:
        eng.dispose()


# -- 4. one bench's role writes only its own rows in the lab database -----------------------

def test_one_bench_role_cannot_write_another_benchs_rows(pg: Any) -> None:
    from tests.conftest import cli

    sfx = uuid.uuid4().hex[:8]
    r1, r2, st = f"hall1r_{sfx}", f"hall2r_{sfx}", f"stationr_{sfx}"
    owner = pg.create_database(f"records_{sfx}")
    pg.admin(*(f'CREATE ROLE "{r}" LOGIN' for r in (r1, r2, st)))
    done = cli("records", "init", owner, "--bench-role", r1, "--bench-role", r2,
               "--station-role", st)
    assert done.returncode == 0, done.stderr
    for name, role in (("hall-1", r1), ("hall-2", r2)):
        done = cli("records", "bench", "add", name, "--role", role, "--records", owner)
        assert done.returncode == 0, done.stderr
    as1, as2 = (_engine(owner.replace(f"//{pg.user}@", f"//{r}@")) for r in (r1, r2))
    try:
        with as1.begin() as c:      # hall-1 delivers its run and registers it
            c.exec_driver_sql("UPDATE benches SET host = 'h1' WHERE name = 'hall-1'")
            c.exec_driver_sql(
                "INSERT INTO bench_runs (bench_id, uid, run_dir, last_seq, title) SELECT id, "
                "'uid-1', 'run-1', 0, 'hall-1 run' FROM benches WHERE name = 'hall-1'")
            c.exec_driver_sql("INSERT INTO tables (maker, model, serial) "
                              "VALUES ('M', 'T', 'SER-RLS')")
            c.exec_driver_sql(
                "INSERT INTO runs (uid, table_id, kind, run_dir, registered_utc, verdict, "
                "simulated, aborted) SELECT 'uid-1', id, 'rate-ladder', 'run-1', now(), "
                "'PASS', false, false FROM tables WHERE serial = 'SER-RLS'")
        with as2.begin() as c:      # hall-2's role: changes nothing of hall-1's
            for q in ("UPDATE benches SET host = 'forged' WHERE name = 'hall-1'",
                      "UPDATE bench_runs SET title = 'forged'",
                      "UPDATE runs SET verdict = 'FAIL'", "DELETE FROM runs"):
                assert c.exec_driver_sql(q).rowcount == 0, q
        for q in ("INSERT INTO bench_events (run_id, seq, event, body) SELECT id, 99, "
                  "'forged', '{}' FROM bench_runs WHERE uid = 'uid-1'",
                  "INSERT INTO bench_runs (bench_id, uid, run_dir, last_seq) SELECT id, "
                  "'uid-x', 'x', 0 FROM benches WHERE name = 'hall-1'",
                  "INSERT INTO figures (run_id, axis, quantity, value, unit) SELECT id, 'a', "
                  "'q', 1, 'u' FROM runs WHERE uid = 'uid-1'",
                  "DELETE FROM bench_runs"):
            with pytest.raises(sa.exc.DBAPIError,
                               match="row-level security|violates|permission denied"), \
                    as2.begin() as c:
                c.exec_driver_sql(q)
        with as1.connect() as c:
            assert c.exec_driver_sql("SELECT title FROM bench_runs").scalar() == "hall-1 run"
            assert c.exec_driver_sql("SELECT verdict FROM runs").scalar() == "PASS"
            assert c.exec_driver_sql("SELECT host FROM benches WHERE name = 'hall-1'"
                                     ).scalar() == "h1"
    finally:
        as1.dispose()
        as2.dispose()


# -- issue 54: the register holds each run from its start, through the service -----------

def test_a_run_is_registered_through_the_service_and_issued_only_from_its_record(
        lab: Lab, demo_run: Any, tmp_path: Path) -> None:
    """The start gate registers the run through the service (no person's token: the entry
    names the bench and its address); its result and raw digests are delivered; a raw
    capture the register saw never changes; a run it never saw start is not issued."""
    from bench.app.register.gate import start_gate

    uid = uuid.uuid4().hex
    gate = start_gate(lab.url, [], True, None, lambda prompt: "", run_uid=uid,
                      bench="hall-1", inputs={"procedure.yaml": "1" * 64,
                                              "stand.yaml": "2" * 64})
    assert gate.refusal == []
    with Register.open(lab.url, migrate=False) as reg:
        rec = reg.run_record(uid)
        assert rec is not None and rec.bench == "hall-1"
        assert rec.via.endswith("at 127.0.0.1")       # who delivered it, as the service saw
        assert rec.inputs == {"procedure.yaml": "1" * 64, "stand.yaml": "2" * 64}
        rec = reg.deliver_result(uid, "session", b'{"verdict": "pass"}\n',
                                 {"raw/s1/outer-fog.bin": "3" * 64})
        assert rec.result_bytes == b'{"verdict": "pass"}\n'
        with pytest.raises(RegisterError, match="raw capture raw/s1/outer-fog.bin changed"):
            reg.deliver_result(uid, "analysis", b"{}", {"raw/s1/outer-fog.bin": "4" * 64})
        with pytest.raises(RegisterError, match="is registered already"):
            reg.register_run(uid, "hall-2", None, "0", True, {}, [])
    with Register.open(lab.owner, migrate=False) as reg:
        entries = [r for r in reg.audit_rows() if r.object == uid]
        assert [r.action for r in entries] == ["run registered", "run session result"]
        assert all('"via"' in str(r.detail) for r in entries)
    # the session's demo run, made without a register: never issued through the service
    assert demo_run.status == 0, demo_run.stderr[-3000:]
    run = demo_run.copy_to(tmp_path / "runs")
    meta = json.loads((run / "meta.json").read_text())      # a run of its own (other tests
    meta["run_uid"] = uuid.uuid4().hex                      # of this register issue copies
    (run / "meta.json").write_text(json.dumps(meta))        # of the demo run's uid)
    lab_yaml = tmp_path / "lab.yaml"
    lab_yaml.write_text(f"laboratory: Service Lab\nregister: {lab.url}\n")
    done = cli_in(password("P. Petrov") + "\n", "authorise", str(run), "--signatory",
                  "P. Petrov", "--lab", str(lab_yaml), "--password-stdin")
    assert done.returncode == 2 and "holds no record of this run" in done.stderr, \
        done.stderr
    assert not (run / "issued").exists()


# -- the DCC signing key lives with the service, never on the bench -------------------------

def test_the_service_alone_signs_the_issued_dcc(lab: Lab, demo_run: Any,
                                                tmp_path: Path) -> None:
    import hashlib

    from tests.conftest import cli
    from tests.test_dcc import _throwaway_key

    key, cert = _throwaway_key(tmp_path / "server-keys", "Service Lab DCC signing")
    with Register.open(lab.owner, migrate=False) as reg:
        reg.set_setting(reg.authenticate("admin", password("admin"), "admin"),
                        "dcc_signing_certificate_sha256",
                        hashlib.sha256(cert.read_bytes()).hexdigest())
    assert demo_run.status == 0, demo_run.stderr[-3000:]
    run = demo_run.copy_to(tmp_path / "runs")
    with _service(lab.service, "--signing-key", str(key), "--signing-certificate", str(cert),
                  "--signing-password-env", "SERVICE_KEY_PASSWORD",
                  env={"SERVICE_KEY_PASSWORD": "s3cret"}) as url:
        lab_yaml = tmp_path / "lab.yaml"        # the bench's lab file: no key in it
        lab_yaml.write_text(f"laboratory: Service Lab\nregister: {url}\n")
        enrol(run, url)         # registered through the service, as at the run's start
        from bench.app.records.extract import run_uid

        with Register.open(lab.owner, migrate=False) as reg:    # the session's one demo run
            again = reg.number_of_run(run_uid(json.loads((run / "meta.json").read_text()),
                                              run.name)) is not None     # may be issued
        done = cli_in(password("P. Petrov") + "\n", "authorise", str(run), "--signatory",
                      "P. Petrov", "--lab", str(lab_yaml), "--password-stdin",
                      *(("--reason", "re-issued with the DCC signed by the service") if again
                        else ()))
        assert done.returncode == 0, done.stdout + done.stderr
        assert "DCC signed (XAdES)" in done.stdout
    dcc = run / "certificate.dcc.xml"          # the issued revision, in place
    done = cli("verify", str(dcc), "--cert", str(cert))
    assert done.returncode == 0, done.stdout + done.stderr
    assert "signature: XAdES verifies; signer CN=Service Lab DCC signing" in done.stdout
    for f in run.rglob("*"):
        assert not f.is_file() or b"PRIVATE KEY" not in f.read_bytes(), f
    with Register.open(lab.owner, migrate=False) as reg:
        assert any(r.action == "DCC signed" and r.actor == "P. Petrov"
                   for r in reg.audit_rows())
