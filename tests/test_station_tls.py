"""Signing from a desk (issue 59): the station over TLS, passwords over TLS from the lab's
networks and never over plain HTTP off this machine, and every bench's drafts signed
from the station.

The browser test drives the real server (`bench serve --tls-cert --tls-key`, cheroot) in
headless chromium over HTTPS on 127.0.0.1 with a self-signed certificate made here
(cryptography), chromium trusting exactly that certificate's key; the lab database is a
real PostgreSQL (tests/pg_server.py) to which another bench's runs folder is delivered
(`sync_folder`, what `bench records sync` runs, under the bench name rate-table-hall-2);
the register is an SQLite lab register made here. The refusals over plain HTTP are raw
requests to a real plain station on 127.0.0.1 with a Host header or X-Forwarded-For that
names another machine. What a request from another address does is checked through
Flask's test client (REMOTE_ADDR, https base URL), as tests/test_station_signing.py does:
this machine can make no other address for real, and every test address stays on
127.0.0.1 / ::1 (192.0.2.0/24 and 10.1.0.0/16 appear only as header and environ values).
"""

from __future__ import annotations

import argparse
import datetime as dt
import hashlib
import http.client
import ipaddress
import json
import os
import re
import ssl
import subprocess
import sys
import time
import urllib.error
import urllib.request
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from bench.app.register import Register
from bench.app.station.app import StationSettings, create_app
from bench.app.station.serve import add_serve_arguments, settings_from_args
from bench.app.station.signing import SESSION_COOKIE
from tests.conftest import ROOT, DemoRun, unavailable
from tests.test_station import TOKEN, _browser, _chromium, _stop, _wait, hand_made_runs
from tests.test_station_signing import (
    LAB_ENV,
    SIGNATORY,
    Lab,
    _lab,
    _login,
    _pdf_text,
    _run_uid,
    enrol_in_register,
    serve,
)

HALL2 = "rate-table-hall-2"
LAN = {"REMOTE_ADDR": "10.1.2.3"}            # a desk in the lab's network (environ only)
ELSEWHERE = {"REMOTE_ADDR": "192.0.2.7"}     # an address outside it (TEST-NET-1)


@pytest.fixture(autouse=True)
def _no_lab_of_the_developer(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(LAB_ENV, raising=False)


def self_signed(folder: Path, names: tuple[str, ...] = ("localhost", "station.lab.example")
                ) -> tuple[Path, Path]:
    """A self-signed certificate for 127.0.0.1, ::1 and `names`, and its key (PEM)."""
    from cryptography import x509
    from cryptography.hazmat.primitives import hashes, serialization
    from cryptography.hazmat.primitives.asymmetric import ec
    from cryptography.x509.oid import NameOID

    key = ec.generate_private_key(ec.SECP256R1())
    name = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, names[-1])])
    now = dt.datetime.now(dt.UTC)
    cert = (x509.CertificateBuilder().subject_name(name).issuer_name(name)
            .public_key(key.public_key()).serial_number(x509.random_serial_number())
            .not_valid_before(now - dt.timedelta(minutes=5))
            .not_valid_after(now + dt.timedelta(days=2))
            .add_extension(x509.SubjectAlternativeName(
                [x509.IPAddress(ipaddress.ip_address("127.0.0.1")),
                 x509.IPAddress(ipaddress.ip_address("::1")),
                 *(x509.DNSName(n) for n in names)]), critical=False)
            .add_extension(x509.BasicConstraints(ca=True, path_length=None), critical=True)
            .sign(key, hashes.SHA256()))
    folder.mkdir(parents=True, exist_ok=True)
    crt, pem = folder / "station.crt", folder / "station.key"
    crt.write_bytes(cert.public_bytes(serialization.Encoding.PEM))
    pem.write_bytes(key.private_bytes(serialization.Encoding.PEM,
                                      serialization.PrivateFormat.PKCS8,
                                      serialization.NoEncryption()))
    pem.chmod(0o600)
    return crt, pem


def spki_sha256(crt: Path) -> str:
    """The base64 SHA-256 of the certificate's public key (chromium's
    --ignore-certificate-errors-spki-list: trust this key, nothing else)."""
    import base64

    from cryptography import x509
    from cryptography.hazmat.primitives import serialization

    spki = x509.load_pem_x509_certificate(crt.read_bytes()).public_key().public_bytes(
        serialization.Encoding.DER, serialization.PublicFormat.SubjectPublicKeyInfo)
    return base64.b64encode(hashlib.sha256(spki).digest()).decode()


