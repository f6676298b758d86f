"""`bench validate` on broken files: exit 2, every problem named by file:line:key."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import pytest

from bench.app.cli import main
from tests.conftest import CONFIGS


@pytest.fixture
def files(tmp_path: Path) -> tuple[Path, Path]:
    """A copy of the demo procedure and its stand, to break."""
    (tmp_path / "stands").mkdir()
    (tmp_path / "procedures").mkdir()
    stand = tmp_path / "stands" / "sim-two-axis.yaml"
    proc = tmp_path / "procedures" / "demo.yaml"
    shutil.copy(CONFIGS / "stands" / "sim-two-axis.yaml", stand)
    shutil.copy(CONFIGS / "procedures" / "demo.yaml", proc)
    return proc, stand


def _replace(path: Path, old: str, new: str) -> int:
    """Edit the file; return the 1-based line of the edit."""
    text = path.read_text()
    assert old in text, old
    line = text[: text.index(old)].count("\n") + 1
    path.write_text(text.replace(old, new, 1))
    return line


def _validate(proc: Path, capsys: pytest.CaptureFixture[str]) -> tuple[int, str]:
    rc = main(["validate", str(proc)])
    return rc, capsys.readouterr().err


def test_the_shipped_configs_are_valid(capsys: pytest.CaptureFixture[str]) -> None:
    procedures = sorted((CONFIGS / "procedures").glob("*.yaml"))
    assert len(procedures) >= 3, procedures  # demo, drift-demo, paper-ladder at least
    for proc in procedures:
        rc, err = _validate(proc, capsys)
        assert rc == 0, (proc, err)


def test_bad_yaml_syntax(files: tuple[Path, Path], capsys: pytest.CaptureFixture[str]) -> None:
    proc, _ = files
    line = _replace(proc, "turns: 4", "turns: [4")
    rc, err = _validate(proc, capsys)
    assert rc == 2
    # reported where the broken list opens, at its key, not where the parser noticed
    assert f"{proc}:{line}: turns: YAML syntax" in err, err


def test_unknown_key_is_named_with_its_line(files: tuple[Path, Path],
                                            capsys: pytest.CaptureFixture[str]) -> None:
    proc, _ = files
    line = _replace(proc, "turns: 4", "turnz: 4")
    rc, err = _validate(proc, capsys)
    assert rc == 2
    assert f"{proc}:{line}: turnz: unknown key" in err


def test_wrong_type_in_the_stand_file(files: tuple[Path, Path],
                                      capsys: pytest.CaptureFixture[str]) -> None:
    proc, stand = files
    line = _replace(stand, "node_id: 3", "node_id: three")
    rc, err = _validate(proc, capsys)
    assert rc == 2
    assert f"{stand}:{line}: axes.inner.drive.node_id: expected an integer" in err
    assert "'three'" in err


def test_validate_refuses_two_drives_with_one_node_id(files: tuple[Path, Path],
                                                      capsys: pytest.CaptureFixture[str]
                                                      ) -> None:
    proc, stand = files
    line = _replace(stand, "node_id: 3", "node_id: 2")
    rc, err = _validate(proc, capsys)
    assert rc == 2
    assert (f"{stand}:{line}: axes.inner.drive.node_id: node id 2 on CAN bus virtual:bench "
            f"is already axis 'outer''s drive") in err


def test_rate_above_the_axis_limit(files: tuple[Path, Path],
                                   capsys: pytest.CaptureFixture[str]) -> None:
    proc, _ = files
    line = _replace(proc, "rates_dps: [20, 100]", "rates_dps: [20, 100, 420]")
    rc, err = _validate(proc, capsys)
    assert rc == 2
    assert f"{proc}:{line}: axes.inner.rates_dps[2]: 420 deg/s exceeds axis 'inner'" in err
    assert "max_rate_dps 360" in err


def test_missing_stand_file(files: tuple[Path, Path], capsys: pytest.CaptureFixture[str]) -> None:
    proc, stand = files
    stand.unlink()
    line = _replace(proc, "stand: ../stands/sim-two-axis.yaml", "stand: ../stands/sim-two-axis.yaml")
    rc, err = _validate(proc, capsys)
    assert rc == 2
    assert f"{proc}:{line}: stand: stand file" in err and "file not found" in err


def test_every_problem_is_reported_at_once(files: tuple[Path, Path],
                                           capsys: pytest.CaptureFixture[str]) -> None:
    proc, stand = files
    _replace(proc, "turns: 4", "turns: 0")
    _replace(proc, "harmonics: 3", "harmonics: lots")
    _replace(stand, "max_rate_dps: 400", "max_rate_dps: -1")
    rc, err = _validate(proc, capsys)
    assert rc == 2
    assert "3 problem(s)" in err
    assert "turns: expected an integer >= 1" in err
    assert "harmonics: expected an integer" in err
    assert "axes.outer.drive.max_rate_dps" in err


def test_nothing_starts_on_invalid_input(files: tuple[Path, Path], tmp_path: Path,
                                         capsys: pytest.CaptureFixture[str]) -> None:
    proc, _ = files
    _replace(proc, "turns: 4", "turnz: 4")
    out = tmp_path / "runs"
    rc = main(["run", str(proc), "--yes", "--out", str(out)])
    assert rc == 2
    assert not out.exists()


def test_plan_estimates_the_papers_ladder_in_real_bench_time(
        capsys: pytest.CaptureFixture[str]) -> None:
    rc = main(["plan", str(CONFIGS / "procedures" / "paper-ladder.yaml")])
    out = capsys.readouterr().out
    assert rc == 0
    # 5 turns at 0.1 deg/s is 5 h per direction: one pair alone is > 10 h per axis
    m = re.search(r"Estimated bench time: (\d+) h", out)
    assert m and int(m.group(1)) >= 20, out


def test_numbers_with_an_unsigned_exponent_are_numbers(tmp_path: Path) -> None:
    from bench.core.yamlfile import load_yaml

    f = tmp_path / "n.yaml"
    f.write_text("impedance_ohm: 1.0e6\nrate: 1e2\nrel: 1.0e-6\nname: 1e6x\nn: 12\n")
    assert load_yaml(f).data == {"impedance_ohm": 1.0e6, "rate": 100.0, "rel": 1e-6,
                                 "name": "1e6x", "n": 12}


def test_every_shipped_stand_file_fits_a_procedure_kind() -> None:
    from bench.core.registry import procedure_kind, procedure_names
    from bench.core.schema import validate
    from bench.core.yamlfile import load_yaml

    stands = sorted((CONFIGS / "stands").glob("*.yaml"))
    assert len(stands) >= 3, stands  # two sim stands and the real example at least
    for stand in stands:
        doc = load_yaml(stand)
        fits = [validate(doc, procedure_kind(n).settings.stand_schema()) for n in procedure_names()]
        assert any(not problems for problems in fits), (stand, fits)


def test_a_fog_declared_inverted_is_refused(files: tuple[Path, Path],
                                            capsys: pytest.CaptureFixture[str]) -> None:
    """`fog.sign: -1` was validated and never read: the analysis took an inverted FOG as
    upright, every k and w0 of the wrong sign. Until the sign is carried end to end it is
    refused by `bench validate`, at its line; +1 (upright, the default) is valid."""
    proc, stand = files
    line = _replace(stand, "units: deg/s, configure: set}   # from",
                    "units: deg/s, configure: set, sign: -1}   # from")
    rc, err = _validate(proc, capsys)
    assert rc == 2
    assert f"{stand}:{line}: axes.outer.fog.sign: only +1 is supported" in err, err
    assert "inverted FOG would give figures of the wrong sign" in err
    _replace(stand, "sign: -1}", "sign: 1}")
    assert _validate(proc, capsys)[0] == 0


def test_the_stand_parses_into_frozen_settings_with_one_default_each() -> None:
    """What the loader returns below the raw files: frozen settings whose defaults are
    the schema keys' (the reference prints them), which are the drivers' own."""
    import inspect

    import msgspec

    from bench.core.config import COUNTER, DRIVE, FOG
    from bench.core.loader import load_config
    from drivers.axis import Axis
    from drivers.drive_settings import DriveSettings
    from drivers.time_tie import TimeTie
    from procedures.rate_ladder.settings import LadderSettings

    cfg = load_config(CONFIGS / "procedures" / "demo.yaml")
    stand = cfg.stand_settings
    assert isinstance(cfg.settings, LadderSettings)           # the kind's `parse`, once
    outer = stand.axes["outer"]
    with pytest.raises(AttributeError):      # frozen
        outer.drive.node_id = 9  # type: ignore[misc]
    assert (outer.drive.node_id, outer.drive.controller_node_id) == (2, 127)
    assert outer.counter is not None and outer.counter.time_tie is not None
    assert outer.counter.time_tie.source == "fog-sync"
    assert outer.fog is not None and outer.fog.sign == 1
    assert stand.identity.serial == "SIM-0001" and stand.sim is not None
    assert stand.sim.axis("outer").truth.fog.scale == 1.0003
    # the driver takes the settings whole: its defaults are the declaration's
    assert "settings" in inspect.signature(Axis).parameters
    axis_defaults = {f.name: f.default for f in msgspec.structs.fields(DriveSettings)}
    for key in ("heartbeat_ms", "counts_per_rev", "pdo", "unit_factors", "position_tolerance_deg"):
        assert DRIVE.keys[key].default == axis_defaults[key], key
    assert COUNTER.keys["timeout_margin_s"].default is not None
    tie = COUNTER.keys["time_tie"].node.keys       # type: ignore[attr-defined]
    assert tie["sync_period_s"].default == TimeTie().sync_period_s
    assert tie["source"].required
    assert FOG.keys["sign"].default == 1


def test_each_setting_is_declared_once_on_its_struct() -> None:
    """The schema (`bench validate`, `bench schema`, JSON Schema) and the parse come from
    one declaration per key: every declared field is a schema key with the field's own
    default, every schema key a field, and the parse turns the YAML's numbers into the
    field's type (a float field holds a float even when the file writes 490)."""
    import msgspec

    from bench.core.config import (
        CALIBRATION,
        COUNTER,
        DRIVE,
        FOG,
        IDENTITY,
        SIM_KEYS,
        Calibration,
        CommonSettings,
        CounterSettings,
        FogSettings,
        Identity,
        SimSettings,
    )
    from bench.core.config import (
        COMMON_PROCEDURE_KEYS as COMMON,
    )
    from bench.core.schema import Map, struct_at, struct_map
    from drivers.drive_settings import DriveSettings
    from procedures.drift_pulse.settings import PROCEDURE as DRIFT
    from procedures.drift_pulse.settings import DriftFile
    from procedures.rate_ladder.settings import PROCEDURE as LADDER
    from procedures.rate_ladder.settings import LadderSettings, Settle

    for struct, node in ((Calibration, CALIBRATION), (DriveSettings, DRIVE),
                         (CounterSettings, COUNTER), (FogSettings, FOG),
                         (Identity, IDENTITY)):
        assert node == struct_map(struct), struct
        struct_fields = {f.encode_name: f for f in msgspec.structs.fields(struct)}
        assert list(node.keys) == list(struct_fields), struct
        for key, spec in node.keys.items():
            default = struct_fields[key].default
            if isinstance(default, int | float | str) and key != "controller_node_id":
                assert spec.default == default and not spec.required, (struct, key)
    for cls, node in ((SimSettings, Map(SIM_KEYS)), (CommonSettings, Map(COMMON))):
        assert node == struct_map(cls), cls
        fields = {f.encode_name: f for f in msgspec.structs.fields(cls)}
        for key, spec in node.keys.items():
            f = fields[key]
            if isinstance(f.default, int | float | str) and key not in ("procedure", "stand"):
                assert spec.default == f.default and not spec.required, (cls, key)
    assert "session" not in SIM_KEYS and "can_bus" not in SIM_KEYS   # set in code only
    assert COMMON["procedure"].required and COMMON["stand"].required
    assert not COMMON["title"].required and COMMON["title"].default is None   # given
    for key, spec in struct_map(LadderSettings).keys.items():
        assert LADDER.keys[key] == spec, (LadderSettings, key)
    for key, spec in struct_map(DriftFile).keys.items():
        assert DRIFT.keys[key] == spec, (DriftFile, key)
    assert LADDER.keys["settle"].node == struct_map(Settle)
    assert DRIFT.keys["positions_deg"].default == (0.0, 180.0)
    drift = struct_at(DriftFile, {"site": {"latitude_deg": 48}, "positions_deg": [0, 180],
                                  "pulse": {"shape": "rectangular", "duration_s": 1,
                                            "amplitude_v": 2}})
    assert drift.positions_deg == (0.0, 180.0) and isinstance(drift.pulse.duration_s, float)
    assert (drift.cycles, drift.timing_cycles, drift.digitizer.sample_rate_hz) == (10, 4, 2000.0)
    fog = struct_at(FogSettings, {"port": "/dev/null", "rate_hz": 1000, "units": "deg/s",
                                       "range_dps": 490, "calibration": {
                                           "certificate": "C-1", "issuer": "L",
                                           "due": "2027-01-31"}})
    assert isinstance(fog.rate_hz, float) and isinstance(fog.range_dps, float)
    assert (fog.baudrate, fog.format, fog.configure) == (921600, "kvh-a", "declare")
    assert fog.calibration is not None and str(fog.calibration.due) == "2027-01-31"
    drive = struct_at(DriveSettings, {"interface": "virtual", "channel": "c", "node_id": 3,
                                      "max_rate_dps": 400, "max_accel_dps2": 200},
                      controller_node_id=127)
    assert isinstance(drive.max_rate_dps, float)
    assert (drive.controller_node_id, drive.heartbeat_ms, drive.pdo) == (127, 50, "verify")
    assert not DRIVE.keys["controller_node_id"].required and DRIVE.keys["node_id"].required


