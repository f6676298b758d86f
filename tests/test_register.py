"""The lab register (issue 42): who may sign, which standards are valid, which certificate
numbers exist, and the audit trail, in a database the lab controls.

Each of the five findings of the quality manager's review, reproduced and now refused or
stated correctly; the register's own guarantees on a real PostgreSQL server the tests start
(tests/pg_server.py: grants tested with a second role, concurrent issuers, the audit chain)
and on SQLite. Issues go through `bench authorise` with `--password-stdin`, as a script
would; the demo run is conftest's, copied per test.
"""

from __future__ import annotations

import concurrent.futures
import datetime as dt
import json
import re
import shutil
import uuid
from pathlib import Path

import pytest
import sqlalchemy as sa
from lxml import etree

from bench.app.certificate import register as run_register
from bench.app.register import AuthError, Register, RegisterError
from bench.app.register.gate import start_gate
from bench.core.config import Traced
from tests import test_authorise
from tests.conftest import cli
from tests.registers import (
    authorise,
    cli_in,
    fill,
    lab_file,
    password,
    sqlite_register,
)

NS = {"dcc": "https://ptb.de/dcc"}
DIGESTS = {"result.json": "a" * 64, "certificate.pdf": "b" * 64,
           "certificate.dcc.xml": "c" * 64, "certificate.html": "d" * 64}


run = test_authorise.run        # the same fixtures: a copy of the demo run, a lab file
lab = test_authorise.lab        # naming a fresh SQLite register


def _url(lab: Path) -> str:
    return next(line.split(": ", 1)[1] for line in lab.read_text().splitlines()
                if line.startswith("register:"))


# -- 1. anyone could authorise ----------------------------------------------------------

def test_unknown_wrong_password_and_file_named_signatories_are_refused(
        run: Path, lab: Path) -> None:
    # "Mallory" exists in no register; the demo procedure file names "A. Ivanova" among
    # its signatories, but her account holds the operator role only
    for who, pw, why in (("Mallory", "anything-1", "unknown account, wrong password"),
                         ("P. Petrov", "not-his-password", "unknown account, wrong password"),
                         ("A. Ivanova", password("A. Ivanova"),
                          "does not hold the signatory role")):
        done = authorise(run, who, lab, password_text=pw)
        assert done.returncode == 2, done.stdout
        assert why in done.stderr, done.stderr
    assert not (run / "issued").exists()
    assert not (run / run_register.REGISTER_NAME).exists()
    with Register.open(_url(lab)) as reg:
        refused = [r for r in reg.audit_rows() if r.action == "authentication refused"]
        assert [r.actor for r in refused] == ["Mallory", "P. Petrov", "A. Ivanova"]
        assert reg.audit_check().ok


def test_no_register_no_issue(run: Path, tmp_path: Path) -> None:
    """The demo runs without a register; its draft cannot be issued without one."""
    bare = tmp_path / "bare.yaml"
    bare.write_text("laboratory: Test Rate Lab\n")
    done = cli_in("x\n", "authorise", str(run), "--signatory", "P. Petrov", "--lab",
                  str(bare), "--password-stdin")
    assert done.returncode == 2
    assert "names no register" in done.stderr
    # unreachable: refused, exit 2
    gone = lab_file(tmp_path / "gone", f"sqlite:///{tmp_path}/no/such/dir/x.sqlite")
    done = authorise(run, "P. Petrov", gone)
    assert done.returncode == 2 and "cannot be reached" in done.stderr
    text = (run / "certificate.html").read_text()
    assert "no lab register was named" in text


# -- 2. the assurance gate bypassed with --records ----------------------------------------

def test_records_cannot_be_chosen_at_issue(run: Path, lab: Path, tmp_path: Path) -> None:
    with pytest.raises(SystemExit) as e:
        cli_in(password("P. Petrov") + "\n", "authorise", str(run), "--signatory",
               "P. Petrov", "--lab", str(lab), "--password-stdin", "--records",
               f"sqlite:///{tmp_path}/empty.sqlite")
    assert e.value.code == 2          # argparse: the option does not exist


