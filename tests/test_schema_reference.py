"""`bench schema` and `bench init`: the reference is the validator's schema, stated as
JSON Schema and as docs/configuration.md, and the starter files validate."""

from __future__ import annotations

import json
from pathlib import Path

import jsonschema
import pytest

from bench.app.cli import main
from bench.core.yamlfile import load_yaml
from tests.conftest import CONFIGS

ROOT = Path(__file__).resolve().parents[1]
SHIPPED_STANDS = sorted([*(CONFIGS / "stands").glob("*.yaml"),
                         *(ROOT / "bench" / "examples" / "stands").glob("*.yaml")])


def _json_data(path: Path) -> object:
    """The file as the bench reads it (its YAML loader), as a JSON document (dates as text)."""
    return json.loads(json.dumps(load_yaml(path).data, default=str))


def _schema(capsys: pytest.CaptureFixture[str], *args: str) -> dict:
    assert main(["schema", *args, "--json"]) == 0
    schema = json.loads(capsys.readouterr().out)
    jsonschema.Draft202012Validator.check_schema(schema)
    return schema


def test_the_stand_json_schema_accepts_every_shipped_stand(
        capsys: pytest.CaptureFixture[str]) -> None:
    validator = jsonschema.Draft202012Validator(_schema(capsys, "stand"))
    assert len(SHIPPED_STANDS) >= 5
    for stand in SHIPPED_STANDS:
        errors = [e.message for e in validator.iter_errors(_json_data(stand))]
        assert not errors, (stand, errors)


# the broken stands of tests/test_config.py, test_validate_robust.py and
# test_every_problem_is_reported_at_once: each a schema error bench validate refuses
BROKEN = [
    ("node_id: 3", "node_id: three"),            # test_wrong_type_in_the_stand_file
    ("max_rate_dps: 400", "max_rate_dps: -1"),   # test_every_problem_is_reported_at_once
    ("units: deg/s, configure: set}   # from", "configure: set}   # from"),  # units required
    ("level_v: 2.5, slope: POS, trigger_jitter_s: 27.0e-9,\n              timebase",
     "level_v: 99, slope: POS, trigger_jitter_s: 27.0e-9,\n              timebase"),
    ("seed: 1", "seed: 1\n  turnz: 4"),          # an unknown key
    ("serial: SIM-0001,", "serial: 1,"),          # a serial is text
]


@pytest.mark.parametrize("old,new", BROKEN)
def test_the_stand_json_schema_rejects_the_broken_stands(
        old: str, new: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    validator = jsonschema.Draft202012Validator(_schema(capsys, "stand"))
    text = (CONFIGS / "stands" / "sim-two-axis.yaml").read_text()
    assert old in text, old
    broken = tmp_path / "stand.yaml"
    broken.write_text(text.replace(old, new, 1))
    assert list(validator.iter_errors(_json_data(broken)))
    # and bench validate refuses the same file
    proc = tmp_path / "p.yaml"
    proc.write_text("procedure: rate-ladder\nstand: stand.yaml\n"
                    "axes: {outer: {rates_dps: [10]}}\n")
    assert main(["validate", str(proc)]) == 2
    capsys.readouterr()


def test_procedure_and_lab_json_schemas_accept_the_shipped_files(
        capsys: pytest.CaptureFixture[str]) -> None:
    procs = sorted((CONFIGS / "procedures").glob("*.yaml"))
    assert len(procs) >= 2, procs          # the demo and the drift demo at least
    for proc in procs:
        data = _json_data(proc)
        assert isinstance(data, dict)
        validator = jsonschema.Draft202012Validator(_schema(capsys, "procedure",
                                                            data["procedure"]))
        assert not [e.message for e in validator.iter_errors(data)], proc
        bad = {**data, "turnz": 4}
        assert list(validator.iter_errors(bad))
    lab = jsonschema.Draft202012Validator(_schema(capsys, "lab"))
    assert not list(lab.iter_errors(_json_data(CONFIGS / "lab.yaml")))
    # every lab key is optional (the certificate says what is missing; `bench authorise`
    # refuses without an authorising signatory), but a misspelt key is refused
    assert list(lab.iter_errors({"laboratory": "x", "adress": "1 Example Street"}))


def test_docs_configuration_md_is_current(capsys: pytest.CaptureFixture[str]) -> None:
    """CI's check: regenerate with `bench schema --markdown > docs/configuration.md`."""
    assert main(["schema", "--markdown"]) == 0
    generated = capsys.readouterr().out
    assert (ROOT / "docs" / "configuration.md").read_text() == generated, (
        "docs/configuration.md is stale: bench schema --markdown > docs/configuration.md")
    for key in ("`axes.<name>.fog.units`", "`mains_hz`", "`harmonics`", "`sequence`",
                "`settle.hold_s`", "`static_record_s`", "`decision_rule`",
                "`axes.<name>.counter.reference`", "`axes.<name>.counter.timebase_limit_rel`"):
        assert key in generated, key


def test_the_reference_states_type_unit_default_and_meaning(
        capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["schema", "procedure", "rate-ladder"]) == 0
    out = capsys.readouterr().out
    block = out[out.index("\nturns"):].split("\n")[1:4]
    assert "default 5" in block[1] and "integer" in block[1], block
    assert main(["schema", "stand"]) == 0
    out = capsys.readouterr().out
    assert "axes.<name>.fog.rate_hz  (required)\n    a number >= 1 and <= 100000; unit Hz" in out
    assert "platform\n" in out and "required by procedure drift-pulse" in out


@pytest.mark.parametrize("args", [["procedure"], ["procedure", "no-such-kind"]])
def test_schema_refuses_an_unknown_kind(args: list[str],
                                        capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["schema", *args]) == 2
    assert "rate-ladder" in capsys.readouterr().err


@pytest.mark.parametrize("real", [False, True])
def test_init_writes_commented_files_that_validate(
        real: bool, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = tmp_path / "lab"
    assert main(["init", str(folder), *(["--real"] if real else [])]) == 0
    capsys.readouterr()
    for name in ("stand.yaml", "procedure.yaml", "lab.yaml"):
        text = (folder / name).read_text()
        assert text.count("#") >= 5, name
    assert ("sim" in load_yaml(folder / "stand.yaml").data) is not real
    assert main(["validate", str(folder / "procedure.yaml")]) == 0, capsys.readouterr().err
    assert main(["plan", str(folder / "procedure.yaml")]) == 0
    assert main(["init", str(folder)]) == 2          # never overwrites
    assert "not overwriting" in capsys.readouterr().err


def test_every_key_of_the_stand_and_the_ladder_says_what_it_means() -> None:
    from bench.app.reference import rows, schema_node, stand_node

    # the drift-pulse kind's own blocks (platform, its twins) are that kind's to document
    theirs = ("platform", "sim.platform", "sim.awg", "sim.dmm")
    missing = [r.path for r in rows(stand_node())
               if not r.meaning and not r.path.startswith(theirs)]
    missing += [r.path for r in rows(schema_node("procedure", "rate-ladder")) if not r.meaning]
    assert not missing, missing
