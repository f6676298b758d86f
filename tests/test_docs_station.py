"""docs/station.md, "Setting up the server and the benches", word for word (issue 57):
every command line of that section is read from the document and run as written, with only
the substitutions the document itself allows (its names are examples): `server` is this
machine's PostgreSQL (127.0.0.1 and the port of a fresh cluster the test starts, every
login by password, scram-sha-256), each `'...'` password a made-up one kept in `~/.pgpass`
(mode 0600; HOME a temporary folder), /etc/ratebench and /srv/runs temporary folders,
/srv/benches/hall-1/runs the bench's own runs folder (the share the station reads), and
the station's `--host server` 127.0.0.1 (its port a free one). The openssl line makes the
station's self-signed certificate as written; the station serves over TLS with it.
Then the bench's `bench run procedure.yaml --lab lab.yaml` shows on the station's page
(read over HTTPS, the certificate verified as the desks' browsers would, for 127.0.0.1),
its draft listed with its draft certificate and its page offering the Certificate
section, and `bench records sync` and `bench records check` agree with the run directory.
"""

from __future__ import annotations

import json
import os
import pty
import re
import secrets
import select
import shlex
import shutil
import ssl
import subprocess
import sys
import time
import urllib.error
import urllib.request
from pathlib import Path

import pytest
import sqlalchemy as sa
import yaml

from tests.conftest import CONFIGS, ROOT, _env_without_lab, unavailable
from tests.pg_server import PgServer, PgUnavailable

DOC = ROOT / "docs" / "station.md"
SECTION = ("### Setting up the server and the benches", "### The lab file: one rule")


def _section() -> str:
    text = DOC.read_text()
    start, end = text.index(SECTION[0]), text.index(SECTION[1])
    return text[start:end]


def _blocks(section: str) -> list[str]:
    """The indented code blocks of the section (7 spaces: inside a numbered item), with a
    backslash continuation joined to one line."""
    blocks: list[str] = []
    current: list[str] = []
    for line in section.splitlines() + [""]:
        if line.startswith("       ") and line.strip():
            current.append(line.strip())
        elif current:
            blocks.append("\n".join(current).replace(" \\\n", " "))
            current = []
    return blocks


def _typed(cmd: list[str], answer: str, cwd: Path, env: dict[str, str]) -> tuple[int, str]:
    """Run `cmd` on a terminal of its own (a pseudo-terminal, as an operator's) and type
    `answer` at each password prompt; its exit status and everything it wrote."""
    master, slave = pty.openpty()
    p = subprocess.Popen(cmd, cwd=cwd, env=env, stdin=slave, stdout=slave, stderr=slave,
                         start_new_session=True)
    os.close(slave)
    said = ""
    deadline = time.monotonic() + 120
    try:
        while time.monotonic() < deadline:
            ready, _, _ = select.select([master], [], [], 0.2)
            if ready:
                try:
                    chunk = os.read(master, 4096).decode(errors="replace")
                except OSError:
                    break                     # the child closed the terminal
                if not chunk:
                    break
                said += chunk
                if said.rstrip().lower().endswith(":") and "password" in \
                        said.rstrip().splitlines()[-1].lower():
                    time.sleep(0.1)           # echo off first (getpass flushes typed-ahead)
                    os.write(master, (answer + "\n").encode())
            elif p.poll() is not None:
                break
        return p.wait(timeout=30), said
    finally:
        if p.poll() is None:
            p.kill()
        os.close(master)


def _end(proc: subprocess.Popen[str]) -> None:
    """Ctrl-C, then SIGKILL after 10 s: a server that ignores a signal it inherited as
    ignored (an xdist worker's) must not hold the test up."""
    import signal

    if proc.poll() is None:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(timeout=10)


