"""What is issued is what was measured (issue 54): the register holds each run from its
start, and an issue is made from that record.

The attacks of the issue, as someone holding the bench's files would make them: a file of
the run folder changed after the run (result.json, stand.yaml, meta.json, one raw byte, a
lab file added), a run no register saw start, a copy and a renamed copy of an issued run;
each refused or given the same number. A short run under an SQLite register shows the
record made at the start and completed at the end, an analysis registered with its reason,
and a real stand without a register refused before anything moves. The register service's
path (PostgreSQL, the bench's role) is in tests/test_register_service.py.
"""

from __future__ import annotations

import json
import shutil
from collections.abc import Callable
from pathlib import Path

import pytest

from bench.app.register import Register
from bench.app.register.runs import raw_digests, run_uid_of
from bench.core import rundir_layout as layout
from tests import test_authorise
from tests.conftest import CONFIGS, check_procedure, cli, run_dir_of
from tests.registers import authorise, enrol, lab_file, lab_register, sqlite_register

run = test_authorise.run        # a copy of the session's demo run, and a lab file naming
lab = test_authorise.lab        # a fresh SQLite register


def _largest_raw(run: Path) -> Path:
    return max((p for p in layout.raw_root(run).rglob("*") if p.is_file()),
               key=lambda p: p.stat().st_size)


def _edit_result(run: Path, lab: Path) -> Path:
    """result.json's `simulated` made false and a figure moved, as the issue's attacker."""
    path = run / layout.RESULT
    result = json.loads(path.read_text())
    result["stand"]["simulated"] = False
    path.write_text(json.dumps(result, indent=2) + "\n")
    return path


def _edit_stand(run: Path, lab: Path) -> Path:
    path = run / layout.STAND
    path.write_text(path.read_text().replace("serial:", "serial: ", 1) + "# edited\n")
    return path


def _edit_meta(run: Path, lab: Path) -> Path:
    path = run / layout.META
    meta = json.loads(path.read_text())
    meta["performer"] = {"account": "M. Madeup", "full_name": "Made Up",
                         "register": "sqlite:///x", "authenticated_utc": "2026-01-01T00:00:00Z"}
    path.write_text(json.dumps(meta, indent=2) + "\n")
    return path


def _flip_raw_byte(run: Path, lab: Path) -> Path:
    path = _largest_raw(run)
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0x01
    path.write_bytes(bytes(data))
    return path


def _add_lab(run: Path, lab: Path) -> Path:
    """A lab file put in a run that ran without one (the same as --lab names: the one-rule
    for lab files lets it pass; the register's record does not)."""
    path = run / layout.LAB
    shutil.copyfile(lab, path)
    return path


def _plant_corrections(run: Path, lab: Path) -> Path:
    """A corrections file put in the folder after the run (issue 58): the analysis would
    read it and move every figure by e; the registered result applied none."""
    path = run / "corrections.json"
    path.write_text(json.dumps({"corrections": [{
        "where": "axes.outer.counter", "quantity": "timebase_offset_rel", "value": 3e-7,
        "U": 3e-8}]}))
    return path


@pytest.mark.parametrize("tamper", [_edit_result, _edit_stand, _edit_meta, _flip_raw_byte,
                                    _add_lab, _plant_corrections])
def test_a_file_changed_after_the_run_is_refused_by_name(
        run: Path, lab: Path, tamper: Callable[[Path, Path], Path]) -> None:
    url = lab_register(lab)
    assert url is not None
    enrol(run, url)                        # the register's record, as at the run's start
    changed = tamper(run, lab)
    done = authorise(run, "P. Petrov", lab)
    assert done.returncode == 2, done.stdout + done.stderr
    assert "no longer matches the lab register's record" in done.stderr, done.stderr
    assert str(changed) in done.stderr, done.stderr
    assert not (run / layout.ISSUED).exists()
    with Register.open(url, migrate=False) as reg:
        assert reg.number_of_run(run_uid_of(run)) is None    # no number spent on it


def test_a_run_no_register_saw_start_stays_a_draft(run: Path, lab: Path) -> None:
    """Issue 54 finding 3: a run made without a register, issued afterwards with --lab."""
    done = authorise(run, "P. Petrov", lab, enrolled=False)
    assert done.returncode == 2, done.stdout
    assert "holds no record of this run" in done.stderr
    assert "never issued" in done.stderr
    assert not (run / layout.ISSUED).exists()
    # and the demo's draft says why it cannot be issued (the README's one command)
    html = (run / layout.CERTIFICATE_HTML).read_text()
    assert "DRAFT, NOT AUTHORISED" in html
    assert "It can never be issued: no lab register was named when the run started" in html


