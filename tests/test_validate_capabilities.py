"""`bench validate` knows each instrument's capabilities (issue 41): a counter model or a
FOG format the drivers do not have is refused at its line with the valid choices, and a
model that cannot do what the rate ladder needs is refused naming the missing capability,
before anything starts (exit 2)."""

from __future__ import annotations

import re
from pathlib import Path

from tests.conftest import CONFIGS, cli

STAND = CONFIGS / "stands" / "sim-two-axis.yaml"
DEMO = CONFIGS / "procedures" / "demo.yaml"


def _files(tmp_path: Path, *edits: tuple[str, str]) -> tuple[Path, str]:
    text = STAND.read_text()
    for old, new in edits:
        assert old in text, old
        text = text.replace(old, new, 1)
    (tmp_path / "stand.yaml").write_text(text)
    proc = tmp_path / "demo.yaml"
    proc.write_text(re.sub(r"(?m)^stand: .*$", "stand: stand.yaml", DEMO.read_text()))
    return proc, text


def _line(text: str, needle: str) -> int:
    return next(i for i, line in enumerate(text.splitlines(), 1) if needle in line)


OUTER_MODEL = ('"TCPIP0::127.0.0.1::5025::SOCKET", model: keysight-53230a',
               '"TCPIP0::127.0.0.1::5025::SOCKET", model: {}')
INNER_MODEL = ('"TCPIP0::127.0.0.1::5026::SOCKET", model: keysight-53230a',
               '"TCPIP0::127.0.0.1::5026::SOCKET", model: {}')


def test_unknown_counter_model_and_fog_format_at_their_lines(tmp_path: Path) -> None:
    proc, text = _files(tmp_path, (OUTER_MODEL[0], OUTER_MODEL[1].format("no-such-counter")),
                        ("format: kvh-a, axis: z, rate_hz: 1000,\n              range_dps: "
                         "490, model: KVH DSP-1760, serial: \"1760-20232\"",
                         "format: kvh-z, axis: z, rate_hz: 1000,\n              range_dps: "
                         "490, model: KVH DSP-1760, serial: \"1760-20232\""))
    out = cli("validate", str(proc))
    assert out.returncode == 2, out.stdout + out.stderr
    said = out.stdout + out.stderr
    stand = tmp_path / "stand.yaml"
    assert (f"{stand}:{_line(text, 'no-such-counter')}: axes.outer.counter.model: expected "
            "one of ") in said, said
    assert "keysight-53230a" in said and "pendulum-cnt-91" in said
    assert (f"{stand}:{_line(text, 'kvh-z')}: axes.inner.fog.format: expected one of "
            "kvh-a, kvh-b, got 'kvh-z'") in said, said


def test_a_counter_without_time_stamps_is_refused_naming_the_capability(
        tmp_path: Path) -> None:
    proc, text = _files(tmp_path, (INNER_MODEL[0], INNER_MODEL[1].format("generic-scpi-period")))
    out = cli("validate", str(proc))
    assert out.returncode == 2
    said = out.stdout + out.stderr
    stand = tmp_path / "stand.yaml"
    assert (f"{stand}:{_line(text, 'generic-scpi-period')}: axes.inner.counter.model: the "
            "generic-scpi-period cannot timestamp edges (supports_timestamps): the rate "
            "ladder needs N+1 consecutive zero-mark timestamps; models that have time "
            "stamps: keysight-53230a, pendulum-cnt-91") in said, said
    # and its `reference: external` and fog-sync time tie name what it lacks
    assert "axes.inner.counter.reference: the generic-scpi-period profile has no " \
           "reference-source word" in said, said
    assert "axes.inner.counter.time_tie.source: the generic-scpi-period profile has no " \
           "trigger-source word" in said, said


def test_the_53220a_has_no_time_stamps_by_its_users_guide(tmp_path: Path) -> None:
    """"Time stamp measurements are available with the 53230A only" (53220A/53230A User's
    Guide, p. 99): the 53220A is a model the bench knows, refused for the ladder."""
    proc, text = _files(tmp_path, (OUTER_MODEL[0], OUTER_MODEL[1].format("keysight-53220a")))
    out = cli("validate", str(proc))
    assert out.returncode == 2
    said = out.stdout + out.stderr
    assert (f"{tmp_path / 'stand.yaml'}:{_line(text, 'keysight-53220a')}: "
            "axes.outer.counter.model: the keysight-53220a cannot timestamp edges") in said
    assert "reference" not in said.split("keysight-53220a cannot")[1].split("\n")[0]


def test_the_schema_names_the_counter_models_and_fog_formats() -> None:
    out = cli("schema", "stand")
    assert out.returncode == 0
    assert re.search(r"counter\.model  \(required\)\n    one of generic-scpi-period, "
                     r"keysight-53220a, keysight-53230a, pendulum-cnt-91", out.stdout), \
        out.stdout
    assert "one of kvh-a, kvh-b" in out.stdout