# -- the rules, through the WSGI test client ------------------------------------------------------

@pytest.fixture(scope="module")
def lab(tmp_path_factory: pytest.TempPathFactory) -> Lab:
    """One SQLite lab register for the rule tests (its accounts cost seconds of argon2id);
    none of them enters a wrong password, so no lockout carries over."""
    return _lab(tmp_path_factory.mktemp("lab"))


def _app(tmp: Path, lab: Lab, **kw: Any) -> Any:
    runs = hand_made_runs(tmp)
    return create_app(StationSettings(runs, TOKEN, register_url=lab.url,
                                      lab_file=str(lab.file), **kw))


def test_plain_http_takes_passwords_from_this_machine_only(tmp_path: Path, lab: Lab) -> None:
    app = _app(tmp_path, lab, server_names=("station.lab.example",))
    c = app.test_client()
    name, _, pw = SIGNATORY
    # a Host that names the server by its network name: the browser is elsewhere
    r = _login(c, name, pw, headers={"Host": "station.lab.example:8765"})
    said = r.get_data(as_text=True)
    assert r.status_code == 403 and SESSION_COOKIE not in r.headers.get("Set-Cookie", "")
    assert "not accepted over plain HTTP" in said and "station.lab.example" in said, said
    # a proxy on this machine relaying for another one (not trusted: still refused)
    r = _login(c, name, pw, headers={"X-Forwarded-For": "192.0.2.7"})
    assert r.status_code == 403 and "forwarded for 192.0.2.7" in r.get_data(as_text=True)
    r = _login(c, name, pw, headers={"Forwarded": 'for="192.0.2.7"'})
    assert r.status_code == 403
    # another machine, with the token (pages readable): no password
    r = _login(c, name, pw, environ_base=ELSEWHERE, headers={"X-Bench-Token": TOKEN})
    assert r.status_code == 403 and "it came from 192.0.2.7" in r.get_data(as_text=True)
    # a Host the station does not answer to: refused before anything, naming it
    r = c.get("/login", headers={"Host": "evil.example"})
    assert r.status_code == 403 and "evil.example" in r.get_data(as_text=True)
    # this machine: logged in; the cookie is not Secure (plain HTTP would never send it)
    r = _login(c, name, pw)
    assert r.status_code == 303
    cookie = r.headers["Set-Cookie"]
    assert "HttpOnly" in cookie and "SameSite=Strict" in cookie and "Secure" not in cookie


def test_over_tls_passwords_from_the_lab_networks_and_secure_cookies(tmp_path: Path, lab: Lab) -> None:
    app = _app(tmp_path, lab, password_networks=("10.1.0.0/16",),
               server_names=("station.lab.example",))
    https = "https://station.lab.example"
    name, _, pw = SIGNATORY
    desk = app.test_client()
    # a desk of the lab's network over TLS: reads without the token, logs in, Secure cookie
    assert desk.get("/", base_url=https, environ_base=LAN).status_code == 200
    r = _login(desk, name, pw, base_url=https, environ_base=LAN)
    assert r.status_code == 303, r.get_data(as_text=True)
    cookie = r.headers["Set-Cookie"]
    assert cookie.startswith(f"{SESSION_COOKIE}=") and "; Secure" in cookie
    assert "HttpOnly" in cookie and "SameSite=Strict" in cookie
    page = desk.get("/run/20260101-000000-demo", base_url=https, environ_base=LAN)
    said = page.get_data(as_text=True)       # past the password rule: the run's own state
    assert "Nothing to sign yet" in said and "not accepted over" not in said
    # the same desk over plain HTTP: no password (and the pages want the token)
    plain = app.test_client()
    assert plain.get("/", environ_base=LAN).status_code == 403
    r = _login(plain, name, pw, environ_base=LAN, headers={"X-Bench-Token": TOKEN,
                                                           "Host": "station.lab.example"})
    assert r.status_code == 403 and "not accepted over plain HTTP" in r.get_data(as_text=True)
    # over TLS from outside the lab's networks: the token to read, and no password
    far = app.test_client()
    assert far.get("/", base_url=https, environ_base=ELSEWHERE).status_code == 403
    r = _login(far, name, pw, base_url=https, environ_base=ELSEWHERE,
               headers={"X-Bench-Token": TOKEN})
    said = r.get_data(as_text=True)
    assert r.status_code == 403 and "accepted over TLS only from the lab" in said and "(10.1.0.0/16:" in said, said
    assert "came from 192.0.2.7" in said