# a copied run directory: tests/test_document_control.py (the issue/re-issue walk)

def _uid(run: Path) -> str:
    from bench.app.records.extract import run_uid

    return run_uid(json.loads((run / "meta.json").read_text()), run.name)


# -- 3. an overdue counter ---------------------------------------------------------------

def _traced(serial: str | None, due: dt.date | None = None) -> Traced:
    return Traced("axes.outer.counter", "counter keysight-53230a (outer)",
                  "SIM-CAL-1" if due else None, "Cal Lab" if due else None, due, None,
                  serial=serial)


def test_overdue_or_unknown_equipment_refuses_a_real_stand(tmp_path: Path) -> None:
    url = sqlite_register(tmp_path)
    with Register.open(url) as reg:
        q = reg.authenticate("Q. Manager", password("Q. Manager"), "quality")
        reg.add_equipment(q, "MY62000117", "Keysight 53230A", "C-2024-117", "Cal Lab",
                          dt.date(2025, 1, 31))
        reg.add_equipment(q, "MY62000118", "Keysight 53230A", "C-2026-118", "Cal Lab",
                          dt.date(2027, 6, 30))
    on = dt.date(2026, 11, 27)
    as_held = Traced("axes.inner.counter", "counter (inner)", "C-2026-118", "Cal Lab",
                     dt.date(2027, 6, 30), None, serial="MY62000118")
    items = [_traced("MY62000117", dt.date(2027, 1, 1)), as_held,
             _traced("NOT-IN-INVENTORY", on)]
    gate = start_gate(url, items, simulated=False, operator=None, password=str, on=on)
    assert len(gate.refusal) == 3 and "deviation" in gate.refusal[2]
    assert "MY62000117" in gate.refusal[0] and "due 2025-01-31" in gate.refusal[0]
    assert "NOT-IN-INVENTORY" in gate.refusal[1] and "not in the lab's" in gate.refusal[1]
    # on twins the same facts are findings, and the run starts
    twin = start_gate(url, items, simulated=True, operator=None, password=str, on=on)
    assert twin.refusal == [] and sum(bool(s["problem"]) for s in twin.equipment) == 2
    # a stand file whose stated calibration contradicts the inventory (issue 54)
    said = _traced("MY62000118", on)
    gate = start_gate(url, [said], simulated=False, operator=None, password=str, on=on)
    assert "the stand file states calibration SIM-CAL-1 due 2026-11-27, the inventory's " \
        "record in force is C-2026-118 due 2027-06-30" in gate.refusal[0]
    twin = start_gate(url, [said], simulated=True, operator=None, password=str, on=on)
    assert twin.refusal == [] and "contradicts" not in str(twin.equipment[0]["problem"])
    assert "the stand file states calibration SIM-CAL-1" in str(twin.equipment[0]["problem"])
    # a quality account's deviation (reason, expiry) lets the overdue counter be used
    with Register.open(url) as reg:
        soon = dt.datetime.now(dt.UTC).date() + dt.timedelta(days=20)   # within 30 days
        with pytest.raises(AuthError):
            reg.add_deviation(reg.authenticate("A. Ivanova", password("A. Ivanova")),
                              "MY62000117", "re-calibration booked", soon)
        reg.add_deviation(reg.authenticate("Q. Manager", password("Q. Manager")),
                          "MY62000117", "re-calibration booked; drift checked", soon)
    gate = start_gate(url, items[:2], simulated=False, operator=None, password=str, on=on)
    assert gate.refusal == [], gate.refusal
    assert "re-calibration booked" in gate.equipment[0]["deviation"]


