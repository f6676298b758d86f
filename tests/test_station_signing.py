"""Logging in and signing at the station (issue 42): a signatory logs in, opens a draft
and signs it with the password entered again; the issued PDF and DCC name the signatory;
an account without the signatory role sees no sign button and the server refuses (403)
and audits its sign request.

The browser test drives the real server (`bench serve`, waitress) in headless chromium,
offline but for 127.0.0.1 (tests/test_station.py CHROMIUM_OFFLINE), on a copy of the
session's demo run (tests/conftest.py demo_run) and an SQLite lab register made here; the
issued PDF is read back with pypdfium2, the DCC with lxml. The refusals and the session
rules are also checked through Flask's test client, which can set a remote address this
sandboxed machine cannot make for real.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import re
import subprocess
import sys
import urllib.error
import urllib.parse
import urllib.request
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pypdfium2 as pdfium
import pytest
from lxml import etree

from bench.app.register import Register
from bench.app.register.model import AuditEntry
from bench.app.station.app import StationSettings, create_app
from bench.app.station.serve import add_serve_arguments, settings_from_args
from bench.app.station.signing import SESSION_COOKIE, STRIKES, Sessions
from tests.conftest import ROOT, DemoRun, unavailable
from tests.test_station import ARTIFACTS, TOKEN, _browser, _chromium, _stop, _wait, hand_made_runs

NS = {"dcc": "https://ptb.de/dcc"}
LAB_ENV = "BENCH_LAB_SETTINGS"
SIGNATORY = ("kowalska", "M. Kowalska", "sign-phrase-123")    # a name the demo's files lack
OPERATOR = ("olga", "O. Operatorova", "oper-phrase-123")
QUALITY = ("quinn", "Q. Quality", "qual-phrase-123")
ADMIN_PW = "root-phrase-123"


@pytest.fixture(autouse=True)
def _no_lab_of_the_developer(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(LAB_ENV, raising=False)


@dataclass(frozen=True)
class Lab:
    file: Path
    url: str


def _lab(tmp: Path) -> Lab:
    """A lab file naming an SQLite register (relative to the file, as a lab writes it)
    with an admin, a signatory, an operator and a quality account."""
    url = f"sqlite:///{tmp / 'register.sqlite'}"
    with Register.open(url) as reg:
        assert reg.init("admin", "The Admin", ADMIN_PW)
        admin = reg.authenticate("admin", ADMIN_PW)
        reg.add_account(admin, SIGNATORY[0], SIGNATORY[1], ["signatory"], "x" + SIGNATORY[2],
                        function="Technical manager")
        reg.add_account(admin, OPERATOR[0], OPERATOR[1], ["operator"], "x" + OPERATOR[2])
        reg.add_account(admin, QUALITY[0], QUALITY[1], ["quality"], "x" + QUALITY[2])
        for name, _, pw in (SIGNATORY, OPERATOR, QUALITY):   # each holder's own password
            reg.change_password(name, "x" + pw, pw)
        reg.set_setting(admin, "issuer.name", "Test Lab")     # the issuer, as registered
    lab = tmp / "lab.yaml"
    lab.write_text("laboratory: Test Lab\nregister: sqlite:///register.sqlite\n")
    return Lab(lab, url)


def enrol_in_register(run: Path, url: str) -> None:
    """The register's record of a copy of the session's demo run (made without a
    register), as `bench run` under the register makes it at the start and end (issue 54:
    no register, no issue; tests/registers.py `enrol`)."""
    from tests.registers import enrol

    enrol(run, url)


def _audit(url: str) -> list[AuditEntry]:
    with Register.open(url, migrate=False) as reg:
        return reg.audit_rows()


def _run_uid(run: Path) -> str:
    from bench.app.records.extract import run_uid

    return run_uid(json.loads((run / "meta.json").read_text()), run.name)


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


# -- the server's rules, through the WSGI test client ------------------------------------------

def _login(client: Any, name: str, password: str, **env: Any) -> Any:
    page = client.get("/login", **env).get_data(as_text=True)
    token = re.search(r'name="token" value="([^"]+)"', page)
    return client.post("/login", data={"name": name, "password": password,
                                       "token": token.group(1) if token else "",
                                       "next": "/"}, **env)


def _csrf(client: Any) -> str:
    m = re.search(r'name="csrf" value="([^"]+)"', client.get("/").get_data(as_text=True))
    assert m, "no logout form with the session's token"
    return m.group(1)


def test_without_a_register_the_station_is_read_only(tmp_path: Path) -> None:
    runs = hand_made_runs(tmp_path)
    c = create_app(StationSettings(runs, TOKEN)).test_client()
    page = c.get("/run/20260101-000000-demo").get_data(as_text=True)
    assert "Signing needs a lab register" in page and 'id="sign-form"' not in page
    assert 'id="read-only"' in page and 'id="login-link"' not in page
    assert "Signing needs a lab register" in c.get("/login").get_data(as_text=True)
    assert _login(c, *SIGNATORY[::2]).status_code == 403
    r = c.post("/run/20260101-000000-demo/sign", data={"password": "x"})
    assert r.status_code == 403 and "signing needs a register" in r.get_data(as_text=True)


def test_the_server_refuses_and_audits_whoever_may_not_sign(tmp_path: Path) -> None:
    lab = _lab(tmp_path)
    runs = hand_made_runs(tmp_path)
    app = create_app(StationSettings(runs, TOKEN, register_url=lab.url,
                                     lab_file=str(lab.file)))
    sign = "/run/20260101-000000-demo/sign"
    draft = _sha256(runs / "20260101-000000-demo" / "result.json")

    # no session: refused and audited
    anon = app.test_client()
    assert anon.post(sign, data={"password": OPERATOR[2]}).status_code == 403
    # a login form not from this page, a wrong password, another host: refused
    assert anon.post("/login", data={"name": OPERATOR[0], "password": OPERATOR[2]}
                     ).status_code == 403
    assert _login(anon, OPERATOR[0], "not-her-password").status_code == 401
    remote = {"environ_base": {"REMOTE_ADDR": "192.0.2.7"}, "headers": {"X-Bench-Token": TOKEN}}
    r = _login(anon, OPERATOR[0], OPERATOR[2], **remote)
    assert r.status_code == 403 and "plain HTTP" in r.get_data(as_text=True)
    assert SESSION_COOKIE not in r.headers.get("Set-Cookie", "")

    # an operator: sees no sign form; with her session and its token, still refused
    op = app.test_client()
    r = _login(op, OPERATOR[0], OPERATOR[2])
    assert r.status_code == 303
    cookie = r.headers["Set-Cookie"]
    assert "HttpOnly" in cookie and "SameSite=Strict" in cookie
    page = op.get("/run/20260101-000000-demo").get_data(as_text=True)
    assert 'id="sign-form"' not in page and 'id="sign"' not in page
    assert "does not hold the signatory role" in page
    r = op.post(sign, data={"csrf": _csrf(op), "draft": draft, "password": OPERATOR[2]})
    assert r.status_code == 403 and "signatory role" in r.get_data(as_text=True)
    assert op.get("/audit").status_code == 403               # quality and admin only

    # a signatory's session without its CSRF token, or from another origin: refused
    sig = app.test_client()
    assert _login(sig, SIGNATORY[0], SIGNATORY[2]).status_code == 303
    assert sig.post(sign, data={"draft": draft, "password": SIGNATORY[2]}).status_code == 403
    assert sig.post(sign, data={"csrf": _csrf(sig), "draft": draft,
                                "password": SIGNATORY[2]},
                    headers={"Origin": "http://evil.example"}).status_code == 403
    # a made-up or altered cookie names no session
    sid = sig.get_cookie(SESSION_COOKIE)
    assert sid is not None
    forged = app.test_client()
    forged.set_cookie(SESSION_COOKIE, sid.value[:-2] + "xx")
    assert 'id="login-link"' in forged.get("/").get_data(as_text=True)

    # wrong passwords at signing: nothing issued; the session ends after STRIKES
    csrf = _csrf(sig)
    for i in range(STRIKES):
        r = sig.post(sign, data={"csrf": csrf, "draft": draft, "password": f"wrong-{i}xxx"})
        assert r.status_code == 422 and "password was not accepted" in r.get_data(as_text=True)
    assert "session has ended" in r.get_data(as_text=True)
    assert 'id="login-link"' in sig.get("/").get_data(as_text=True)
    assert not (runs / "20260101-000000-demo" / "issued").exists()

    q = app.test_client()
    assert _login(q, QUALITY[0], QUALITY[2]).status_code == 303
    audit_page = q.get("/audit")
    assert audit_page.status_code == 200 and "chain intact" in audit_page.get_data(as_text=True)

    rows = _audit(lab.url)
    refused = [(r.actor, json.loads(r.detail)["why"]) for r in rows
               if r.action == "station sign refused"]
    assert [a for a, _ in refused] == ["(no session)", OPERATOR[0], SIGNATORY[0], SIGNATORY[0]]
    assert "signatory role" in refused[1][1] and "CSRF" in refused[2][1]
    assert "another origin" in refused[3][1]
    failed = [r.actor for r in rows if r.action == "authentication refused"]
    assert failed == [OPERATOR[0]] + [SIGNATORY[0]] * STRIKES
    assert [r.actor for r in rows if r.action == "station session ended"] == [SIGNATORY[0]]
    assert not any(r.action in ("issue", "number allocated") for r in rows)


def test_sessions_expire_and_end_at_logout() -> None:
    now = [1000.0]
    s = Sessions(idle_s=60, max_s=300, clock=lambda: now[0])
    acct = argparse.Namespace(name="x", roles=("operator",), has=lambda r: False)
    cookie, _ = s.start(acct)  # type: ignore[arg-type]
    for _ in range(4):           # kept alive by use, within the idle time
        now[0] += 50
        assert s.get(cookie) is not None
    now[0] += 50                 # 250 s after the login, but idle > 60 s: gone
    now[0] += 11
    assert s.get(cookie) is None
    cookie, _ = s.start(acct)  # type: ignore[arg-type]
    for _ in range(5):           # used every 55 s: ends 300 s after the login anyway
        now[0] += 55
        assert s.get(cookie) is not None
    now[0] += 55
    assert s.get(cookie) is None
    cookie, _ = s.start(acct)  # type: ignore[arg-type]
    assert s.end(cookie) is not None and s.get(cookie) is None   # logout: the cookie is dead
    assert Sessions().get(cookie) is None                         # another server's secret
    assert s.get("made-up.cookie") is None and s.get(None) is None
    assert s.login_token_ok(s.login_token()) and not Sessions().login_token_ok(s.login_token())


def test_serve_options_name_one_register(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    lab = _lab(tmp_path)
    parser = argparse.ArgumentParser()
    add_serve_arguments(parser)
    s, _ = settings_from_args(parser.parse_args(["--lab", str(lab.file)]))
    assert s.register_url == lab.url and s.lab_file == str(lab.file.resolve())
    monkeypatch.chdir(tmp_path)
    s, _ = settings_from_args(parser.parse_args(["--register", "sqlite:///register.sqlite"]))
    assert s.register_url == lab.url and s.lab_file is None
    other = tmp_path / "other.yaml"
    other.write_text("laboratory: Elsewhere\nregister: sqlite:///other.sqlite\n")
    with pytest.raises(SystemExit, match="is not the register the lab file"):
        settings_from_args(parser.parse_args(["--register", lab.url, "--lab", str(other)]))
    monkeypatch.setenv(LAB_ENV, str(lab.file))               # the lab file by default
    s, _ = settings_from_args(parser.parse_args([]))
    assert s.register_url == lab.url
    monkeypatch.delenv(LAB_ENV)
    assert settings_from_args(parser.parse_args([]))[0].register_url is None


# -- in a browser, on a real run ----------------------------------------------------------------

def serve(args: list[str], env: dict[str, str]) -> tuple[subprocess.Popen[str], str, str]:
    """`bench serve ARGS` on a free port with the test's token: the process, its URL
    (http or https, on 127.0.0.1) and its first three lines."""
    proc = subprocess.Popen([sys.executable, "-m", "bench", "serve", *args, "--port", "0",
                             "--token", TOKEN], cwd=ROOT, text=True, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    assert proc.stdout is not None
    first = proc.stdout.readline()
    m = re.search(r"(https?://127\.0\.0\.1:\d+)/", first)
    if not m:
        _stop(proc)
        pytest.fail(first + proc.stdout.read())
    said = first + "".join(proc.stdout.readline() for _ in range(2))
    return proc, m.group(1), said


def _serve(runs: Path, lab: Path) -> tuple[subprocess.Popen[str], int]:
    """`bench serve` on a free port, its lab file from $BENCH_LAB_SETTINGS (the default of
    --lab)."""
    proc, url, said = serve(["--runs", str(runs)], {**os.environ, LAB_ENV: str(lab)})
    assert "Log in and sign at /login" in said.splitlines()[1], said
    return proc, int(url.rsplit(":", 1)[1])


def _pdf_text(pdf: Path) -> str:
    doc = pdfium.PdfDocument(str(pdf))
    try:
        return " ".join(" ".join(p.get_textpage().get_text_range().split()) for p in doc)
    finally:
        doc.close()


def _main_signers(dcc: Path) -> list[str | None]:
    root = etree.parse(str(dcc), etree.XMLParser(huge_tree=True)).getroot()
    return [rp.findtext("dcc:person/dcc:name/dcc:content", None, NS)
            for rp in root.iterfind(".//dcc:respPerson", NS)
            if rp.findtext("dcc:mainSigner", None, NS) == "true"]


def _post(url: str, data: dict[str, str], cookie: str | None) -> int:
    req = urllib.request.Request(url, data=urllib.parse.urlencode(data).encode(),
                                 headers={"Cookie": f"{SESSION_COOKIE}={cookie}"} if cookie
                                 else {}, method="POST")
    try:
        with urllib.request.urlopen(req, timeout=30) as resp:
            return int(resp.status)
    except urllib.error.HTTPError as e:
        return int(e.code)


@pytest.fixture
def served(demo_run: DemoRun, tmp_path: Path) -> Iterator[tuple[Path, Lab, int]]:
    assert demo_run.status == 0, demo_run.stderr[-3000:]
    lab = _lab(tmp_path)
    run = demo_run.copy_to(tmp_path / "runs")
    enrol_in_register(run, lab.url)
    proc, port = _serve(run.parent, lab.file)
    try:
        yield run, lab, port
    finally:
        _stop(proc)


@pytest.mark.timeout(240)
def test_sign_a_draft_in_a_real_browser(served: tuple[Path, Lab, int]) -> None:
    found = _chromium()
    if found is None:
        unavailable("chromium and chromium-driver are not installed (Debian packages "
                    "`chromium chromium-driver`; .ci/run installs them)")
    from selenium.webdriver.common.by import By

    run, lab, port = served
    base = f"http://127.0.0.1:{port}"
    run_url = f"{base}/run/{run.name}"
    driver = _browser(found, height=1400)

    def log_in(name: str, password: str) -> None:
        driver.find_element(By.ID, "login-name").send_keys(name)
        driver.find_element(By.ID, "login-password").send_keys(password)
        driver.find_element(By.ID, "login-submit").click()
        _wait(lambda: driver.current_url == run_url and driver.find_elements(By.ID, "who"),
              20, f"{name}'s login back to the run's page")

    def submit_signature(password: str) -> str:
        driver.find_element(By.ID, "sign-password").send_keys(password)
        driver.find_element(By.ID, "sign").click()
        return str(_wait(lambda: next((e.text for e in driver.find_elements(By.ID, "sign-title")
                                       ), None), 120, "the sign request's answer"))

    try:
        # not logged in: a draft, no sign button, a way to log in
        driver.get(run_url)
        assert driver.find_element(By.ID, "cert-status").text.startswith("Draft, not authorised")
        assert not driver.find_elements(By.ID, "sign")
        driver.find_element(By.ID, "sign-login").click()
        log_in(SIGNATORY[0], SIGNATORY[2])
        cookie = driver.get_cookie(SESSION_COOKIE)
        assert cookie and cookie["httpOnly"] and cookie["sameSite"] == "Strict", cookie
        assert driver.find_element(By.ID, "sign-as").text == SIGNATORY[1]

        # a wrong password at signing: refused, nothing issued
        title = submit_signature("not-the-password")
        assert title == "Not issued: the password was not accepted"
        assert not (run / "issued").exists()
        with Register.open(lab.url, migrate=False) as reg:
            assert reg.number_of_run(_run_uid(run)) is None

        # the password: issued, and the PDF and DCC name the signatory
        driver.get(run_url)
        title = submit_signature(SIGNATORY[2])
        lines = driver.find_element(By.TAG_NAME, "main").text
        assert title == "Issued", lines
        driver.save_screenshot(str(ARTIFACTS / "signed.png"))
        with Register.open(lab.url, migrate=False) as reg:
            number = reg.number_of_run(_run_uid(run))
            assert number is not None
            [rev] = reg.revisions(number)
        assert (rev.signatory, rev.signatory_name) == (SIGNATORY[0], SIGNATORY[1])
        issued = run / "issued" / number
        text = _pdf_text(issued / "certificate.pdf")
        assert "DRAFT" not in text
        assert f"authorised for issue by {SIGNATORY[1]}" in text, text[-1500:]
        assert _main_signers(issued / "certificate.dcc.xml") == [SIGNATORY[1]]
        assert (run / "certificate.pdf").read_bytes() == (issued / "certificate.pdf").read_bytes()
        assert rev.pdf_sha256 == _sha256(issued / "certificate.pdf")
        driver.get(run_url)
        status = driver.find_element(By.ID, "cert-status").text
        assert status.startswith(f"Issued: certificate {number}") and SIGNATORY[1] in status

        # an operator: sees the run, no sign button; her POST is refused by the server
        driver.find_element(By.ID, "logout").click()
        _wait(lambda: driver.find_elements(By.ID, "login-link"), 20, "the logout")
        driver.get(run_url)
        driver.find_element(By.ID, "sign-login").click()
        log_in(OPERATOR[0], OPERATOR[2])
        assert not driver.find_elements(By.ID, "sign") \
            and not driver.find_elements(By.ID, "sign-form")
        assert "does not hold the signatory role" in driver.find_element(By.ID, "sign-note").text
        driver.save_screenshot(str(ARTIFACTS / "operator.png"))
        op_cookie = driver.get_cookie(SESSION_COOKIE)
        assert op_cookie is not None
        csrf = driver.find_element(By.CSS_SELECTOR, "#logout-form input[name=csrf]") \
            .get_attribute("value")
        form = {"csrf": str(csrf), "draft": _sha256(run / "result.json"),
                "password": OPERATOR[2], "reason": "an operator's try"}
        assert _post(f"{run_url}/sign", form, op_cookie["value"]) == 403
        assert _post(f"{run_url}/sign", form, None) == 403
    finally:
        driver.quit()

    with Register.open(lab.url, migrate=False) as reg:
        assert len(reg.revisions(number)) == 1                  # nothing more issued
    rows = _audit(lab.url)
    assert [r.actor for r in rows if r.action == "station sign refused"] == \
        [OPERATOR[0], "(no session)"]
    assert [r.actor for r in rows if r.action == "issue"] == [SIGNATORY[0]]
    assert [r.actor for r in rows if r.action == "authentication refused"] == \
        [SIGNATORY[0]]