@pytest.mark.timeout(400)
def test_the_station_setup_of_docs_station_md_word_for_word(tmp_path: Path) -> None:
    superuser = secrets.token_hex(8)
    try:
        pg = PgServer(superuser="postgres", password=superuser).start()
    except PgUnavailable as e:
        unavailable(str(e))
    server = f"127.0.0.1:{pg.port}"
    home = tmp_path / "home"
    home.mkdir()
    etc, srv = tmp_path / "etc" / "ratebench", tmp_path / "srv" / "runs"
    etc.mkdir(parents=True)
    srv.mkdir(parents=True)
    env = {**_env_without_lab(), "HOME": str(home)}
    env.pop("PGPASSFILE", None)
    station: subprocess.Popen[str] | None = None
    register_service: subprocess.Popen[str] | None = None

    def sub(text: str) -> str:
        return (text.replace("@server/", f"@{server}/").replace("/etc/ratebench", str(etc))
                .replace("/srv/runs", str(srv))
                .replace("/srv/benches/hall-1/runs", str(etc / "runs"))
                .replace("--host server", "--host 127.0.0.1"))

    def bench(line: str, cwd: Path = tmp_path, stdin: str = "", doc: bool = True
              ) -> subprocess.CompletedProcess[str]:
        """A command line: the document's (substituted), or the test's own (doc=False)."""
        args = (sub(line) if doc else line).split()
        assert args[0] == "bench", line
        return subprocess.run([sys.executable, "-m", "bench", *args[1:]], cwd=cwd, text=True,
                              input=stdin, capture_output=True, timeout=300, env=env)

    try:
        blocks = _blocks(_section())
        sql, records_init, register_init, service, lab, stand_block, openssl, serve = blocks
        # 1. roles and databases, as the cluster's superuser; each '...' a password of its own
        passwords: dict[str, str] = {}
        statements = []
        for stmt in sql.splitlines():
            stmt = stmt.split("--")[0].strip().rstrip(";")
            role = re.match(r"CREATE ROLE (\w+) LOGIN PASSWORD '\.\.\.'", stmt)
            if role:
                passwords[role.group(1)] = secrets.token_hex(12)
                stmt = stmt.replace("'...'", f"'{passwords[role.group(1)]}'")
            statements.append(stmt)
        assert set(passwords) == {"lab_owner", "register_service", "bench", "station"}
        pg.admin(*statements)
        pgpass = home / ".pgpass"
        pgpass.write_text("".join(f"127.0.0.1:{pg.port}:*:{r}:{p}\n"
                                  for r, p in passwords.items()))
        pgpass.chmod(0o600)
        # 2. the records, as their owner
        done = bench(records_init)
        assert done.returncode == 0, done.stdout + done.stderr
        # 3. the register, as its owner: the admin's new password typed at a terminal
        admin_pw = "Lab-root-" + secrets.token_hex(6)
        code, said = _typed([sys.executable, "-m", "bench", *sub(register_init).split()[1:]],
                            admin_pw, tmp_path, env)
        assert code == 0, said
        # 4. the register service, on this machine (its port: a free one)
        assert service.startswith("bench register serve ") and "--port 8741" in service
        svc_args = sub(service).replace("--port 8741", "--port 0").split()
        register_service = subprocess.Popen([sys.executable, "-m", "bench", *svc_args[1:]],
                                            cwd=tmp_path, text=True, stdout=subprocess.PIPE,
                                            stderr=subprocess.STDOUT, env=env)
        assert register_service.stdout is not None
        listening = register_service.stdout.readline()
        found = re.search(r"http://127\.0\.0\.1:\d+", listening)
        assert found, listening + (register_service.stdout.read()
                                   if register_service.poll() is not None else "")
        # 5. the lab file, shared by every bench: the register is the service
        assert lab.startswith("records: ") and "register: http://127.0.0.1:8741" in lab
        (etc / "lab.yaml").write_text(sub(lab).replace("http://127.0.0.1:8741",
                                                        found.group(0)) + "\n")
        # 6. the bench's stand file names the bench; a short procedure of this bench's
        stand = yaml.safe_load((CONFIGS / "stands" / "sim-two-axis.yaml").read_text())
        stand.update(yaml.safe_load(stand_block))
        (etc / "stand.yaml").write_text(yaml.safe_dump(stand, sort_keys=False))
        (etc / "procedure.yaml").write_text(yaml.safe_dump({
            "procedure": "rate-ladder", "title": "docs walk", "stand": "stand.yaml",
            "turns": 2, "static_record_s": 5, "harmonics": 1, "prompts": False,
            "axes": {"outer": {"rates_dps": [20]}},
            "tolerance": {"rate_error": [{"rel": 1e-3}]}}))
        # 7. the station: its certificate and key as written, then over TLS with them
        if shutil.which("openssl") is None:
            unavailable("openssl is not installed (Debian package `openssl`)")
        assert openssl.startswith("openssl req -x509 "), openssl
        made = subprocess.run(shlex.split(sub(openssl)), cwd=tmp_path, text=True,
                              capture_output=True, timeout=120, env=env)
        assert made.returncode == 0, made.stdout + made.stderr
        assert (etc / "station.key").stat().st_mode & 0o077 == 0     # its owner's only
        (etc / "runs").mkdir()                 # the bench's runs folder, the station's share
        assert "--tls-cert" in serve and "--host server" in serve
        args = sub(serve).split()
        station = subprocess.Popen([sys.executable, "-m", "bench", *args[1:], "--port", "0"],
                                   cwd=tmp_path, text=True, stdout=subprocess.PIPE,
                                   stderr=subprocess.STDOUT,
                                   env={**env, "BENCH_STATION_TOKEN": secrets.token_hex(8)})
        assert station.stdout is not None
        first = station.stdout.readline()
        started = re.search(r"https://127\.0\.0\.1:(\d+)/", first)
        assert started, f"bench serve did not say where it listens: {first}"
        page = f"https://127.0.0.1:{started.group(1)}"
        tls = ssl.create_default_context(cafile=str(etc / "station.crt"))
        # then, on the bench: the sentence after the steps, as written
        then = re.search(r"Then `(bench run [^`]+)` on any bench", _section())
        assert then is not None and then.group(1) == "bench run procedure.yaml --lab lab.yaml"
        t0 = time.monotonic()
        ran = bench(then.group(1), cwd=etc)
        took_s = time.monotonic() - t0
        assert ran.returncode == 0, ran.stdout + ran.stderr
        run = etc / ran.stdout.strip().splitlines()[-1]
        with urllib.request.urlopen(f"{page}/api/fleet", timeout=10, context=tls) as resp:
            shown = json.loads(resp.read())
        assert [(b["bench"], b["run"], b["status"]) for b in shown] == [
            ("rate-table-hall-2", run.name, "passed")], shown
        # its draft, listed with its draft certificate (the station reads that folder),
        # and its page with the Certificate section
        with urllib.request.urlopen(f"{page}/", timeout=30, context=tls) as resp:
            lab_page = resp.read().decode()
        row = re.search(r'<tr data-uid="(\w+)">.*?</tr>', lab_page, re.S)
        assert row and run.name in row.group(0) and 'class="draft-pdf"' in row.group(0), \
            lab_page
        uid = row.group(1)
        try:
            with urllib.request.urlopen(f"{page}/bench/rate-table-hall-2/{uid}",
                                        timeout=30, context=tls) as resp:
                run_page = resp.read().decode()
        except urllib.error.HTTPError as e:
            _end(station)
            pytest.fail(f"the run's page: {e}: {station.stdout.read()[-3000:]}")
        assert "Draft, not authorised" in run_page and 'id="sign-login"' in run_page, run_page
        synced = bench("bench records sync", cwd=etc)
        assert synced.returncode == 0, synced.stdout + synced.stderr
        assert "0 new event(s)" in synced.stdout, synced.stdout
        checked = bench(f"bench records check {run}", cwd=etc, doc=False)
        assert checked.returncode == 0 and "equal" in checked.stdout, checked.stdout
        # the records went to the lab database alone, with the bench's own password
        assert not (etc / "runs" / "records.sqlite").exists()
        eng = sa.create_engine(f"postgresql+psycopg://postgres:{superuser}@{server}/lab_records")
        try:
            with eng.connect() as c:
                assert c.execute(sa.text("SELECT count(*) FROM runs")).scalar_one() == 1
        finally:
            eng.dispose()
        print(f"\ndocs/station.md walk: bench run {took_s:.1f} s")
    finally:
        for proc in (station, register_service):
            if proc is not None:
                _end(proc)
        pg.stop()