def test_overdue_counter_on_twins_is_stated_in_the_pdf_and_the_dcc(
        tmp_path: Path, demo_files: Path) -> None:
    url = sqlite_register(tmp_path / "reg")
    with Register.open(url) as reg:
        q = reg.authenticate("Q. Manager", password("Q. Manager"), "quality")
        reg.add_equipment(q, "1760-20231", "KVH DSP-1760", "C-2024-31", "Cal Lab",
                          dt.date(2025, 1, 31))
    procedure = demo_files / "procedures" / "demo.yaml"
    lab_file(demo_files, url)
    done = cli_in(password("A. Ivanova") + "\n", "run", str(procedure), "--out",
                  str(tmp_path / "runs"), "--yes", "--quiet", "--operator", "A. Ivanova",
                  "--password-stdin")
    assert done.returncode == 0, done.stderr[-3000:]
    run = Path(done.stdout.strip().splitlines()[-1])
    html = (run / "certificate.html").read_text()
    assert "1760-20231" in html and "was due 2025-01-31" in html
    root = etree.parse(str(run / "certificate.dcc.xml")).getroot()
    texts = [st.findtext("dcc:declaration/dcc:content", "", NS)
             for st in root.iterfind(".//dcc:statement[@refType='ratebench_equipmentStatus']",
                                     NS)]
    assert any("1760-20231" in t and "2025-01-31" in t for t in texts), texts
    # 5. the performer is the account that authenticated, not a name from a file
    meta = json.loads((run / "meta.json").read_text())
    assert meta["performer"]["account"] == "A. Ivanova"
    with Register.open(url, migrate=False) as reg:   # the entry names the run and the bench
        started = [json.loads(str(r.detail)) for r in reg.audit_rows()
                   if r.action == "run started by"]
    assert [d["run_uid"] for d in started] == [meta["run_uid"]] and started[0]["bench"]
    assert "Calibration performed by: A. Ivanova (account A. Ivanova, authenticated" in html
    # and a wrong password starts nothing
    done = cli_in("wrong-password\n", "run", str(procedure), "--out", str(tmp_path / "r2"),
                  "--yes", "--quiet", "--operator", "A. Ivanova", "--password-stdin")
    assert done.returncode == 2 and "Not started" in done.stderr
    assert not (tmp_path / "r2").exists() or not any((tmp_path / "r2").iterdir())


def test_a_real_stand_with_an_overdue_fog_does_not_start(tmp_path: Path,
                                                        demo_files: Path) -> None:
    """The demo stand without its sim: block is a real stand: refused before anything
    moves (no run directory), naming serial and due date."""
    url = sqlite_register(tmp_path / "reg")
    with Register.open(url) as reg:
        q = reg.authenticate("Q. Manager", password("Q. Manager"), "quality")
        reg.add_equipment(q, "1760-20231", "KVH DSP-1760", "C-2024-31", "Cal Lab",
                          dt.date(2025, 1, 31))
    lab_file(demo_files, url)
    stand = demo_files / "stands" / "sim-two-axis.yaml"
    text = stand.read_text()
    text = text[:text.index("\nsim:")] + "\n"
    stand.write_text(text.replace("drive:   {interface:", "drive:   {unit_factors: read, "
                                                           "interface:"))
    out = tmp_path / "runs"
    done = cli("run", str(demo_files / "procedures" / "demo.yaml"), "--out", str(out),
               "--yes", "--quiet")
    assert done.returncode == 2, done.stdout + done.stderr
    assert "Not started: the lab register refuses" in done.stderr
    assert "serial 1760-20231: calibration (C-2024-31, Cal Lab) was due 2025-01-31" \
        in done.stderr
    assert not out.exists() or not any(out.iterdir())


@pytest.fixture
def demo_files(tmp_path: Path) -> Path:
    """The shipped demo procedure and stand, copied, the procedure naming ../lab.yaml."""
    from bench.examples import example_path

    src = example_path("demo")
    root = tmp_path / "files"
    (root / "procedures").mkdir(parents=True)
    (root / "stands").mkdir()
    for f in src.parent.parent.joinpath("stands").iterdir():
        shutil.copyfile(f.resolve(), root / "stands" / f.name)
    text = src.read_text().replace(
        "certificate:                    #", "certificate:\n  lab: ../lab.yaml\n  #", 1)
    assert "lab: ../lab.yaml" in text
    (root / "procedures" / "demo.yaml").write_text(text)
    return root


# -- 4. the records and the register agree on what was issued -----------------------------