def test_a_copy_or_a_renamed_copy_only_reissues_the_same_number(run: Path, lab: Path,
                                                                 tmp_path: Path) -> None:
    """Issue 54 finding 2: one run, one number, whatever folder holds it."""
    first = authorise(run, "P. Petrov", lab)
    assert first.returncode == 0, first.stderr
    number = next((run / layout.ISSUED).iterdir()).name
    copy = tmp_path / "elsewhere" / run.name
    shutil.copytree(run, copy, symlinks=True)          # cp -a
    renamed = tmp_path / "renamed" / "some-other-name"
    shutil.copytree(run, renamed, symlinks=True)
    for folder in (copy, renamed):
        again = authorise(folder, "P. Petrov", lab)
        assert again.returncode == 2
        assert f"certificate {number} is already issued" in again.stderr, again.stderr
    reissued = authorise(renamed, "P. Petrov", lab, "--reason",
                         "re-issued from a renamed copy of the same run's folder")
    assert reissued.returncode == 0, reissued.stderr
    assert (renamed / layout.ISSUED / f"{number}-R2").is_dir()
    with Register.open(lab_register(lab) or "", migrate=False) as reg:
        assert [r.revision for r in reg.revisions(number)] == [1, 2]
        assert reg.number_of_run(run_uid_of(run)) == number


def test_a_run_under_a_register_is_recorded_from_its_start(tmp_path: Path) -> None:
    """A short check run under an SQLite register: the record made at the start (before
    the run folder), completed at the session's end; `bench analyze --reason` registers
    an analysis; the issue states the record; result.json edited afterwards is refused."""
    url = sqlite_register(tmp_path / "register")
    labf = lab_file(tmp_path / "lab", url)
    proc = check_procedure(tmp_path / "files", seed=3)
    out = cli("run", str(proc), "--yes", "--quiet", "--out", str(tmp_path / "runs"),
              "--lab", str(labf))
    assert out.returncode in (0, 1), out.stderr[-3000:]
    made = run_dir_of(out)
    uid = run_uid_of(made)
    meta = json.loads((made / layout.META).read_text())
    with Register.open(url, migrate=False) as reg:
        rec = reg.run_record(uid)
        assert rec is not None and rec.uid == uid
        # the inputs as used, hashed by the register's record and by meta.json alike
        assert rec.inputs[layout.PROCEDURE] == meta["procedure_sha256"]
        assert rec.inputs[layout.STAND] == meta["stand_sha256"]
        assert layout.LAB in rec.inputs
        assert rec.simulated and rec.version == meta["bench_version"]
        assert rec.raw == raw_digests(made) and len(rec.raw) >= 3
        assert rec.result_bytes == (made / layout.RESULT).read_bytes()
        assert [e.kind for e in rec.events] == ["start", "session"]
        actions = [r.action for r in reg.audit_rows()]
        assert actions.count("run registered") == 1
        assert actions.count("run session result") == 1
    again = cli("analyze", str(made), "--reason", "re-analysed for the test", "--quiet")
    assert again.returncode in (0, 1), again.stderr[-2000:]
    with Register.open(url, migrate=False) as reg:
        rec = reg.run_record(uid)
        assert rec is not None
        assert [e.kind for e in rec.events] == ["start", "session", "analysis"]
        assert rec.events[-1].detail.reason == "re-analysed for the test"
        assert rec.result_bytes == (made / layout.RESULT).read_bytes()
    verified = cli("verify", str(made), "--reanalyse")
    assert verified.returncode == 0, verified.stdout + verified.stderr
    assert "the lab register's record of the run" in verified.stdout
    assert "equal, byte for byte" in verified.stdout.splitlines()[-1], verified.stdout
    issued = authorise(made, "P. Petrov", labf, enrolled=False)
    assert issued.returncode == 0, issued.stderr
    number = next((made / layout.ISSUED).iterdir())
    html = (number / layout.CERTIFICATE_HTML).read_text()
    assert f"record of run {uid}" in html and rec.registered_utc in html
    assert (number / layout.RESULT).read_bytes() == rec.result_bytes


def test_a_real_stand_without_a_register_is_refused_before_anything_moves(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The shipped real stand (its addresses are another host's: nothing may be opened)
    with the demo's outer axis and no lab file: refused, no run folder made."""
    import yaml

    monkeypatch.delenv("BENCH_LAB_SETTINGS", raising=False)
    shutil.copyfile(CONFIGS / "stands" / "example-real.yaml", tmp_path / "stand.yaml")
    proc = yaml.safe_load((CONFIGS / "procedures" / "demo.yaml").read_text())
    proc["stand"] = "stand.yaml"
    proc["axes"].pop("inner", None)
    (tmp_path / "proc.yaml").write_text(yaml.safe_dump(proc))
    out = cli("run", str(tmp_path / "proc.yaml"), "--yes", "--out", str(tmp_path / "runs"))
    assert out.returncode == 2, out.stdout + out.stderr
    assert "a real stand runs only under the lab's register" in out.stderr, out.stderr
    assert not (tmp_path / "runs").exists()
