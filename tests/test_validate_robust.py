"""`bench validate` never crashes: every file, however broken, gets exit 0 or 2 with
file:line:key (issue 13). The four minimal cases of the fault campaign, syntax errors at
the key of the broken collection, absurd numbers, and a hypothesis fuzz over mutations of
the shipped demo files."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from bench.app.cli import main
from tests.conftest import CONFIGS

MINIMAL_CASES = {  # the campaign's crashes: bytes, and the line the problem is on
    "nul": (b"procedure: rate-ladder\nturns: 4\x00\n", 2),
    "recursive-alias": (b"a: &x [*x]\nprocedure: rate-ladder\n", 1),
    "list-as-key": (b"procedure: rate-ladder\n? [a, b]\n: 1\n", 2),
    "not-utf8": (b"procedure: rate-ladder\nx: \xff\n", 2),
    "deep-nesting": (b"procedure: rate-ladder\nx: " + b"[" * 3000 + b"]" * 3000 + b"\n", 2),
    "alias-bomb": (b"a: &a [1,2,3,4,5,6,7,8,9]\n" + b"".join(
        b"%c: &%c [" % (c, c) + b",".join([b"*%c" % (c - 1)] * 9) + b"]\n"
        for c in b"bcdefg"), 1),
    "bad-date": (b"procedure: rate-ladder\nd: 2024-13-45\n", 2),
    "huge-int": (b"procedure: rate-ladder\nstand: x.yaml\nturns: " + b"9" * 400 + b"\n", 3),
}


@pytest.mark.parametrize("name", sorted(MINIMAL_CASES))
def test_minimal_cases_exit_2_with_file_and_line(name: str, tmp_path: Path,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    data, line = MINIMAL_CASES[name]
    f = tmp_path / "p.yaml"
    f.write_bytes(data)
    assert main(["validate", str(f)]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    assert f"{f}:{line}: " in err, err


@pytest.fixture
def demo(tmp_path: Path) -> tuple[Path, Path]:
    (tmp_path / "stands").mkdir()
    (tmp_path / "procedures").mkdir()
    stand = tmp_path / "stands" / "sim-two-axis.yaml"
    proc = tmp_path / "procedures" / "demo.yaml"
    shutil.copy(CONFIGS / "stands" / "sim-two-axis.yaml", stand)
    shutil.copy(CONFIGS / "procedures" / "demo.yaml", proc)
    return proc, stand


def test_unclosed_list_is_reported_at_its_key(demo: tuple[Path, Path],
                                              capsys: pytest.CaptureFixture[str]) -> None:
    proc, _ = demo
    text = proc.read_text()
    line = text[: text.index("rates_dps: [10, 50, 200]")].count("\n") + 1
    proc.write_text(text.replace("rates_dps: [10, 50, 200]", "rates_dps: [10, 50, 200"))
    assert main(["validate", str(proc)]) == 2
    err = capsys.readouterr().err
    assert f"{proc}:{line}: axes.outer.rates_dps: YAML syntax" in err, err


@pytest.mark.parametrize("old,new,key", [
    ("rates_dps: [10, 50, 200]", "rates_dps: [1e-300]", "axes.outer.rates_dps[0]"),
    ("rates_dps: [10, 50, 200]", "rates_dps: [1e300]", "axes.outer.rates_dps[0]"),
    ("{rel: 1.0e-6}", "{rel: 5}", "tolerance.rate_error[1].rel"),
    ("timeout_s: 60", "timeout_s: 1e12", "settle.timeout_s"),
])
def test_absurd_numbers_are_refused(old: str, new: str, key: str, demo: tuple[Path, Path],
                                    capsys: pytest.CaptureFixture[str]) -> None:
    proc, _ = demo
    text = proc.read_text()
    assert old in text
    proc.write_text(text.replace(old, new, 1))
    assert main(["validate", str(proc)]) == 2
    assert f": {key}: expected" in capsys.readouterr().err


def test_a_slow_rate_that_would_take_months_is_refused(
        demo: tuple[Path, Path], capsys: pytest.CaptureFixture[str]) -> None:
    proc, _ = demo
    proc.write_text(proc.read_text().replace("rates_dps: [10, 50, 200]",
                                             "rates_dps: [0.001]"))
    assert main(["validate", str(proc)]) == 2
    err = capsys.readouterr().err
    assert "axes.outer.rates_dps[0]: 4 turns at 0.001 deg/s take" in err, err


def test_a_real_stand_without_a_trigger_level_is_refused(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """CONTRACT's example stand has no level_v: the counter would refuse to arm it."""
    text = (CONFIGS / "stands" / "example-real.yaml").read_text()
    assert "level_v: 2.5, " in text
    stand = tmp_path / "stand.yaml"
    stand.write_text(text.replace("level_v: 2.5, ", ""))
    proc = tmp_path / "p.yaml"
    proc.write_text("procedure: rate-ladder\nstand: stand.yaml\n"
                    "axes: {outer: {rates_dps: [10]}}\n")
    assert main(["validate", str(proc)]) == 2
    err = capsys.readouterr().err
    assert f"{stand}:" in err and ": axes.outer.counter: missing level_v" in err, err
    stand.write_text(text)
    assert main(["validate", str(proc)]) == 0, capsys.readouterr().err