@pytest.mark.timeout(120)
def test_the_twins_point_a_copy_of_the_parsed_stand_at_themselves() -> None:
    """One stand in flight: the twins' addresses go into a new StandSettings; the run's
    Config (its parsed stand and the stand file's mapping, copied into the run
    directory) stays as written."""
    import copy

    from bench.core.loader import load_config
    from bench.core.registry import procedure_kind

    cfg = load_config(CONFIGS / "procedures" / "demo.yaml")
    written, parsed = copy.deepcopy(cfg.stand), cfg.stand_settings
    simbench, served = procedure_kind(cfg.kind).steps.start_sim(cfg)
    try:
        assert cfg.stand == written and cfg.stand_settings is parsed
        for name, axis in served.axes.items():
            stated = parsed.axes[name]
            assert axis.fog is not None and stated.fog is not None
            assert axis.fog.port != stated.fog.port and axis.fog.port.startswith("/dev/")
            assert axis.counter is not None and stated.counter is not None
            assert "127.0.0.1" in axis.counter.resource
            assert axis.drive.channel != stated.drive.channel
            assert axis.drive.node_id == stated.drive.node_id
            assert (axis.fog.rate_hz, axis.counter.model) == (stated.fog.rate_hz,
                                                              stated.counter.model)
    finally:
        simbench.stop()


def test_a_number_written_as_a_key_is_the_key_as_text(tmp_path: Path) -> None:
    """The schema accepts `20: C` under conditions and names its key "20"; the parse
    (msgspec, whose dict[str, ...] refuses an int key) reads it as the same text."""
    import yaml

    from bench.core.loader import load_config

    doc = yaml.safe_load((CONFIGS / "procedures" / "demo.yaml").read_text())
    doc["stand"] = str((CONFIGS / "procedures" / doc["stand"]).resolve())
    doc["conditions"] = {20: "C", "humidity": 40}
    (tmp_path / "p.yaml").write_text(yaml.safe_dump(doc))
    cfg = load_config(tmp_path / "p.yaml")
    assert dict(cfg.common.conditions) == {"20": "C", "humidity": 40}