# verified against the register and against another lab file's: in
# test_the_issuer_is_named_by_the_register_not_by_a_file (its issue)


def test_a_draft_is_cited_nowhere(run: Path) -> None:
    from bench.app.records.extract import record_of

    rec = record_of(run)
    assert rec.certificate_number is None and rec.cert_files == ()


# -- the register itself: SQLite and PostgreSQL ---------------------------------------------

@pytest.fixture(params=["sqlite", "postgresql"])
def url(request: pytest.FixtureRequest, tmp_path: Path) -> str:
    if request.param == "sqlite":
        return sqlite_register(tmp_path)
    server = request.getfixturevalue("pg")
    u = server.create_database(f"register_{uuid.uuid4().hex[:10]}")
    fill(u)
    return str(u)


def _issue_one(url: str, run_uid: str) -> str:
    with Register.open(url, migrate=False) as reg:
        signer = reg.authenticate("P. Petrov", password("P. Petrov"), "signatory")
        number = reg.allocate(run_uid, "RT", signer.name)
        reg.issue(number, 1, signer, DIGESTS, None, {})
        return number


def test_concurrent_issuers_never_share_a_number(url: str) -> None:
    with concurrent.futures.ThreadPoolExecutor(4) as pool:
        numbers = list(pool.map(lambda i: _issue_one(url, f"run-{i}"), range(12)))
    assert len(set(numbers)) == 12
    with Register.open(url, migrate=False) as reg:
        assert reg.audit_check().ok
        # the same revision twice: the register refuses the second
        signer = reg.authenticate("P. Petrov", password("P. Petrov"))
        with pytest.raises(RegisterError, match="not the next"):
            reg.issue(numbers[0], 1, signer, DIGESTS, None, {})
        with pytest.raises(RegisterError, match="needs a reason"):
            reg.issue(numbers[0], 2, signer, DIGESTS, " ", {})


def _tamper(url: str, *sql: str) -> None:
    """As the database's owner (SQLite: the file's owner, who can drop the guards)."""
    eng = sa.create_engine(url.replace("postgresql://", "postgresql+psycopg://"))
    with eng.begin() as c:
        if c.dialect.name == "sqlite":
            c.exec_driver_sql("DROP TRIGGER IF EXISTS reg_audit_no_update")
            c.exec_driver_sql("DROP TRIGGER IF EXISTS reg_audit_no_delete")
        for q in sql:
            c.exec_driver_sql(q)
    eng.dispose()


def test_the_audit_trail_finds_altered_and_removed_entries(url: str) -> None:
    _issue_one(url, "run-a")
    _issue_one(url, "run-b")
    done = cli("register", "audit", "--register", url)
    assert done.returncode == 0 and "chain whole" in done.stdout
    _tamper(url, "UPDATE reg_audit SET actor = 'someone else' WHERE seq = 3")
    done = cli("register", "audit", "--register", url)
    assert done.returncode == 1 and "entry 3" in done.stdout and "altered" in done.stdout
    with Register.open(url, migrate=False) as reg:
        n = len(reg.audit_rows())
    _tamper(url, f"DELETE FROM reg_audit WHERE seq >= {n - 1}")
    done = cli("register", "audit", "--register", url)
    assert done.returncode == 1 and "removed from its end" in done.stdout


def test_sqlite_guards_against_mistakes(tmp_path: Path) -> None:
    url = sqlite_register(tmp_path)
    _issue_one(url, "run-x")
    eng = sa.create_engine(url)
    for q in ("DELETE FROM reg_audit", "UPDATE reg_audit SET actor = 'x'",
              "DELETE FROM reg_revisions", "UPDATE reg_revisions SET signatory = 'admin'"):
        with pytest.raises(sa.exc.DBAPIError), eng.begin() as c:
            c.exec_driver_sql(q)
    eng.dispose()


# -- issue 56, item 5: a command that reads a register never makes one ----------------------

