"""`bench validate` reports every problem of both files in one pass (issue 26)."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from bench.app.cli import main
from tests.conftest import CONFIGS
from tests.test_validate_robust import demo  # noqa: F401 - the fixture


def _break(path: Path, old: str, new: str) -> int:
    """Edit the file; the 1-based line of the edit."""
    text = path.read_text()
    assert old in text, old
    path.write_text(text.replace(old, new, 1))
    return text[: text.index(old)].count("\n") + 1


def test_five_independent_problems_in_two_files_are_reported_at_once(
        demo: tuple[Path, Path], capsys: pytest.CaptureFixture[str]) -> None:  # noqa: F811
    proc, stand = demo
    # two in the stand's schema
    s1 = _break(stand, "node_id: 3", "node_id: three")
    s2 = _break(stand, "level_v: 2.5, slope: POS", "level_v: 2.5, slope: UP")
    # one in the procedure's schema
    p1 = _break(proc, "harmonics: 3", "harmonics: lots")
    # a rate over the outer axis's max_rate_dps 400, and an axis the stand lacks
    p2 = _break(proc, "rates_dps: [10, 50, 200]", "rates_dps: [10, 50, 450]")
    p3 = _break(proc, "  inner:\n", "  elevation:\n    rates_dps: [10]\n  inner:\n")
    assert main(["validate", str(proc)]) == 2
    err = capsys.readouterr().err
    expected = [
        f"{stand}:{s1}: axes.inner.drive.node_id: expected an integer",
        f"{stand}:{s2}: axes.outer.counter.slope: expected one of POS, NEG, got 'UP'",
        f"{proc}:{p1}: harmonics: expected an integer",
        f"{proc}:{p2}: axes.outer.rates_dps[2]: 450 deg/s exceeds axis 'outer''s "
        "max_rate_dps 400",
        f"{proc}:{p3}: axes.elevation: the stand file {stand} has no axis 'elevation'",
    ]
    for line in expected:
        assert line in err, (line, err)
    assert "5 problem(s)" in err, err


def test_a_stand_schema_error_does_not_hide_the_real_stand_checks(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The report had unit_factors and time_tie, and level_v only after those were fixed."""
    stand = tmp_path / "stand.yaml"
    stand.write_text((CONFIGS / "stands" / "example-real.yaml").read_text()
                     .replace("level_v: 2.5, ", "").replace("unit_factors: read, ", "")
                     .replace("node_id: 2,", "node_id: 200,"))
    proc = tmp_path / "p.yaml"
    proc.write_text("procedure: rate-ladder\nstand: stand.yaml\n"
                    "axes: {outer: {rates_dps: [10, 1000]}}\n")
    assert main(["validate", str(proc)]) == 2
    err = capsys.readouterr().err
    for what in ("axes.outer.drive.node_id: expected an integer >= 1 and <= 127",
                 "axes.outer.drive: a real stand must state drive.unit_factors",
                 "axes.outer.counter: missing level_v",
                 "axes.outer.rates_dps[1]: 1000 deg/s exceeds"):
        assert what in err, (what, err)
    assert ".py" not in err, err        # hints name documentation, not source files


def test_a_stand_file_validates_alone(tmp_path: Path,
                                      capsys: pytest.CaptureFixture[str]) -> None:
    stands = sorted((CONFIGS / "stands").glob("*.yaml"))
    assert len(stands) >= 2, stands        # the two-axis and the gyro-platform twins
    for stand in stands:
        assert main(["validate", str(stand)]) == 0, capsys.readouterr().err
        assert "valid" in capsys.readouterr().out
    broken = tmp_path / "stand.yaml"
    line = _break(broken if broken.exists() else _copy(stand, broken), "node_id:",
                  "node_idd:")
    assert main(["validate", str(broken)]) == 2
    err = capsys.readouterr().err
    assert f"{broken}:{line}:" in err and "node_idd: unknown key" in err, err
    assert "procedure: expected one of" not in err


def _copy(src: Path, dst: Path) -> Path:
    shutil.copy(src, dst)
    return dst


def test_a_tab_is_named_in_a_plain_sentence(tmp_path: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    proc = tmp_path / "p.yaml"
    proc.write_text("procedure: rate-ladder\nstand: s.yaml\naxes:\n  outer:\n"
                    "    rates_dps: [10]\n    turns:\t4\n")
    assert main(["validate", str(proc)]) == 2
    err = capsys.readouterr().err
    assert f"{proc}:6: axes.outer: a tab character on the line of 'turns': YAML indents " \
           "with spaces only" in err, err


def test_an_unknown_procedure_kind_does_not_hide_the_stand(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    stand = _copy(CONFIGS / "stands" / "sim-two-axis.yaml", tmp_path / "stand.yaml")
    line = _break(stand, "node_id: 3", "node_id: three")
    proc = tmp_path / "p.yaml"
    proc.write_text("procedure: rate-ladderr\nstand: stand.yaml\n")
    assert main(["validate", str(proc)]) == 2
    err = capsys.readouterr().err
    assert f"{proc}:1: procedure: expected one of drift-pulse, rate-ladder" in err
    assert f"{stand}:{line}: axes.inner.drive.node_id" in err, err
