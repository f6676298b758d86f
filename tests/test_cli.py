"""The console script's small commands: --help, devices, bad invocations."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from bench.app.cli import main
from bench.examples import example_names, example_path
from tests.conftest import CONFIGS, bench, run_dir_of


def test_help_lists_every_contract_command() -> None:
    out = bench("--help", timeout=60)
    assert out.returncode == 0
    for cmd in ("run", "validate", "plan", "analyze", "devices", "decode"):
        assert cmd in out.stdout


def test_version(capsys: pytest.CaptureFixture[str]) -> None:
    import bench

    with pytest.raises(SystemExit) as stop:
        main(["--version"])
    assert stop.value.code == 0
    assert capsys.readouterr().out.strip() == f"bench (ratebench) {bench.__version__}"


@pytest.mark.timeout(60)
def test_devices_prints_each_instruments_identity(capsys: pytest.CaptureFixture[str]) -> None:
    rc = main(["devices", str(CONFIGS / "stands" / "sim-two-axis.yaml")])
    out = capsys.readouterr().out.splitlines()
    assert rc == 0
    rows = {(line.split()[0], line.split()[1]): line for line in out}
    assert set(rows) == {(a, w) for a in ("outer", "inner") for w in ("drive", "counter", "fog")}
    assert "Keysight Technologies,53230A" in rows["outer", "counter"]   # the twin's *IDN?
    assert "CiA 402" in rows["inner", "drive"]                          # 0x1008 over SDO
    # what the measurement rests on, read back at connect (issue 11): the feedback PDOs
    assert "drive.pdo (TPDO1) mapping = 0x606C + 0x6064" in rows["inner", "drive"]
    assert "drive.quick stop deceleration 0x6085 = " in rows["inner", "drive"]
    assert "KVH DSP-1760" in rows["outer", "fog"]


@pytest.mark.timeout(60)
def test_devices_opens_a_gyro_platform_stand_through_its_own_kind(
        capsys: pytest.CaptureFixture[str]) -> None:
    rc = main(["devices", str(CONFIGS / "stands" / "sim-gyro-platform.yaml")])
    out = capsys.readouterr().out
    assert rc == 0
    assert "33522B" in out                       # the AWG twin's *IDN?
    assert out.count("34465A") == 2              # one digitizer per horizontal gyro
    # the AWG profile's words were checked against no manual: said where the user looks
    awg = next(line for line in out.splitlines() if "33522B" in line)
    assert "UNVERIFIED (no manual found)" in awg, awg
    assert out.count("checked against: Keysight Truevolt") == 2


def test_run_without_a_procedure_is_invalid_input(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["run", "--yes"]) == 2
    assert "give a PROCEDURE.yaml" in capsys.readouterr().err


def test_analyze_refuses_a_folder_that_is_not_a_run(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["analyze", str(tmp_path)]) == 2
    assert "not a run directory" in capsys.readouterr().err


def test_the_shipped_examples_are_the_configs_procedures_and_valid(
        capsys: pytest.CaptureFixture[str]) -> None:
    assert example_names() == ["demo", "drift-demo"]                  # CONTRACT §1
    for name in example_names():
        path = example_path(name)
        assert path.read_bytes() == (CONFIGS / "procedures" / f"{name}.yaml").read_bytes()
        assert main(["validate", str(path)]) == 0
    assert "valid drift-pulse procedure" in capsys.readouterr().out


def test_run_an_unknown_example_is_invalid_input(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["run", "--example", "nope", "--yes"]) == 2
    assert "demo, drift-demo" in capsys.readouterr().err


def _one_pair(tmp_path: Path) -> Path:
    proc = tmp_path / "one-pair.yaml"
    proc.write_text(
        f"procedure: rate-ladder\nstand: {CONFIGS / 'stands' / 'sim-two-axis.yaml'}\n"
        "turns: 4\nsequence: '+-'\nstatic_record_s: 2\nharmonics: 1\nprompts: false\n"
        "axes:\n  outer: {rates_dps: [60]}\n")
    return proc


@pytest.mark.timeout(240)
@pytest.mark.parametrize("mode", ["--quiet", "--log-json"])
def test_quiet_and_json_log_modes_through_the_cli(mode: str, tmp_path: Path) -> None:
    """--quiet: stdout holds the verdict and the run directory, stderr nothing; --log-json:
    every stderr line is one JSON object (a log collector reads it), stdout as usual."""
    out = bench("run", str(_one_pair(tmp_path)), "--yes", "--out", str(tmp_path / "runs"), mode,
                timeout=200)
    assert out.returncode == 0, out.stderr
    run_dir = run_dir_of(out)
    assert (run_dir / "certificate.pdf").stat().st_size > 0
    if mode == "--quiet":
        assert out.stdout.strip().splitlines() == ["verdict: PASS", str(run_dir)], out.stdout
        assert out.stderr == ""
    else:
        objects = [json.loads(line) for line in out.stderr.splitlines()]
        kinds = {o.get("type") or o.get("kind") or o.get("event") for o in objects}
        assert len(objects) > 10 and None not in kinds, kinds


# -- issue 26: help, plan layout, logs, history plot -----------------------------------

def test_help_gives_examples_and_exit_codes(capsys) -> None:  # noqa: ANN001
    import pytest as _pytest

    from bench.app.cli import main as _main
    with _pytest.raises(SystemExit):
        _main(["--help"])
    out = capsys.readouterr().out
    assert "examples:" in out and "bench init mylab" in out
    for code in ("0  completed", "1  completed", "2  the input is invalid", "3  aborted"):
        assert code in out, code
    for cmd in ("validate", "plan"):
        with _pytest.raises(SystemExit):
            _main([cmd, "--help"])
        text = capsys.readouterr().out
        assert "stand" in text and "Exit" in text, text


def test_help_names_only_what_an_installed_package_has(
        capsys: pytest.CaptureFixture[str], tmp_path: Path,
        monkeypatch: pytest.MonkeyPatch) -> None:
    """Issue 46: every command `bench --help` names exists, every file it names is made
    by the example before it (bench init), nothing points into a checkout (README.md,
    docs/), and the method text it points at is installed."""
    import re

    from bench.app.cli import build_parser
    with pytest.raises(SystemExit):
        main(["--help"])
    text = capsys.readouterr().out
    assert "README" not in text and "docs/" not in text, text
    sub = next(a for a in build_parser()._actions if a.dest == "command")
    commands = set(sub.choices)    # type: ignore[arg-type]
    # every `bench WORD` but the plan's quantity "bench time" (prose, not a command)
    named = [w for w in re.findall(r"\bbench ([a-z][a-z-]*)", text) if w != "time"]
    assert {"schema", "init", "method"} <= set(named), named
    assert set(named) <= commands, set(named) - commands
    monkeypatch.chdir(tmp_path)
    examples = [line.split("   ")[0].strip() for line in text.splitlines()
                if line.startswith("  bench ")]
    for example in examples:         # in order: `bench init mylab` makes what follows
        for word in example.split()[2:]:
            if "/" in word and not re.search(r"[A-Z]", word) and "://" not in word:
                assert (tmp_path / word).exists(), f"{example}: {word} does not exist"
        if example.startswith("bench init "):
            assert main(example.split()[1:]) == 0
            capsys.readouterr()
    assert main(["method", "--path"]) == 0
    path = Path(capsys.readouterr().out.strip())
    assert path.is_file() and path.name == "method.md"
    assert main(["method"]) == 0
    assert capsys.readouterr().out.startswith("# The measurement methods of ratebench")


def test_a_closed_pipe_ends_a_command_quietly() -> None:
    """`bench schema stand | head`: no BrokenPipeError traceback, exit 0."""
    import subprocess
    import sys

    from tests.conftest import ROOT
    p = subprocess.run(f"{sys.executable} -m bench schema --markdown | head -1",
                       shell=True, cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert p.stdout.startswith("#") and p.stderr == "", p.stderr


def _demo_with(tmp_path, axis: str, turns: int):  # noqa: ANN001, ANN202
    import yaml

    from tests.conftest import CONFIGS
    stand = yaml.safe_load((CONFIGS / "stands" / "sim-two-axis.yaml").read_text())
    stand["axes"] = {axis: stand["axes"]["outer"]}
    stand["sim"]["axes"] = {axis: stand["sim"]["axes"]["outer"]}
    (tmp_path / "stand.yaml").write_text(yaml.safe_dump(stand, sort_keys=False))
    proc = yaml.safe_load((CONFIGS / "procedures" / "demo.yaml").read_text())
    proc.update(stand="stand.yaml", turns=turns, axes={axis: {"rates_dps": [10]}})
    (tmp_path / "p.yaml").write_text(yaml.safe_dump(proc, sort_keys=False))
    return tmp_path / "p.yaml"


def test_plan_columns_fit_a_long_axis_name_and_odd_turns_are_warned(tmp_path,  # noqa: ANN001
                                                                    capsys) -> None:  # noqa: ANN001
    from bench.app.cli import main as _main
    assert _main(["plan", str(_demo_with(tmp_path, "elevation_gimbal", 5))]) == 0
    out = capsys.readouterr().out
    rows = [ln for ln in out.splitlines() if "elevation_gimbal" in ln and "deg/s" in ln]
    # the action column starts at the same place on every row
    starts = {ln.index(a) for ln in rows for a in ("set_rate", "settle", "acquire")
              if f" {a} " in ln}
    assert len(starts) == 1, rows
    assert "Warning: axis elevation_gimbal: 5 turns with sequence +-+ split the + " \
           "direction 3/2" in out
    # 3 turns at 10 deg/s plus the lead-in turn: 4 x 36 s = 2 min 24 s
    assert "3 turns at +10 deg/s (half 1/3, 2 min 24 s with the lead-in turn)" in out
    assert _main(["plan", str(_demo_with(tmp_path, "outer", 4))]) == 0
    assert "Warning" not in capsys.readouterr().out


def test_a_log_has_one_line_per_step_and_no_zero_of_n_noise() -> None:
    import io

    from bench.app.console import PlainConsole
    from bench.core.plan import Step
    from bench.core.progress import Figure

    out = io.StringIO()
    con = PlainConsole(out, min_interval_s=0.0)
    steps = [Step("static", "outer", "FOG at rest for 30 s", 30.0),
             Step("acquire", "outer", "2 turns at +10 deg/s", 108.0)]
    con.begin(steps, lambda: 0.0)
    con.step(0)
    con.advance(0, 30, "FOG at rest: 0 of 30 s")
    con.advance(15, 30, "FOG at rest: 15 of 30 s")
    con.step_done(0)
    con.step(1)
    for turn in range(3):
        con.advance(turn, 2, f"{turn} of 2 turns timed")
    con.result("outer +10 deg/s, 2 turns timed", Figure("mean", 1e-7))
    con.warn("FOG: 3 frames lost")
    lines = out.getvalue().splitlines()
    assert len(lines) == 4, lines
    assert lines[0].startswith("[1/2] outer") and lines[1].startswith("[2/2] outer")
    assert "outer +10 deg/s, 2 turns timed" in lines[2] and "frames lost" in lines[3]
    assert not any(" of 30 s" in ln or "turns timed" in ln and ln.startswith("  0") for ln in lines)


def test_history_plot_defaults_beside_the_records(tmp_path) -> None:  # noqa: ANN001
    from bench.app.records.commands import _records_folder
    db = tmp_path / "lab" / "records.sqlite"
    assert _records_folder(f"sqlite:///{db}", "runs") == db.parent
    assert _records_folder("postgresql://u@h/db", str(tmp_path / "runs")) == tmp_path / "runs"
