"""Lab registers for tests: a real SQLite register file with the lab's accounts, made once
per test process (its passwords hashed with the suite's cheap argon2id parameters,
tests/conftest.py `cheap_password_hashes`) and copied for each test, and the lab file that
names it. `authorise` issues with the signatory's password on stdin, as a script would
(`--password-stdin`)."""

from __future__ import annotations

import contextlib
import io
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING

from tests.conftest import cli

if TYPE_CHECKING:
    from bench.app.register.store import RunRecord

#: account: (password, roles, full name, function)
ACCOUNTS: dict[str, tuple[str, tuple[str, ...], str, str | None]] = {
    "admin": ("keeper-of-keys-1", ("admin",), "R. Admin", "Register administrator"),
    "P. Petrov": ("petrov-pass-1", ("signatory", "reviewer"), "P. Petrov",
                  "Technical manager (authorised signatory)"),
    "A. Tester": ("tester-pass-1", ("signatory",), "A. Tester", "Head of calibration"),
    "A. Ivanova": ("ivanova-pass-1", ("operator",), "A. Ivanova", "Calibration engineer"),
    "Q. Manager": ("quality-pass-1", ("quality",), "Q. Manager", "Quality manager"),
}
#: the issuer as the tests' register holds it (printed on every issued certificate)
ISSUER = {"issuer.name": "Test Rate Lab", "issuer.address": "Example Street 1, Example City",
          "issuer.code": "D-K-00000-01", "issuer.accreditation": "not accredited (test lab)",
          "issuer.prefix": "RT"}
_TEMPLATE: list[Path] = []


def password(account: str) -> str:
    return ACCOUNTS[account][0]


def fill(url: str) -> None:
    """Create the register at `url` with every account of ACCOUNTS."""
    from bench.app.register import Register

    with Register.open(url) as reg:
        reg.init("admin", ACCOUNTS["admin"][2], password("admin"))
        admin = reg.authenticate("admin", password("admin"), "admin")
        for name, (pw, roles, full, function) in ACCOUNTS.items():
            if name != "admin":     # an admin-set password, changed by its holder (issue 53)
                reg.add_account(admin, name, full, roles, pw + "-initial", function)
                reg.change_password(name, pw + "-initial", pw)
        for key, value in ISSUER.items():   # the issuer's identity (issue 54)
            reg.set_setting(admin, key, value)


def sqlite_register(folder: Path) -> str:
    """A fresh copy of the template register in `folder`; returns its URL."""
    if not _TEMPLATE:
        path = Path(tempfile.mkdtemp(prefix="ratebench-register-")) / "register.sqlite"
        fill(f"sqlite:///{path}")
        _TEMPLATE.append(path)
    folder.mkdir(parents=True, exist_ok=True)
    target = folder / "register.sqlite"
    shutil.copyfile(_TEMPLATE[0], target)
    return f"sqlite:///{target}"


def lab_file(folder: Path, register_url: str, extra: str = "") -> Path:
    """A lab file naming the register (and `extra` YAML lines)."""
    folder.mkdir(parents=True, exist_ok=True)
    lab = folder / "lab.yaml"
    lab.write_text(f"register: {register_url}\n{extra}")
    return lab


def cli_in(stdin: str, *args: str) -> subprocess.CompletedProcess[str]:
    """`bench ARGS` in this process with `stdin` as standard input."""
    old = sys.stdin
    sys.stdin = io.StringIO(stdin)
    try:
        with contextlib.ExitStack():
            return cli(*args)
    finally:
        sys.stdin = old


