"""The register's stored bytes do not move with its codec (issue 60, bench/app/register/wire.py).

tests/data/register-fc7c28f.sql is a register written by main fc7c28f's code (before the
wire module) doing `act` below: `python tests/test_register_wire.py URL` with that code on
PYTHONPATH made it (then `sqlite3 FILE .dump`). Today's code must read it (the chain whole,
the runs' JSON columns decoded), and, doing the same acts on a fresh register, store the
same bytes: every audit entry's detail (the chain hashes it), every run's JSON columns and
events; only times, the argon2 hashes and what they feed (digests) may differ.
"""

from __future__ import annotations

import datetime as dt
import re
import sqlite3
import sys
from pathlib import Path

import pytest

DUMP = Path(__file__).resolve().parent / "data" / "register-fc7c28f.sql"
ITEMS = [{"where": "stand", "item": "counter", "serial": "C-1", "problem": None,
          "deviation": None, "certificate": "CAL-1", "issuer": "Lab A",
          "calibrated_on": "2026-01-02", "due": "2027-01-02"},
         {"where": "stand", "item": "fixture", "serial": None, "problem": None,
          "deviation": None, "identity_only": "yes"}]
RESULT = b'{"schema": "bench.result/1", "stand": {"simulated": true}, "x": 1e-05}\n'
DIGESTS = {"result.json": "a" * 64, "certificate.pdf": "b" * 64,
           "certificate.dcc.xml": "c" * 64, "certificate.html": "d" * 64}


def act(url: str) -> None:
    """Every kind of stored write the register makes, through its public methods."""
    from bench.app.register import Register

    with Register.open(url) as reg:
        reg.init("admin", "R. Admin", "keeper-of-keys-1")
        admin = reg.authenticate("admin", "keeper-of-keys-1", "admin")
        sig = reg.add_account(admin, "P. Petrov", "P. Petrov", ("signatory",),
                              "petrov-pass-initial", "Technical manager")
        reg.change_password("P. Petrov", "petrov-pass-initial", "petrov-pass-1")
        qm = reg.add_account(admin, "Q. Manager", "Q. Manager", ("quality",),
                             "quality-pass-initial", None)
        reg.set_setting(admin, "issuer.prefix", "RT")
        reg.set_setting(admin, "lockout_attempts", "7")
        reg.set_role(admin, "P. Petrov", "reviewer", True)
        reg.add_equipment(qm, "C-1", "counter", "CAL-1", "Lab A", dt.date(2026, 6, 1),
                          calibrated_on=dt.date(2025, 6, 1))
        reg.add_equipment(qm, "F-1", "fixture", None, None, None, identity_only=True)
        reg.add_deviation(qm, "C-1", "used while the new certificate is awaited",
                          dt.date.today() + dt.timedelta(days=10))
        reg.revoke_deviation(qm, "C-1")
        reg.update_equipment(qm, "C-1", "CAL-2", "Lab B", dt.date(2028, 1, 2),
                             dt.date(2026, 7, 1), "out", 1.5e-05, 2.5e-06)
        reg.register_run("run-1", "hall-1", "P. Petrov", "0.1", True,
                         {"procedure.yaml": "e" * 64, "stand.yaml": "f" * 64}, ITEMS)
        reg.run_session("run-1", 2, None)
        reg.deliver_result("run-1", "session", RESULT, {"raw/s1/fog.bin": "1" * 64})
        reg.deliver_result("run-1", "analysis", RESULT,
                           {"raw/s1/fog.bin": "1" * 64, "raw/s2/fog.bin": "2" * 64},
                           "re-analysed: ünïcode reason")
        sig = reg.authenticate("P. Petrov", "petrov-pass-1", "signatory")
        number = reg.allocate("run-1", "RT", sig.name)
        reg.begin_issue(sig, number, 1, "a" * 64)
        reg.issue(number, 1, sig, DIGESTS, None,
                  {"run_dir": "run-1", "signatory": sig.name, "run_uid": "run-1",
                   "bench": "hall-1", "x": 1e-05, "list": [1, 2.5, None, "é"]})
        reg.withdraw(qm, number, "withdrawn for the stored bytes test of the register")
        reg.append(sig.name, "station login", sig.name, {"at": "station", "remote": "::1"})
        reg.append(sig.name, "control review", "run-1", "a plain text detail")
        reg.impact_assessed(qm, "C-1", {"finding": {"error": 1e-05, "serial": "C-1"},
                                        "runs": [{"uid": "run-1", "shift": None}]})


#: a time (then a date: the deviation's expiry is made relative to the day it is made)
_TIME = re.compile(r"\d{4}-\d\d-\d\d(T\d\d:\d\d:\d\d(\.\d+)?Z)?")


def _rows(path: Path) -> dict[str, list[tuple[object, ...]]]:
    """What the register stored, times masked (hashes and digests left out)."""
    def mask(v: object) -> object:
        return _TIME.sub("<utc>", v) if isinstance(v, str) else v

    with sqlite3.connect(path) as c:
        return {
            "audit": [tuple(mask(v) for v in r) for r in c.execute(
                "SELECT seq, actor, action, object, detail FROM reg_audit ORDER BY seq")],
            "runs": [tuple(mask(v) for v in r) for r in c.execute(
                "SELECT uid, bench, performer, version, simulated, inputs, items, via, "
                "result_sha256, result, raw FROM reg_runs ORDER BY uid")],
            "events": [tuple(mask(v) for v in r) for r in c.execute(
                "SELECT uid, kind, detail FROM reg_run_events ORDER BY id")],
            "equipment": [tuple(mask(v) for v in r) for r in c.execute(
                "SELECT * FROM reg_equipment ORDER BY serial")],
            "deviations": [tuple(mask(v) for v in r) for r in c.execute(
                "SELECT serial, reason, expires, recorded_by FROM reg_deviations "
                "ORDER BY id")],
            "settings": list(c.execute("SELECT * FROM reg_settings ORDER BY key")),
        }


