"""A throwaway PostgreSQL server for the records tests (a real server, not a mock).

The distribution's PostgreSQL binaries (Debian `postgresql`, installed by .ci/run) run
from a temporary directory on a free port. initdb and postgres refuse to run as root,
and CI runs as root, so as root they run as the `postgres` system user (runuser).
`PgServer.start()` raises `PgUnavailable` with the reason when that cannot be done; the
tests then skip with that reason (in CI they fail: tests.conftest.unavailable).
"""

from __future__ import annotations

import contextlib
import glob
import os
import pwd
import shutil
import socket
import subprocess
import tempfile
import time
from pathlib import Path

import sqlalchemy as sa


class PgUnavailable(RuntimeError):
    """No PostgreSQL server can be started here; the message says why."""


def _bindir() -> Path:
    for env in (os.environ.get("PG_BINDIR"),):
        if env and (Path(env) / "initdb").exists():
            return Path(env)
    found = sorted(glob.glob("/usr/lib/postgresql/*/bin/initdb"), reverse=True)
    if found:
        return Path(found[0]).parent
    which = shutil.which("initdb")
    if which:
        return Path(which).parent
    raise PgUnavailable("PostgreSQL server binaries not found (install the Debian package "
                        "`postgresql`, as .ci/run does, or set PG_BINDIR)")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


class PgServer:
    """One postgres process; `url(db)` names a database on it."""

    def __init__(self, superuser: str = "bench", password: str | None = None) -> None:
        """`password`: a cluster whose every login is by password (scram-sha-256, as a
        lab's is, docs/station.md); the `superuser` has it. Default: trust."""
        self.password = password
        self.bindir = _bindir()
        self.port = _free_port()
        self.tmp = Path(tempfile.mkdtemp(prefix="ratebench-pg-"))
        self.data = self.tmp / "data"
        self.proc: subprocess.Popen[bytes] | None = None
        self.prefix: list[str] = []
        if os.geteuid() == 0:
            try:
                user = pwd.getpwnam("postgres")
            except KeyError:
                raise PgUnavailable("running as root and there is no `postgres` user to run "
                                    "the server as (install the Debian package "
                                    "`postgresql`)") from None
            runuser = shutil.which("runuser") or shutil.which("setpriv")
            if runuser is None:
                raise PgUnavailable("running as root without runuser/setpriv")
            self.prefix = ([runuser, "-u", "postgres", "--"] if runuser.endswith("runuser")
                           else [runuser, f"--reuid={user.pw_uid}", f"--regid={user.pw_gid}",
                                 "--init-groups"])
            os.chown(self.tmp, user.pw_uid, user.pw_gid)
        self.user = superuser

    def _run(self, *cmd: str) -> None:
        out = subprocess.run([*self.prefix, *cmd], capture_output=True, text=True, timeout=120)
        if out.returncode:
            raise PgUnavailable(f"{Path(cmd[0]).name} failed: {out.stderr.strip()[-400:]}")

    def start(self) -> PgServer:
        auth = ["--auth=trust"]
        if self.password is not None:
            pwfile = self.tmp / "superuser.pw"
            pwfile.write_text(self.password + "\n")
            if self.prefix:
                user = pwd.getpwnam("postgres")
                os.chown(pwfile, user.pw_uid, user.pw_gid)
            auth = ["--auth=scram-sha-256", f"--pwfile={pwfile}"]
        self._run(str(self.bindir / "initdb"), "-D", str(self.data), "-U", self.user,
                  *auth, "--no-sync", "-E", "UTF8")
        self.proc = subprocess.Popen(
            [*self.prefix, str(self.bindir / "postgres"), "-D", str(self.data),
             "-p", str(self.port), "-k", str(self.tmp), "-c", "listen_addresses=127.0.0.1",
             "-c", "fsync=off", "-c", "max_connections=40"],
            stdout=subprocess.DEVNULL, stderr=open(self.tmp / "server.log", "wb"))  # noqa: SIM115
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            if self.proc.poll() is not None:
                raise PgUnavailable("postgres exited: "
                                    + (self.tmp / "server.log").read_text()[-400:])
            try:
                eng = sa.create_engine(self._admin_url())
                with eng.connect():
                    pass
                eng.dispose()
                return self
            except sa.exc.OperationalError:
                time.sleep(0.2)
        raise PgUnavailable("postgres did not accept connections within 60 s")

    def url(self, database: str) -> str:
        return f"postgresql://{self.user}@127.0.0.1:{self.port}/{database}"

    def _admin_url(self) -> str:
        """The superuser's URL, with its password where the cluster asks for one."""
        login = self.user if self.password is None else f"{self.user}:{self.password}"
        return f"postgresql+psycopg://{login}@127.0.0.1:{self.port}/postgres"

    def admin(self, *sql: str) -> None:
        """Statements run outside a transaction (CREATE/ALTER DATABASE)."""
        eng = sa.create_engine(self._admin_url(), isolation_level="AUTOCOMMIT")
        try:
            with eng.connect() as c:
                for q in sql:
                    c.exec_driver_sql(q)
        finally:
            eng.dispose()

    def create_database(self, name: str) -> str:
        self.admin(f'CREATE DATABASE "{name}"')
        return self.url(name)

    def block(self, name: str) -> None:
        """Make one database unreachable: refuse new connections, end the open ones."""
        self.admin(f'ALTER DATABASE "{name}" ALLOW_CONNECTIONS false',
                   f"SELECT pg_terminate_backend(pid) FROM pg_stat_activity "
                   f"WHERE datname = '{name}'")

    def unblock(self, name: str) -> None:
        self.admin(f'ALTER DATABASE "{name}" ALLOW_CONNECTIONS true')

    def stop(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.terminate()
            with contextlib.suppress(subprocess.TimeoutExpired):
                self.proc.wait(timeout=30)
            if self.proc.poll() is None:
                self.proc.kill()
        shutil.rmtree(self.tmp, ignore_errors=True)