def test_behind_the_trusted_proxy_its_forwarded_headers_alone_count(tmp_path: Path, lab: Lab) -> None:
    """A TLS proxy on this machine (nginx) in front of a plain station: its
    X-Forwarded-Proto and X-Forwarded-For count; the same headers from anyone else do not."""
    app = _app(tmp_path, lab, trusted_proxy="127.0.0.2", password_networks=("10.1.0.0/16",),
               server_names=("station.lab.example",))
    via = {"X-Forwarded-Proto": "https", "X-Forwarded-For": "10.1.2.3",
           "Host": "station.lab.example"}
    c = app.test_client()
    r = _login(c, *SIGNATORY[::2], environ_base={"REMOTE_ADDR": "127.0.0.2"}, headers=via)
    assert r.status_code == 303 and "; Secure" in r.headers["Set-Cookie"]
    r = _login(app.test_client(), *SIGNATORY[::2], headers=via)    # 127.0.0.1: not the proxy
    assert r.status_code == 403 and "not accepted over plain HTTP" in r.get_data(as_text=True)


def test_serve_options_for_tls_say_what_is_wrong(tmp_path: Path) -> None:
    parser = argparse.ArgumentParser()
    add_serve_arguments(parser)
    crt, key = self_signed(tmp_path / "a")
    other_crt, other_key = self_signed(tmp_path / "b")

    def settings(*args: str) -> StationSettings:
        return settings_from_args(parser.parse_args(["--token", "t", *args]))[0]

    s = settings("--tls-cert", str(crt), "--tls-key", str(key), "--passwords-from",
                 "10.1.0.0/16", "--server-name", "station.lab.example",
                 "--other-runs", str(tmp_path))
    assert s.tls and s.password_networks == ("127.0.0.0/8", "::1/128", "10.1.0.0/16")
    assert s.other_runs == (tmp_path,) and s.runs_folders[1:] == (tmp_path,)
    assert settings("--tls-cert", str(crt), "--tls-key", str(key)).password_networks == \
        ("127.0.0.0/8", "::1/128")                       # default: this machine only
    assert not settings().tls
    for args, said in (
            (["--tls-cert", str(crt)], "--tls-cert and --tls-key go together"),
            (["--passwords-from", "10.1.0.0/16"], "--passwords-from needs TLS"),
            (["--tls-cert", str(crt), "--tls-key", str(key), "--passwords-from", "lab"],
             "'lab' is not a network"),
            (["--tls-cert", str(crt), "--tls-key", str(other_key)],
             "the key is not the certificate's"),
            (["--tls-cert", str(tmp_path / "no.crt"), "--tls-key", str(key)], "not found"),
            (["--tls-cert", str(other_crt.parent / "station.key"), "--tls-key", str(key)],
             "not a PEM certificate"),
            (["--other-runs", str(tmp_path / "nowhere")], "nowhere: not a folder")):
        with pytest.raises(SystemExit, match=re.escape(said)):
            settings(*args)


# -- in a browser, over HTTPS, a draft of another bench -------------------------------------------

def _raw(port: int, method: str, path: str, headers: dict[str, str], body: str = ""
         ) -> tuple[int, str]:
    """A request to 127.0.0.1:port over plain HTTP with exactly these headers."""
    conn = http.client.HTTPConnection("127.0.0.1", port, timeout=20)
    try:
        conn.putrequest(method, path, skip_host=True, skip_accept_encoding=True)
        for k, v in {**headers, "Content-Length": str(len(body.encode()))}.items():
            conn.putheader(k, v)
        conn.endheaders(body.encode())
        resp = conn.getresponse()
        return resp.status, resp.read().decode(errors="replace")
    finally:
        conn.close()


@pytest.fixture
def hall2(demo_run: DemoRun, pg: Any, tmp_path: Path) -> Iterator[tuple[Path, str]]:
    """Another bench's runs folder holding a draft (a copy of the session's demo run),
    delivered to a lab database under the bench name rate-table-hall-2."""
    from bench.app.fleet.sync import sync_folder
    from bench.app.records import Records

    assert demo_run.status == 0, demo_run.stderr[-3000:]
    url = pg.create_database("station_tls_lab")
    Records.open(url).close()
    run = demo_run.copy_to(tmp_path / "hall-2" / "runs")
    [delivered] = sync_folder(run.parent, url, bench=HALL2)
    assert delivered is not None
    yield run, url


