"""`bench init`'s starter files leave nothing for the certificate to flag unseen (issue 46).

Every key a certificate needs and only the laboratory knows is a placeholder, `"TO FILL
IN: ..."`, that `bench validate` lists as a note at file:line: key (exit 0, so the twins
run at once). Filled in as validate names them (the serials as the twins report them),
the run's certificate flags nothing NOT IDENTIFIED or NOT TRACEABLE; left unfilled, the
twins still run and the certificate flags each rather than printing it as a value.
"""

from __future__ import annotations

import html
import re
import sqlite3
import zlib
from pathlib import Path
from typing import Any

import pytest

from bench.core.loader import load_config, load_stand
from bench.core.placeholders import PREFIX, is_placeholder, run_copy
from bench.core.yamlfile import load_yaml
from tests.conftest import bench, cli, run_dir_of

NOTE = re.compile(r"^note: (?P<file>\S+?):(?P<line>\d+): (?P<key>\S+): to fill in: "
                  r"(?P<what>.+)$", re.MULTILINE)

#: what a certificate needs from the files, by key (issue 46): each must be a placeholder
CERTIFICATE_KEYS = {"specification.source", "mains_hz", "axes.main.drive.serial",
                    "axes.main.counter.serial", "axes.main.fog.serial",
                    "axes.main.counter.calibration.certificate",
                    "axes.main.counter.calibration.issuer",
                    "axes.main.counter.calibration.due", "traceability[0].certificate"}
#: and what a real stand must state from its own calibrations (bench/core/config.py)
REAL_KEYS = {"axes.main.counter.time_tie.latency_s", "axes.main.counter.time_tie.latency_u_s",
             "axes.main.counter.timebase_limit_rel"}


def _notes(stdout: str) -> list[dict[str, str]]:
    return [m.groupdict() for m in NOTE.finditer(stdout)]


def _validate(folder: Path) -> tuple[int, list[dict[str, str]], str]:
    out = cli("validate", str(folder / "procedure.yaml"))
    return out.returncode, _notes(out.stdout), out.stdout + out.stderr


def _text(html_file: Path) -> str:
    text = html.unescape(re.sub(r"<[^>]+>", " ", html_file.read_text(encoding="utf-8")))
    return re.sub(r"\s+", " ", text)


def _twin_serials(folder: Path) -> dict[str, Any]:
    stand = load_yaml(folder / "stand.yaml").data
    return dict(stand["sim"]["axes"]["main"]["serials"])


def _plausible(key: str, twins: dict[str, Any]) -> str:
    """A value (YAML text) a laboratory would write at `key`; the serials the twins'."""
    leaf = key.rsplit(".", 1)[-1]
    if key.endswith(("drive.serial", "counter.serial")) and twins:
        return f'"{twins[key.split(".")[-2]]}"'
    values = {"mains_hz": "50", "serial": '"SN-{n}"', "certificate": '"CAL-2026-{n:04d}"',
              "issuer": '"Example Calibration Service, accreditation 0000"',
              "due": "2030-06-30", "model": '"KVH DSP-1760"',
              "source": '"Example Tables Ltd, ET-1 data sheet, revision C, 2025-01-15"',
              "trigger_jitter_s": "27.0e-9", "timebase_limit_rel": "1.0e-9",
              "latency_s": "2.0e-6", "latency_u_s": "2.0e-7"}
    assert leaf in values, f"a placeholder the test does not know how to fill: {key}"
    return values[leaf].format(n=zlib.crc32(key.encode()) % 10000)


def _fill(notes: list[dict[str, str]], twins: dict[str, Any]) -> None:
    """Replace exactly the values validate named, each on its line, by its key."""
    for note in notes:
        path, line = Path(note["file"]), int(note["line"])
        lines = path.read_text(encoding="utf-8").splitlines(keepends=True)
        leaf = note["key"].rsplit(".", 1)[-1]
        pattern = re.compile(rf'^(\s*(?:- )?{re.escape(leaf)}:\s*)"{re.escape(PREFIX)}[^"]*"')
        value = _plausible(note["key"], twins)
        new, n = pattern.subn(lambda m, v=value: m.group(1) + v, lines[line - 1])
        assert n == 1, (note, lines[line - 1])
        lines[line - 1] = new
        path.write_text("".join(lines), encoding="utf-8")


