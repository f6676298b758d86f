"""`bench --help` starts at once (issue 45): building and using the parser imports no
heavy library and none of the measurement code; a command's module is imported when the
command runs (bench/app/cli.py). The time itself: benchmarks/bench_cli_startup.py."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from tests.conftest import ROOT

#: third-party libraries a command may need, none of which the parser may load
HEAVY = ("numpy", "scipy", "matplotlib", "yaml", "serial", "pyvisa", "can", "canopen",
         "jinja2", "fpdf", "rich", "flask", "werkzeug", "waitress", "lxml", "xmlschema",
         "signxml", "cryptography", "sqlalchemy", "alembic", "psycopg", "argon2")
#: our packages below bench.app: the configuration, the engine, the analysis and the rest
OURS = ("bench.core", "bench.analysis", "bench.report", "procedures", "drivers", "sims")

PROBE = """
import json, sys
{code}
print(json.dumps(sorted(sys.modules)))
"""


def loaded_after(code: str) -> set[str]:
    """The modules a fresh interpreter holds after running `code`."""
    r = subprocess.run([sys.executable, "-c", PROBE.format(code=code)], cwd=ROOT,
                       capture_output=True, text=True, timeout=120, check=False)
    assert r.returncode == 0, r.stderr
    return set(json.loads(r.stdout.splitlines()[-1]))


def too_heavy(modules: set[str]) -> list[str]:
    return sorted(m for m in modules
                  if m.split(".")[0] in HEAVY or any(m == p or m.startswith(p + ".")
                                                     for p in OURS))


def test_importing_the_cli_loads_nothing_heavy() -> None:
    assert too_heavy(loaded_after("import bench.app.cli")) == []


@pytest.mark.parametrize("argv", [
    ["--help"], ["--version"], ["run", "--help"], ["validate", "--help"],
    ["schema", "--help"], ["register", "user", "add", "--help"], ["authorise", "--help"],
    ["records", "import", "--help"], ["control", "--help"], ["serve", "--help"],
    ["dcc", "--help"], ["decode", "--help"],
    ["run", "--no-such-option"],           # a wrong option is answered by the parser alone
])
def test_parsing_any_command_line_loads_nothing_heavy(argv: list[str]) -> None:
    code = ("import contextlib, io\nfrom bench.app.cli import main\n"
            "with contextlib.redirect_stdout(io.StringIO()), "
            "contextlib.redirect_stderr(io.StringIO()):\n"
            "    try:\n"
            f"        main({argv!r})\n"
            "    except SystemExit:\n"
            "        pass\n")
    assert too_heavy(loaded_after(code)) == []


def test_the_probe_sees_a_heavy_import() -> None:
    """The check above is not blind: a command module that needs numpy shows it."""
    assert "numpy" in too_heavy(loaded_after("import bench.app.decode"))
    assert "bench.core.journal" in too_heavy(loaded_after("import bench.app.decode"))


def test_the_parsers_copies_match_their_sources() -> None:
    """bench/app/parsers.py copies a few constants so as not to import their modules."""
    from bench.app import parsers
    from bench.app.records.commands import RECORDS_COMMANDS
    from bench.app.records.settings import DEFAULT_RUNS
    from bench.app.register.schema import ROLES

    assert parsers.DEFAULT_RUNS == DEFAULT_RUNS
    assert parsers.ROLES == ROLES
    assert set(parsers.RECORDS_COMMAND_NAMES) == set(RECORDS_COMMANDS)