def enrol(run: Path, url: str) -> None:
    """Record a run in the register as `bench run` under that register would have at the
    run's start and end (issue 54: bench/app/register/runs.py). The session's demo runs are
    made once, without a register, and shared by every test; a test that issues a copy
    first enrols it in its own register. The refusal of a run no register saw start is
    tested on runs that are not enrolled (tests/test_run_record.py)."""
    import json

    from bench.app.register import Register
    from bench.app.register.runs import input_digests, raw_digests, run_uid_of
    from bench.core import rundir_layout as layout

    uid = run_uid_of(run)
    meta = json.loads((run / layout.META).read_text())
    performer = meta.get("performer") or {}
    result = (run / layout.RESULT).read_bytes()
    lab = run / layout.LAB
    from bench.app.register import RegisterError

    try:
        reg = Register.open(url, migrate=False)
    except RegisterError:
        return          # a register out of reach: `bench authorise` says so itself
    with reg:
        if reg.run_record(uid) is not None:
            return
        reg.register_run(uid, "test bench", performer.get("account"), meta["bench_version"],
                         bool((json.loads(result).get("stand") or {}).get("simulated")),
                         input_digests(run / layout.PROCEDURE, run / layout.STAND,
                                       lab if lab.is_file() else None),
                         meta.get("equipment_status") or [])
        reg.deliver_result(uid, "session", result, raw_digests(run))


def lab_register(lab: Path) -> str | None:
    from bench.core.lab import load_lab

    return load_lab(lab).register_url


def authorise(run: Path, account: str, lab: Path, *args: str,
              password_text: str | None = None, enrolled: bool = True
              ) -> subprocess.CompletedProcess[str]:
    """`bench authorise` with the password on stdin; the run is first enrolled in the lab
    file's register (`enrol`) unless `enrolled=False`."""
    url = lab_register(lab) if enrolled and lab.is_file() else None
    if url and (run / "meta.json").is_file() and (run / "result.json").is_file():
        enrol(run, url)
    pw = password(account) if password_text is None and account in ACCOUNTS \
        else (password_text or "")
    return cli_in(pw + "\n", "authorise", str(run), "--signatory", account, "--lab",
                  str(lab), "--password-stdin", *args)


def add_register(lab: Path, folder: Path) -> str:
    """Name a fresh register in an existing lab file; returns its URL."""
    url = sqlite_register(folder)
    with lab.open("a") as f:
        f.write(f"register: {url}\n")
    return url


def designate(url: str, certificate: Path) -> None:
    """The register's admin designates the DCC signing certificate (issue 42)."""
    import hashlib

    from bench.app.certificate.authorise import SIGNING_SETTING
    from bench.app.register import Register

    with Register.open(url) as reg:
        reg.set_setting(reg.authenticate("admin", password("admin"), "admin"), SIGNING_SETTING,
                        hashlib.sha256(certificate.read_bytes()).hexdigest())


def issue_then_find_out(run: Path, lab: Path, url: str, serial: str, certificate: str,
                        error: float, error_u: float) -> str:
    """Issue the run (P. Petrov signs; the run is in the register from its start), then the
    item's recalibration finds it out of tolerance with the as-found error (Q. Manager,
    `bench register equipment update ... --found out --found-error V,U`; issue 58);
    returns the certificate number issued."""
    import datetime as dt

    from bench.core import rundir_layout as layout

    issued = authorise(run, "P. Petrov", lab, enrolled=False)
    assert issued.returncode == 0, issued.stdout + issued.stderr
    number = next((run / layout.ISSUED).iterdir()).name
    found = cli_in(password("Q. Manager") + "\n", "register", "equipment", "update", serial,
                   "--certificate", certificate, "--issuer", "Cal Lab",
                   "--due", (dt.date.today() + dt.timedelta(days=400)).isoformat(),
                   "--found", "out", "--found-error", f"{error},{error_u}",
                   "--register", url, "--as", "Q. Manager", "--password-stdin")
    assert found.returncode == 0, found.stderr
    return number


def registered_run(procedure: Path, runs: Path, lab: Path, url: str
                   ) -> tuple[Path, RunRecord]:
    """`bench run PROCEDURE` under the lab file's register (it holds the run from its start,
    issue 54): the run folder and the register's record of it, with its result."""
    from bench.app.register import Register
    from bench.app.register.runs import run_uid_of
    from tests.conftest import run_dir_of

    out = cli("run", str(procedure), "--yes", "--quiet", "--out", str(runs), "--lab", str(lab))
    assert out.returncode in (0, 1), out.stderr[-3000:]
    made = run_dir_of(out)
    with Register.open(url, migrate=False) as reg:
        rec = reg.run_record(run_uid_of(made))
    assert rec is not None and rec.result is not None
    return made, rec