def _placeholders_written(folder: Path) -> int:
    """The placeholders the files write as values (the comments name the convention too)."""
    value = re.compile(rf'^\s*(?:- )?\w+: "{re.escape(PREFIX)}', re.MULTILINE)
    return sum(len(value.findall((folder / n).read_text()))
               for n in ("stand.yaml", "procedure.yaml"))


def _init(tmp_path: Path, real: bool) -> tuple[Path, list[dict[str, str]]]:
    folder = tmp_path / ("real" if real else "lab")
    out = cli("init", str(folder), *(["--real"] if real else []))
    assert out.returncode == 0, out.stderr
    code, notes, said = _validate(folder)
    assert code == 0, said
    keys = {n["key"] for n in notes}
    assert CERTIFICATE_KEYS <= keys, CERTIFICATE_KEYS - keys
    assert not real or REAL_KEYS <= keys, REAL_KEYS - keys
    assert len(notes) == len(keys) == _placeholders_written(folder)   # every one, once
    assert f"{len(notes)} values are yours to fill in" in out.stdout
    for note in notes:       # each at its own line, where the file writes that key
        text = Path(note["file"]).read_text().splitlines()[int(note["line"]) - 1]
        assert f'{note["key"].rsplit(".", 1)[-1]}: "{PREFIX} {note["what"]}"' in text, note
    return folder, notes


@pytest.mark.timeout(240)
def test_a_filled_in_starter_runs_to_a_certificate_that_flags_nothing(
        tmp_path: Path) -> None:
    folder, notes = _init(tmp_path, real=False)
    twins = _twin_serials(folder)
    assert {n["key"]: n["what"] for n in notes}["axes.main.counter.serial"].endswith(
        f"(the twin's: {twins['counter']})")
    _fill(notes, twins)
    code, left, said = _validate(folder)
    assert code == 0 and not left and "to fill in" not in said, said
    assert "mains_hz not set" not in said        # nothing else noted: nothing unstated
    out = bench("run", str(folder / "procedure.yaml"), "--yes", "--out",
                str(tmp_path / "runs"), timeout=230)
    assert out.returncode == 0, out.stderr[-3000:]
    assert "FINDING" not in out.stdout + out.stderr   # the stated serials are the reported
    run = run_dir_of(out)
    cert = _text(run / "certificate.html")
    assert "Identity: axes." not in cert
    result = (run / "result.json").read_text()
    for flag in ("NOT IDENTIFIED", "NOT TRACEABLE", "NONE REPORTED", "FILL IN"):
        assert flag not in cert and flag not in result, flag
    assert "Example Tables Ltd, ET-1 data sheet, revision C, 2025-01-15" in cert
    assert "CAL-2026-" in cert and "valid on the work's date" in cert
    assert f"serial {twins['drive']}" in cert and twins["counter"] in cert


@pytest.mark.timeout(240)
def test_an_unfilled_starter_runs_and_its_certificate_flags_each_placeholder(
        tmp_path: Path) -> None:
    folder, _ = _init(tmp_path, real=False)
    out = bench("run", str(folder / "procedure.yaml"), "--yes", "--out",
                str(tmp_path / "runs"), timeout=230)
    assert out.returncode in (0, 1), out.stderr[-3000:]
    run = run_dir_of(out)
    cert = _text(run / "certificate.html")
    assert "Specification: NOT IDENTIFIED" in cert
    assert "NOT TRACEABLE: no calibration certificate in the stand file" in cert
    # a placeholder is never a value: not on the certificate, its DCC, result or records
    for name in ("certificate.html", "certificate.dcc.xml", "result.json"):
        assert "fill in" not in (run / name).read_text().lower(), name
    with sqlite3.connect(tmp_path / "runs" / "records.sqlite") as db:
        serials = [s for (s,) in db.execute("select serial from instruments")]
    assert serials and not any(is_placeholder(s) for s in serials), serials
    # the run directory keeps the files as written; its readers, as the run read them
    assert PREFIX in (run / "stand.yaml").read_text()
    stand = run_copy(run, "stand.yaml")
    assert "calibration" not in stand["axes"]["main"]["counter"]
    assert stand["traceability"] == [] and "mains_hz" not in stand


