"""docs/register.md's "lab's first day", word for word (issue 57): every command line of the
script is read from the document and run as written, with only the substitutions the
document states: `URL` the register (the SQLite file the first line creates, or the
register service on a PostgreSQL cluster the test starts, set up as docs/station.md says),
/srv/lab a temporary folder, the deviation's date within 30 days of today, and the
example number a number the register issued.

The commands run in this process (bench/app/cli.main); their password prompts are answered
as a person at the terminal would, by replacing `getpass.getpass` and saying standard input
is a terminal: the one stand-in here, since no terminal is attached to a test.
"""

from __future__ import annotations

import contextlib
import datetime as dt
import io
import re
import secrets
import shlex
import uuid
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from bench.app.register import Register
from tests.conftest import ROOT

DOC = ROOT / "docs" / "register.md"
EXAMPLE_NUMBER = "RT-2026-00012"
EXAMPLE_EXPIRY = "2026-12-20"
DIGESTS = {"result.json": "a" * 64, "certificate.pdf": "b" * 64,
           "certificate.dcc.xml": "c" * 64, "certificate.html": "d" * 64}


def _script() -> list[str]:
    """The command lines of the first-day script, continuations joined."""
    text = DOC.read_text()
    start = text.index("```sh\n", text.index("A lab's first day")) + len("```sh\n")
    block = text[start:text.index("```", start)]
    return [line.strip() for line in block.replace("\\\n", " ").splitlines() if line.strip()]


class Person:
    """Answers each password prompt as the account's holder would."""

    def __init__(self, admin_pw: str) -> None:
        self.pw = {"admin": admin_pw}
        self.initial: dict[str, str] = {}
        self.prompts: list[str] = []

    def __call__(self, prompt: str = "") -> str:
        self.prompts.append(prompt)
        kind, name = re.match(r"(current password of|password of|new password for|"
                              r"initial password for) (\S+?)[ :(]", prompt).groups()  # type: ignore[union-attr]
        if kind == "initial password for":
            self.initial[name] = "set-by-the-admin-" + secrets.token_hex(4)
            return self.initial[name]
        if kind in ("current password of", "password of"):
            return self.pw.get(name) or self.initial[name]
        if name == "admin" and name not in self.initial and len(self.prompts) == 1:
            return self.pw["admin"]                       # init: the admin's own
        self.pw[name] = "own-phrase-" + secrets.token_hex(6)
        return self.pw[name]


@contextlib.contextmanager
def _at_a_terminal(person: Person) -> Iterator[None]:
    import getpass
    import sys

    class Tty(io.StringIO):
        def isatty(self) -> bool:
            return True

    old_getpass, old_stdin = getpass.getpass, sys.stdin
    getpass.getpass = person           # type: ignore[assignment]
    sys.stdin = Tty()
    try:
        yield
    finally:
        getpass.getpass, sys.stdin = old_getpass, old_stdin


def _walk(url: str, srv: Path, person: Person, skip_init: bool) -> dict[str, str]:
    from bench.app.cli import main

    said: dict[str, str] = {}
    for line in _script():
        args = shlex.split(line.replace("/srv/lab", str(srv)), comments=True)
        assert args[0] == "bench", line
        args = [url if a == "URL" else a for a in args[1:]]
        if args[:2] == ["register", "init"] and skip_init:
            continue
        args = [(dt.datetime.now(dt.UTC).date() + dt.timedelta(days=20)).isoformat()
                if a == EXAMPLE_EXPIRY else a for a in args]
        if EXAMPLE_NUMBER in args:      # a number the register issued, as petrov signed it
            with Register.open(url, migrate=False) as reg:
                signer = reg.authenticate("petrov", person.pw["petrov"], "signatory")
                number = reg.allocate(uuid.uuid4().hex, "RT", signer.name)
                reg.begin_issue(signer, number, 1, DIGESTS["result.json"])
                reg.issue(number, 1, signer, DIGESTS, None, {"run_dir": "docs walk"})
            args = [number if a == EXAMPLE_NUMBER else a for a in args]
        out, err = io.StringIO(), io.StringIO()
        with _at_a_terminal(person), contextlib.redirect_stdout(out), \
                contextlib.redirect_stderr(err):
            code = main(args)
        assert code == 0, f"{line}\n{out.getvalue()}{err.getvalue()}"
        said[" ".join(args[:3])] = out.getvalue()
    return said


def _check(said: dict[str, str]) -> None:
    history = said["register equipment history"]
    assert "C-2026-117" in history and "C-2027-117" in history
    assert "found OUT of tolerance, as-found error 3e-07 +/- 1e-08" in history
    listed = said["register equipment list"]
    assert "identity only" in listed and "MY59000042" in listed and "OVERDUE" in listed
    users = said["register user list"]
    assert re.search(r"petrov .*DISABLED", users) and "quality1" in users
    assert "chain whole" in said["register audit --register"]


def test_the_first_day_on_one_bench_word_for_word(tmp_path: Path) -> None:
    srv = tmp_path / "srv" / "lab"
    url = f"sqlite:///{srv}/lab-register.sqlite"
    assert _script()[0].startswith("bench register init sqlite:////srv/lab/")
    _check(_walk(url, srv, Person("first-keeper-phrase-" + secrets.token_hex(3)), False))


def test_the_first_day_through_the_register_service(pg: Any, tmp_path: Path) -> None:
    from tests.test_register_service import _service

    sfx = uuid.uuid4().hex[:8]
    owner = pg.create_database(f"docs_register_{sfx}")
    svc = f"docs_svc_{sfx}"
    pg.admin(f'CREATE ROLE "{svc}" LOGIN')
    person = Person("first-keeper-phrase-" + secrets.token_hex(3))
    from bench.app.cli import main

    with _at_a_terminal(person), contextlib.redirect_stdout(io.StringIO()):
        assert main(["register", "init", owner, "--admin", "admin", "--full-name", "R. Admin",
                     "--service-role", svc]) == 0
    with _service(owner.replace(f"//{pg.user}@", f"//{svc}@")) as url:
        _check(_walk(url, tmp_path, person, skip_init=True))


@pytest.fixture(autouse=True)
def _no_lab_of_the_developer(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("BENCH_LAB_SETTINGS", raising=False)