@pytest.fixture(scope="module")
def main_register(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("main") / "register.sqlite"
    with sqlite3.connect(path) as c:
        c.executescript(DUMP.read_text(encoding="utf-8"))
    return path


def test_a_register_written_before_the_codec_reads_whole(main_register: Path) -> None:
    from bench.app.register import Register

    with Register.open(f"sqlite:///{main_register}", migrate=False) as reg:
        report = reg.audit_check()
        assert report.ok and report.entries == len(_rows(main_register)["audit"]) > 20
        rec = reg.run_record("run-1")
        assert rec is not None and rec.items == tuple(ITEMS)
        assert rec.inputs == {"procedure.yaml": "e" * 64, "stand.yaml": "f" * 64}
        assert rec.raw == {"raw/s1/fog.bin": "1" * 64, "raw/s2/fog.bin": "2" * 64}
        assert [(e.kind, e.detail.session, e.detail.reason) for e in rec.events] == [
            ("start", None, None), ("resume", 2, None), ("session", None, None),
            ("analysis", None, "re-analysed: ünïcode reason")]
        assert rec.result_bytes == RESULT
        [counter] = reg.equipment("C-1")
        assert [c.found_error for c in counter.calibrations] == [None, 1.5e-05]
        assert [r.uid for r in reg.runs_using("C-1")] == ["run-1"]
        assert [e.seq for e in reg.audit_rows()] == list(range(1, report.entries + 1))


def test_todays_code_stores_the_same_bytes(main_register: Path, tmp_path: Path) -> None:
    path = tmp_path / "register.sqlite"
    act(f"sqlite:///{path}")
    before, now = _rows(main_register), _rows(path)
    for table in before:
        assert now[table] == before[table], table


def test_a_broken_column_is_named(main_register: Path, tmp_path: Path) -> None:
    from bench.app.register import Register, RegisterError

    path = tmp_path / "broken.sqlite"
    path.write_bytes(main_register.read_bytes())
    with sqlite3.connect(path) as c:
        c.execute("UPDATE reg_runs SET inputs = '{\"procedure.yaml\": 1}'")
    with Register.open(f"sqlite:///{path}", migrate=False) as reg, \
            pytest.raises(RegisterError, match=r"inputs as stored: .*Expected `str`, got `int`"):
        reg.run_record("run-1")



def test_the_service_names_the_key_a_body_gets_wrong(main_register: Path) -> None:
    from bench.app.register import Register
    from bench.app.register.service import create_app

    with Register.open(f"sqlite:///{main_register}", migrate=False) as reg:
        client = create_app(reg).test_client()
        got = client.post("/v1/add_account", json={"name": "x", "full_name": "X",
                                                  "password": "p", "roles": ["ok", 1]})
        assert got.status_code == 400 and got.get_json() == {
            "error": "add_account: $.roles[1]: Expected `str`, got `int`", "kind": "register"}
        got = client.post("/v1/update_equipment", json={"serial": "C-1"})
        assert got.status_code == 400 and "missing required field `certificate`" in \
            got.get_json()["error"]
        got = client.post("/v1/add_deviation", json={"serial": "C-1", "reason": "r",
                                                    "expires": "2026-13-01"})
        assert got.get_json()["error"] == \
            "add_deviation: $.expires: Invalid RFC3339 encoded date"
        # a well-formed body without a login is refused as such, not as malformed
        got = client.post("/v1/withdraw", json={"number": "RT-1", "reason": "r"})
        assert got.status_code == 403 and got.get_json()["kind"] == "auth"
        got = client.post("/v1/run_record", json={"uid": "run-1"})
        assert got.status_code == 200 and got.get_json()["ok"]["items"] == ITEMS



#: a line of a run's certificate-register.jsonl as fc7c28f's code wrote it (Issue.to_json)
ISSUE_LINE = (
    '{"audit_digest": "dddddddddddddddddddddddddddddddddddddddddddddddddddddddddddddddd",'
    ' "audit_entry": "eeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeeee", '
    '"audit_seq": 5, "changes": ["x", "y"], "function": "TM", "issued_utc": "2026-01-01T0'
    '0:00:00Z", "issuer": [["laboratory", "L"], ["code", "C"]], "meaning": "authorised fo'
    'r issue", "number": "RT-1-R2", "reason": "why \\u00e9", "register": "http://127.0.0.1'
    '", "replaces": "RT-1", "result_sha256": "aaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaa'
    'aaaaaaaaaaaaaaaaaaaaa", "revision": 2, "run_registered_utc": "2026", "run_uid": "uid'
    '", "signatory": "P. P"}')


def test_a_certificate_register_line_keeps_its_bytes() -> None:
    from bench.app.certificate.register import issue_line, issue_of

    issue = issue_of(ISSUE_LINE)
    assert (issue.audit_seq, issue.changes, issue.issuer[1]) == (5, ("x", "y"), ("code", "C"))
    assert issue_line(issue) == ISSUE_LINE


if __name__ == "__main__":
    act(sys.argv[1])