def test_a_simulated_stand_may_leave_the_level_to_its_twin(
        demo: tuple[Path, Path], capsys: pytest.CaptureFixture[str]) -> None:
    proc, stand = demo
    stand.write_text(stand.read_text().replace("level_v: 2.5, ", ""))
    assert main(["validate", str(proc)]) == 0, capsys.readouterr().err


# -- fuzz: random mutations of the shipped files -------------------------------------------

DEMO = (CONFIGS / "procedures" / "demo.yaml").read_bytes()
STAND = (CONFIGS / "stands" / "sim-two-axis.yaml").read_bytes()
YAMLISH = st.sampled_from([b"[", b"]", b"{", b"}", b":", b": ", b"- ", b"&a ", b"*a", b"!!",
                           b"?", b"\n", b"  ", b"\t", b"'", b'"', b"#", b"1e-300", b"-1",
                           b"<<: ", b"---\n", b"\x00", b"\xff", b"\x1b", b"~", b"null",
                           b"9" * 40, b".nan", b"true", b"[[[[[[", b"\xc3"])


@st.composite
def mutated(draw: st.DrawFn, base: bytes) -> bytes:
    data = bytearray(base)
    for _ in range(draw(st.integers(1, 4))):
        pos = draw(st.integers(0, len(data)))
        op = draw(st.sampled_from(["insert", "delete", "replace", "swap-lines"]))
        if op == "insert":
            data[pos:pos] = draw(st.one_of(YAMLISH, st.binary(min_size=1, max_size=4)))
        elif op == "delete":
            del data[pos:pos + draw(st.integers(1, 40))]
        elif op == "replace" and pos < len(data):
            data[pos] = draw(st.integers(0, 255))
        else:
            lines = bytes(data).split(b"\n")
            i, j = draw(st.integers(0, len(lines) - 1)), draw(st.integers(0, len(lines) - 1))
            lines[i], lines[j] = lines[j], lines[i]
            data = bytearray(b"\n".join(lines))
    return bytes(data)


#: per file; RATEBENCH_FUZZ_EXAMPLES=5000 for a longer campaign on demand
FUZZ_EXAMPLES = int(os.environ.get("RATEBENCH_FUZZ_EXAMPLES", "300"))


def _fuzz_once(tmp: Path, proc: bytes, stand: bytes, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp / "stands").mkdir(parents=True, exist_ok=True)
    (tmp / "procedures").mkdir(parents=True, exist_ok=True)
    (tmp / "stands" / "sim-two-axis.yaml").write_bytes(stand)
    p = tmp / "procedures" / "demo.yaml"
    p.write_bytes(proc)
    rc = main(["validate", str(p)])       # an exception here fails the test: a traceback
    err = capsys.readouterr().err
    assert rc in (0, 2), err
    if rc == 2:
        assert "Traceback" not in err
        assert any(ln.strip().startswith(str(tmp)) for ln in err.splitlines()), err


@settings(max_examples=FUZZ_EXAMPLES, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(proc=mutated(DEMO))
def test_fuzz_procedure_file(proc: bytes, tmp_path: Path,
                             capsys: pytest.CaptureFixture[str]) -> None:
    _fuzz_once(tmp_path, proc, STAND, capsys)


@settings(max_examples=FUZZ_EXAMPLES, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(stand=mutated(STAND))
def test_fuzz_stand_file(stand: bytes, tmp_path: Path,
                         capsys: pytest.CaptureFixture[str]) -> None:
    _fuzz_once(tmp_path, DEMO, stand, capsys)


def test_a_syntax_error_on_a_line_past_the_text_still_gets_its_sentence() -> None:
    """Found by the fuzz in CI: PyYAML counts only "\\n" breaks, str.splitlines() more
    (\\x1c, \\x0b...), so a line number PyYAML reports could index past splitlines()."""
    from bench.core.yamlfile import _plain_sentence

    text = "turns: 4\n"   # line 2 is the empty one after the last break
    assert _plain_sentence("found character '\\t' that cannot start any token", text, 2) \
        == "a tab character on line 2: YAML indents with spaces only; replace the tab " \
           "with spaces"