def test_a_real_starter_validates_lists_its_placeholders_and_does_not_run_unfilled(
        tmp_path: Path) -> None:
    folder, notes = _init(tmp_path, real=True)
    assert "sim" not in load_yaml(folder / "stand.yaml").data
    refused = cli("run", str(folder / "procedure.yaml"), "--yes", "--out",
                  str(tmp_path / "runs"))
    assert refused.returncode == 2, refused.stdout + refused.stderr
    assert "Not started: a real stand runs once nothing is left to fill in" in refused.stderr
    assert "axes.main.counter.time_tie.latency_s: to fill in" in refused.stderr
    assert not (tmp_path / "runs").exists()       # nothing written, nothing connected
    _fill(notes, {})
    code, left, said = _validate(folder)
    assert code == 0 and not left and "to fill in" not in said, said
    cfg = load_config(folder / "procedure.yaml")
    tie = cfg.stand["axes"]["main"]["counter"]["time_tie"]
    assert (tie["latency_s"], tie["latency_u_s"]) == (2.0e-6, 2.0e-7)
    assert cfg.stand_settings.mains_hz == 50.0


def test_a_placeholder_is_its_key_left_out(tmp_path: Path) -> None:
    """Half a calibration is none; a list entry left out moves the next one, whose
    problems are still reported where they were written; a required key in a block that
    must be there is a problem beside its note."""
    folder, _ = _init(tmp_path, real=False)
    stand = folder / "stand.yaml"
    first, sensor = stand.read_text().split("  - item: zero-mark sensor")
    first = first.replace('certificate: "TO FILL IN: the counter\'s calibration certificate '
                          'number"', 'certificate: "CAL-1"')           # its due left unfilled
    sensor = re.sub(r'(certificate|issuer): "TO FILL IN:[^"]*"', r'\1: "CAL-2"', sensor)
    sensor = re.sub(r'due: "TO FILL IN:[^"]*"', "due: soon", sensor)
    text = first + "  - item: zero-mark sensor" + sensor
    stand.write_text(text)
    out = cli("validate", str(stand))
    bad_line = next(i for i, t in enumerate(text.splitlines(), 1) if "soon" in t)
    assert out.returncode == 2
    assert f"stand.yaml:{bad_line}: traceability[1].due: expected a date" in out.stderr, \
        out.stderr
    stand.write_text(text.replace("due: soon", "due: 2030-02-28"))
    read = load_stand(stand).data
    assert "calibration" not in read["axes"]["main"]["counter"]    # due still to fill in
    assert [t["certificate"] for t in read["traceability"]] == ["CAL-2"]
    assert cli("validate", str(stand)).returncode == 0
    stand.write_text(stand.read_text().replace('serial: "0001"',
                                               'serial: "TO FILL IN: the table\'s serial"'))
    out = cli("validate", str(folder / "procedure.yaml"))
    assert out.returncode == 2 and "stand: missing required key 'serial'" in out.stderr


def test_the_placeholder_convention_is_one_test() -> None:
    assert is_placeholder("TO FILL IN: x") and is_placeholder("  to fill in: x")
    for value in ("TO FILL IN", "fill in: x", 50, None, {"a": "TO FILL IN: x"}):
        assert not is_placeholder(value), value