@pytest.mark.timeout(300)
def test_a_desk_signs_another_benchs_draft_over_https(hall2: tuple[Path, str],
                                                      tmp_path: Path) -> None:
    found = _chromium()
    if found is None:
        unavailable("chromium and chromium-driver are not installed (Debian packages "
                    "`chromium chromium-driver`; .ci/run installs them)")
    from selenium.webdriver.common.by import By

    t0 = time.monotonic()
    run, records = hall2
    lab = _lab(tmp_path)
    enrol_in_register(run, lab.url)
    crt, key = self_signed(tmp_path / "tls")
    own = tmp_path / "station-runs"
    own.mkdir()
    env = {**os.environ}
    env.pop(LAB_ENV, None)
    proc, base, said = serve(["--runs", str(own), "--other-runs", str(run.parent),
                               "--records", records, "--lab", str(lab.file),
                               "--tls-cert", str(crt), "--tls-key", str(key)], env)
    plain = None
    driver = None
    try:
        assert base.startswith("https://127.0.0.1:"), said
        assert "TLS: certificate" in said and "127.0.0.0/8, ::1/128" in said, said
        # TLS for real: the certificate verifies for 127.0.0.1 against itself as the CA
        tls = ssl.create_default_context(cafile=str(crt))
        with urllib.request.urlopen(f"{base}/login", context=tls, timeout=20) as resp:
            assert resp.status == 200
        with pytest.raises(urllib.error.URLError, match="CERTIFICATE_VERIFY_FAILED"):
            urllib.request.urlopen(f"{base}/", context=ssl.create_default_context(),
                                   timeout=20)

        driver = _browser(found, height=1400,
                          extra=(f"--ignore-certificate-errors-spki-list={spki_sha256(crt)}",))
        driver.get(f"{base}/")
        # the lab page lists hall-2's draft (on the twins: the simulated drafts' table)
        row = _wait(lambda: next((r for r in driver.find_elements(
            By.CSS_SELECTOR, "#drafts-simulated tr[data-uid]")
            if r.get_attribute("data-uid") == _run_uid(run)), None), 20, "hall-2's draft")
        assert HALL2 in row.text and run.name in row.text, row.text
        assert row.find_elements(By.CLASS_NAME, "draft-pdf"), row.text   # its draft, reachable
        row.find_element(By.CLASS_NAME, "draft-link").click()
        _wait(lambda: driver.find_elements(By.ID, "cert-status"), 20, "the draft's page")
        page_url = driver.current_url
        assert f"/bench/{HALL2}/" in page_url
        assert driver.find_element(By.ID, "cert-status").text.startswith("Draft, not authorised")
        assert str(run.parent.resolve()) in driver.find_element(By.ID, "run-folder").text
        assert not driver.find_elements(By.ID, "draft-pdf")   # the sign form: a signatory's
        driver.find_element(By.ID, "sign-login").click()
        driver.find_element(By.ID, "login-name").send_keys(SIGNATORY[0])
        driver.find_element(By.ID, "login-password").send_keys(SIGNATORY[2])
        driver.find_element(By.ID, "login-submit").click()
        _wait(lambda: driver.current_url == page_url and driver.find_elements(By.ID, "who"),
              20, "the login back to the draft's page")
        cookie = driver.get_cookie(SESSION_COOKIE)
        assert cookie and cookie["secure"] and cookie["httpOnly"], cookie
        assert cookie["sameSite"] == "Strict", cookie
        href = driver.find_element(By.ID, "draft-pdf").get_attribute("href")
        with urllib.request.urlopen(str(href), context=tls, timeout=20) as resp:
            assert resp.read() == (run / "certificate.pdf").read_bytes()   # the draft shown
        driver.find_element(By.ID, "sign-password").send_keys(SIGNATORY[2])
        driver.find_element(By.ID, "sign").click()
        title = _wait(lambda: next((e.text for e in driver.find_elements(By.ID, "sign-title")),
                                   None), 120, "the sign request's answer")
        lines = driver.find_element(By.TAG_NAME, "main").text
        assert title == "Issued", lines
        with Register.open(lab.url, migrate=False) as reg:
            number = reg.number_of_run(_run_uid(run))
            assert number is not None
            [rev] = reg.revisions(number)
        assert (rev.signatory, rev.signatory_name) == (SIGNATORY[0], SIGNATORY[1])
        issued = run / "issued" / number / "certificate.pdf"      # in hall-2's folder
        assert issued.is_file()
        assert hashlib.sha256(issued.read_bytes()).hexdigest() == rev.pdf_sha256
        assert f"authorised for issue by {SIGNATORY[1]}" in _pdf_text(issued)
        verified = subprocess.run([sys.executable, "-m", "bench", "verify", str(issued),
                                   "--register", lab.url], cwd=ROOT, text=True,
                                  capture_output=True, timeout=120, env=env)
        assert verified.returncode == 0, verified.stdout + verified.stderr
        assert "issued" in verified.stdout, verified.stdout
        # issued: no longer waiting on the lab page
        driver.get(f"{base}/")
        _wait(lambda: driver.find_elements(By.ID, "fleet"), 20, "the lab page")
        assert not [r for r in driver.find_elements(By.CSS_SELECTOR, "tr[data-uid]")
                    if r.get_attribute("data-uid") == _run_uid(run)]

        # plain HTTP: a station on 127.0.0.1 named station.lab.example refuses a password
        # sent under that Host, or forwarded for another machine, and takes this machine's
        # (and, not reading hall-2's folder, it shows hall-2's run without signing it)
        plain, plain_base, _ = serve(["--runs", str(own), "--lab", str(lab.file),
                                      "--records", records,
                                      "--server-name", "station.lab.example"], env)
        port = int(plain_base.rsplit(":", 1)[1])
        for headers, why in (({"Host": "station.lab.example"}, "the Host header names "
                              "station.lab.example"),
                             ({"Host": f"127.0.0.1:{port}", "X-Forwarded-For": "192.0.2.7"},
                              "it was forwarded for 192.0.2.7")):
            status, page = _raw(port, "GET", "/login", headers)
            assert status == 200 and "not accepted over plain HTTP" in page, page
            assert 'id="login-form"' not in page
            status, page = _raw(port, "POST", "/login", {
                **headers, "Content-Type": "application/x-www-form-urlencoded"},
                f"name={SIGNATORY[0]}&password={SIGNATORY[2]}&token=x")
            assert status == 403 and why in page, page
        status, page = _raw(port, "GET", "/login", {"Host": f"127.0.0.1:{port}"})
        assert status == 200 and 'id="login-form"' in page
        here = {"Host": f"127.0.0.1:{port}"}
        status, page = _raw(port, "GET", f"/bench/{HALL2}/{_run_uid(run)}", here)
        assert status == 200 and "in none of this station's runs folders" in page, page
        assert 'id="sign-form"' not in page and 'id="cert-status"' not in page
        status, page = _raw(port, "POST", f"/bench/{HALL2}/{_run_uid(run)}/sign", {
            **here, "Content-Type": "application/x-www-form-urlencoded"}, "password=x")
        assert status == 404 and "none of this station" in page, page
    finally:
        if driver is not None:
            driver.quit()
        for p in (proc, plain):
            if p is not None:
                _stop(p)
    print(f"\nissue 59 browser test over HTTPS: {time.monotonic() - t0:.1f} s")



def test_a_drafts_folder_is_the_one_whose_meta_names_its_uid(tmp_path: Path) -> None:
    """Two benches' runs of one name (started in the same second): each draft's folder is
    found by the uid in its meta.json, never by its name alone; no path leaves a folder."""
    from bench.app.station.drafts import find_run

    folders = []
    for bench_name in ("hall-1", "hall-2"):
        run = tmp_path / bench_name / "runs" / "20261129-100000-demo"
        run.mkdir(parents=True)
        (run / "events.jsonl").write_text("")
        (run / "meta.json").write_text(json.dumps({"run_uid": f"uid-of-{bench_name}"}))
        folders.append(run.parent)
    name = "20261129-100000-demo"
    assert find_run(folders, name, "uid-of-hall-2") == (folders[1] / name).resolve()
    assert find_run(folders, name, "uid-of-hall-1") == (folders[0] / name).resolve()
    assert find_run(folders, name, "uid-of-hall-3") is None
    for bad in ("", "..", f"../runs/{name}", f"{name}/..", ".hidden"):
        assert find_run(folders, bad, "uid-of-hall-1") is None