def test_the_two_serve_lines_of_logging_in_word_for_word(tmp_path: Path) -> None:
    """docs/station.md, "Logging in and signing a draft": both `bench serve` lines as
    written (in a folder with runs/, lab.yaml and lab-register.sqlite; the port a free one,
    the one substitution), each starting a station that logs in against the register."""
    from tests.registers import sqlite_register

    text = DOC.read_text()
    part = text[text.index("## Logging in and signing a draft"):]
    lines = [ln.split("#")[0].strip() for ln in part.splitlines()[:20]
             if ln.startswith("    bench serve ")]
    assert len(lines) == 2, lines
    (tmp_path / "runs").mkdir()
    made = Path(sqlite_register(tmp_path / "made").removeprefix("sqlite:///"))
    made.rename(tmp_path / "lab-register.sqlite")
    (tmp_path / "lab.yaml").write_text("register: sqlite:///lab-register.sqlite\n")
    for line in lines:
        p = subprocess.Popen([sys.executable, "-m", "bench", *line.split()[1:], "--port", "0",
                              "--token", "t0ken"], cwd=tmp_path, text=True,
                             stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                             env=_env_without_lab())
        try:
            assert p.stdout is not None
            first, second = p.stdout.readline(), p.stdout.readline()
            assert first.startswith("Station view of") and "http://127.0.0.1:" in first, first
            assert second.startswith("Log in and sign at /login: accounts of register "), \
                second
        finally:
            _end(p)
