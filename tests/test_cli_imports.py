"""`bench --help` starts at once (issue 45): building and using the parser imports no
heavy library and none of the measurement code; a command's module is imported when the
command runs (bench/app/cli.py). `bench validate` and `bench schema` load the
configuration and the kinds, but not numpy, the analysis, the plots, the fits, the CAN
stack or the records (those are imported where they are used). The time itself:
benchmarks/bench_cli_startup.py."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import ROOT

#: third-party libraries a command may need, none of which the parser may load
HEAVY = ("numpy", "scipy", "matplotlib", "yaml", "serial", "pyvisa", "can", "canopen",
         "jinja2", "fpdf", "rich", "flask", "werkzeug", "waitress", "lxml", "xmlschema",
         "signxml", "cryptography", "sqlalchemy", "alembic", "psycopg", "argon2")
#: our packages below bench.app: the configuration, the engine, the analysis and the rest
OURS = ("bench.core", "bench.analysis", "bench.report", "procedures", "drivers", "sims")
#: ...but for the run directory's names (bench/core/rundir_layout.py imports nothing), which
#: the DCC package's names are made of
LIGHT = ("bench.core", "bench.core.rundir_layout")

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
                  if m.split(".")[0] in HEAVY or (m not in LIGHT and any(
                      m == p or m.startswith(p + ".") for p in OURS)))


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


#: what reading and checking the configuration must not load: the certificate's plots
#: (matplotlib), the analysis's fits (scipy), the drives' CAN stack and the records
NOT_FOR_THE_FILES = ("matplotlib", "scipy", "canopen", "can", "sqlalchemy")


def _run_quietly(argv: list[str]) -> str:
    return ("import contextlib, io\nfrom bench.app.cli import main\n"
            "with contextlib.redirect_stdout(io.StringIO()):\n"
            f"    assert main({argv!r}) == 0\n")


def loaded_libraries(modules: set[str], names: tuple[str, ...]) -> list[str]:
    return sorted({m.split(".")[0] for m in modules} & set(names))


@pytest.mark.parametrize("argv", [
    ["validate", "configs/procedures/demo.yaml"],
    ["validate", "configs/procedures/drift-demo.yaml"],
    ["validate", "configs/stands/sim-two-axis.yaml"],     # a stand file alone
    ["schema", "stand"], ["schema", "procedure", "rate-ladder"], ["schema", "lab"],
])
def test_validate_and_schema_load_no_plots_fits_can_or_records(argv: list[str]) -> None:
    modules = loaded_after(_run_quietly(argv))
    assert "bench.core.schema" in modules       # the command did read the configuration
    assert loaded_libraries(modules, NOT_FOR_THE_FILES) == []


#: a kind's heavy parts (bench/core/registry.py `ProcedureKind`: `certificate`, `dcc`,
#: `records` and what they use), imported when first used, never to read the files
KIND_PARTS = ("certificate", "dcc", "records", "starter", "sample", "conditions", "events",
              "budgets", "station", "plots", "axes_view")
REPORT_PARTS = ("bench.report.certificate", "bench.report.dcc", "bench.report.figures",
                "bench.report.station")


@pytest.mark.parametrize("argv", [
    ["validate", "configs/procedures/demo.yaml"],
    ["validate", "configs/procedures/drift-demo.yaml"],
    ["validate", "configs/stands/sim-two-axis.yaml"],
    ["schema", "stand"], ["schema", "procedure", "rate-ladder"],
    ["schema", "procedure", "drift-pulse"],
])
def test_validate_and_schema_load_no_certificate_dcc_or_records_of_a_kind(
        argv: list[str]) -> None:
    modules = loaded_after(_run_quietly(argv))
    assert "procedures.rate_ladder.kind" in modules or "procedures.drift_pulse.kind" in modules
    heavy = sorted(m for m in modules
                   if (m.startswith("procedures.") and m.split(".")[-1] in KIND_PARTS
                       and m.count(".") == 2 and m != "procedures.drift_pulse.budgets")
                   or m.startswith(REPORT_PARTS) or m.split(".")[0] == "lxml")
    assert heavy == []


#: what the files' settings are read without: the numerics (numpy, the analysis), the
#: plots, the fits, the drives' CAN stack, the DCC's XML and the records. The settings
#: take their limits, model names and defaults from light modules (drivers/counter_profiles.py,
#: drivers/fog_format_names.py, sims/truth.py, procedures/drift_pulse/shapes.py); the
#: numerics are imported by the functions that compute.
NOT_FOR_READING = ("numpy", "scipy", "matplotlib", "lxml", "sqlalchemy", "canopen", "can")


@pytest.mark.parametrize("argv", [
    ["--help"],
    ["validate", "configs/procedures/demo.yaml"],
    ["validate", "configs/procedures/drift-demo.yaml"],
    ["validate", "configs/stands/sim-two-axis.yaml"],
    ["schema", "stand"], ["schema", "procedure", "rate-ladder"],
    ["schema", "procedure", "drift-pulse"], ["schema", "lab"],
])
def test_validate_and_schema_load_no_numpy_or_analysis(argv: list[str]) -> None:
    code = _run_quietly(argv) if argv != ["--help"] else (
        "import contextlib, io\nfrom bench.app.cli import main\n"
        "with contextlib.redirect_stdout(io.StringIO()):\n"
        "    try:\n"
        f"        main({argv!r})\n"
        "    except SystemExit:\n"
        "        pass\n")
    modules = loaded_after(code)
    assert loaded_libraries(modules, NOT_FOR_READING) == []
    assert sorted(m for m in modules if m.startswith("bench.analysis")) == []


def test_the_light_names_are_the_heavy_modules_names() -> None:
    """The FOG formats' names read by the settings are the formats the decoder knows."""
    from drivers.fog_format_names import FORMAT_NAMES
    from drivers.fog_formats import FORMATS

    assert tuple(FORMATS) == FORMAT_NAMES