def test_a_missing_register_is_an_error_and_nothing_is_created(run: Path, lab: Path,
                                                               tmp_path: Path) -> None:
    nowhere = tmp_path / "nowhere" / "register.sqlite"
    bad = lab_file(tmp_path / "badlab", f"sqlite:///{nowhere}")
    done = authorise(run, "P. Petrov", bad)
    assert done.returncode == 2 and "no such file" in done.stderr, done.stderr
    done = cli("verify", str(run / "certificate.dcc.xml"), "--register", f"sqlite:///{nowhere}")
    assert done.returncode == 1 and "no such file" in done.stdout
    # the run's own copy of a lab file whose relative path points into the run directory
    (run / "lab.yaml").write_text("register: sqlite:///register.sqlite\n")
    done = cli_in(password("P. Petrov") + "\n", "authorise", str(run), "--signatory",
                  "P. Petrov", "--password-stdin")
    assert done.returncode == 2 and "no such file" in done.stderr, done.stderr
    assert not nowhere.exists() and not nowhere.parent.exists()
    assert not (run / "register.sqlite").exists()


# -- issue 54, item 5: the trail anchored in what customers hold -----------------------------

def _rewrite_without_issues(url: str) -> None:
    """As the owner: the trail rebuilt without its issue entries, every digest and the
    head recomputed, so the chain itself checks whole."""
    from bench.app.register import chain

    eng = sa.create_engine(url.replace("postgresql://", "postgresql+psycopg://"))
    with eng.begin() as c:
        if c.dialect.name == "sqlite":
            c.exec_driver_sql("DROP TRIGGER IF EXISTS reg_audit_no_update")
            c.exec_driver_sql("DROP TRIGGER IF EXISTS reg_audit_no_delete")
        rows = [dict(r._mapping) for r in c.exec_driver_sql(
            "SELECT * FROM reg_audit ORDER BY seq")]
        kept = [r for r in rows if not str(r["action"]).startswith("issue")]
        c.exec_driver_sql("DELETE FROM reg_audit")
        prev = chain.GENESIS
        for seq, r in enumerate(kept, 1):
            d = chain.entry_digest(prev, seq, r["utc"], r["actor"], r["action"], r["object"],
                                   r["detail"], r["db_user"])
            c.execute(sa.text("INSERT INTO reg_audit (seq, utc, actor, action, object, "
                              "detail, db_user, prev_digest, digest) VALUES (:s, :u, :a, "
                              ":b, :o, :d, :w, :p, :g)"),
                      {"s": seq, "u": r["utc"], "a": r["actor"], "b": r["action"],
                       "o": r["object"], "d": r["detail"], "w": r["db_user"], "p": prev,
                       "g": d})
            prev = d
        c.execute(sa.text("UPDATE reg_audit_head SET seq = :s, digest = :d"),
                  {"s": len(kept), "d": prev})
    eng.dispose()


def test_issued_documents_anchor_the_trail(url: str, run: Path, tmp_path: Path) -> None:
    """An issue and its re-issue: the withdrawn revision gets no OK line from `bench verify`
    (each issue renders a certificate, so one walk checks both), and each issued document's
    receipt is found in the trail until the trail is rewritten or truncated."""
    lab = lab_file(tmp_path / "lab", url)
    assert authorise(run, "P. Petrov", lab).returncode == 0
    first = next((run / "issued").iterdir()) / "certificate.dcc.xml"
    kept = first.read_bytes()
    assert authorise(run, "P. Petrov", lab, "--reason", "the customer's address corrected"
                     ).returncode == 0
    # the withdrawn file gets no OK line
    done = cli("verify", str(first), "--register", url, "--no-result")
    assert first.read_bytes() == kept
    assert done.returncode == 1 and "withdrawn" in done.stdout, done.stdout
    assert "verify: OK" not in done.stdout
    assert "the register does not hold it as issued" in done.stdout
    html = (run / "certificate.html").read_text()
    m = re.search(r"Lab register audit trail entry (\d+), SHA-256 ([0-9a-f]{64})", html)
    assert m, "the issued certificate states no receipt"
    with Register.open(url, migrate=False) as reg:
        entry = next(r for r in reg.audit_rows() if r.seq == int(m.group(1)))
    assert entry.digest == m.group(2) and entry.action == "issue begun"
    assert m.group(0).encode() in (run / "certificate.dcc.xml").read_bytes()
    whole = cli("register", "audit", "--register", url, "--receipts", str(run))
    assert whole.returncode == 0 and "every one in the trail" in whole.stdout, whole.stdout
    # a consistently rewritten trail (the issues erased): the chain checks, the receipts not
    _rewrite_without_issues(url)
    chain_only = cli("register", "audit", "--register", url)
    assert chain_only.returncode == 0 and "chain whole" in chain_only.stdout
    found = cli("register", "audit", "--register", url, "--receipts", str(run))
    assert found.returncode == 1 and "RECEIPT NOT IN THE TRAIL" in found.stdout
    assert "certificate.dcc.xml" in found.stdout and "rewritten" in found.stdout
    # truncated, head and all
    _tamper(url, "DELETE FROM reg_audit", "DELETE FROM reg_audit_head")
    chain_only = cli("register", "audit", "--register", url)
    assert chain_only.returncode == 0 and "0 entries, chain whole" in chain_only.stdout
    found = cli("register", "audit", "--register", url, "--receipts", str(run))
    assert found.returncode == 1 and "missing from the trail" in found.stdout


# -- issue 54, item 4: the issuer is the register's, not a file's ----------------------------

def test_the_issuer_is_named_by_the_register_not_by_a_file(run: Path, tmp_path: Path) -> None:
    """The issuer is the register's; and `bench verify` finds the issue in the register
    that issued it, not in another lab file's (the review's fourth finding: a swapped lab file)."""
    from tests.registers import ISSUER

    url = sqlite_register(tmp_path / "reg")
    lab = lab_file(tmp_path / "lab", url, "laboratory: ACME Accredited Lab\n"
                   "accreditation: ACME-ACCREDITED\ncode: ACME-1\nprefix: ACME\n")
    done = cli("verify", str(run / "certificate.dcc.xml"), "--register", url)
    assert done.returncode == 1 and "not issued (draft)" in done.stdout
    procedure_says = json.loads((run / "result.json").read_text())["certificate"]["laboratory"]
    assert procedure_says == "Rate Table Metrology Lab (demo)"
    # a register that holds no issuer identity issues nothing
    eng = sa.create_engine(url)
    with eng.begin() as c:
        kept = c.exec_driver_sql("SELECT key, value FROM reg_settings WHERE key LIKE "
                                 "'issuer.%'").all()
        c.exec_driver_sql("DELETE FROM reg_settings WHERE key LIKE 'issuer.%'")
    refused = authorise(run, "P. Petrov", lab)
    assert refused.returncode == 2 and "holds no issuer identity" in refused.stderr
    with eng.begin() as c:
        for key, value in kept:
            c.execute(sa.text("INSERT INTO reg_settings VALUES (:k, :v)"), {"k": key, "v": value})
    eng.dispose()
    done = authorise(run, "P. Petrov", lab)
    assert done.returncode == 0, done.stderr
    html = (run / "certificate.html").read_text()
    dcc = (run / "certificate.dcc.xml").read_text()
    for said in (html, dcc):
        assert ISSUER["issuer.name"] in said
        assert "ACME" not in said and procedure_says not in said
    assert ISSUER["issuer.accreditation"] in html and ISSUER["issuer.address"] in html
    assert ISSUER["issuer.code"] in dcc
    with Register.open(url, migrate=False) as reg:
        number = reg.number_of_run(_uid(run))
    assert number is not None and number.startswith("RT-")
    # issued through this register: not another lab file's certificate
    other = sqlite_register(tmp_path / "other")
    issued = next((run / "issued").iterdir())
    for name in ("certificate.dcc.xml", "certificate.pdf"):
        done = cli("verify", str(issued / name), "--register", other)
        assert done.returncode == 1 and "not issued" in done.stdout, done.stdout
        done = cli("verify", str(issued / name), "--register", url)
        assert done.returncode == 0 and "issued: certificate" in done.stdout, done.stdout