def test_the_probe_sees_the_libraries_validate_must_not_load() -> None:
    """Not blind: the modules that draw, open a drive or keep the records load them."""
    modules = loaded_after("import bench.app.records.control_plot, drivers.cia402, sims.drive_twin\n"
                           "import bench.app.records.schema")
    assert loaded_libraries(modules, NOT_FOR_THE_FILES) == ["can", "canopen", "matplotlib",
                                                            "sqlalchemy"]
    # the fit imports scipy when it solves (bench/analysis/systematic.py solve_direction)
    modules = loaded_after("import bench.analysis.systematic\nimport scipy.linalg")
    assert "scipy" in loaded_libraries(modules, NOT_FOR_THE_FILES)


def test_a_file_read_again_is_parsed_once_and_handed_out_as_a_copy(tmp_path: Path) -> None:
    """`bench validate` reads a procedure file three times: the parse is kept by the file's
    text (bench/core/yamlfile.py), and each reader gets its own copy to change."""
    from bench.core import yamlfile

    path = tmp_path / "p.yaml"
    path.write_text("a:\n  b: [1, 2]\n")
    first = yamlfile.load_yaml(path)
    first.data["a"]["b"].append(3)
    first.lines.clear()
    again = yamlfile.load_yaml(path)
    assert again.data == {"a": {"b": [1, 2]}} and again.lines[("a", "b")] == 2
    assert yamlfile._parse_kept.cache_info().hits >= 1
    path.write_text("a:\n  b: [1, 2, 3]\n")          # new text: parsed afresh
    assert yamlfile.load_yaml(path).data == {"a": {"b": [1, 2, 3]}}


def test_the_probe_sees_a_heavy_import() -> None:
    """The check above is not blind: a command module that needs numpy shows it."""
    assert "numpy" in too_heavy(loaded_after("import bench.app.decode"))
    assert "bench.core.journal" in too_heavy(loaded_after("import bench.app.decode"))


def test_the_records_commands_parsed_are_the_ones_handled() -> None:
    """bench/app/parsers.py names the records subcommands without importing their
    handlers (bench/app/records/commands.py): the two lists must be the same."""
    from bench.app import parsers
    from bench.app.records.commands import RECORDS_COMMANDS

    assert set(parsers.RECORDS_COMMAND_NAMES) == set(RECORDS_COMMANDS)
