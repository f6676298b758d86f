"""A drive's settings, declared once (drivers/drive_settings.py): the stand's schema,
`bench schema` and the loader read the declaration; the driver applies a setting at
connect; a refusal names file:line:key, whether the schema's nodes or a rule of the
declaration (msgspec's `$.path`) refuse it."""

from __future__ import annotations

import shutil
from pathlib import Path

import msgspec
import pytest

from bench.app.cli import main
from bench.core.schema import SettingsRefused, struct_at
from drivers.cia402 import Od
from drivers.drive_settings import DriveSettings
from tests.conftest import CONFIGS, Twins, drive_settings, one_axis_stand


@pytest.fixture
def stand(tmp_path: Path) -> tuple[Path, Path]:
    """A copy of the demo procedure and its stand, to edit."""
    (tmp_path / "stands").mkdir()
    (tmp_path / "procedures").mkdir()
    shutil.copy(CONFIGS / "stands" / "sim-two-axis.yaml", tmp_path / "stands")
    shutil.copy(CONFIGS / "procedures" / "demo.yaml", tmp_path / "procedures")
    return tmp_path / "procedures" / "demo.yaml", tmp_path / "stands" / "sim-two-axis.yaml"


def _edit(path: Path, old: str, new: str) -> int:
    """Edit the file; return the 1-based line of the edit."""
    text = path.read_text()
    assert old in text, old
    path.write_text(text.replace(old, new, 1))
    return text[: text.index(old)].count("\n") + 1


def test_bench_schema_lists_the_quick_stop_deceleration_with_unit_and_meaning(
        capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["schema", "stand"]) == 0
    out = capsys.readouterr().out.splitlines()
    at = out.index("axes.<name>.drive.quick_stop_decel_dps2")
    assert out[at + 1].strip() == "a number > 0 and <= 100000; unit deg/s^2"
    assert "CiA 402 0x6085" in out[at + 2]
    assert main(["schema", "stand", "--json"]) == 0
    drive = msgspec.json.decode(capsys.readouterr().out)["properties"]["axes"][
        "additionalProperties"]["properties"]["drive"]["properties"]
    assert drive["quick_stop_decel_dps2"]["x-unit"] == "deg/s^2"
    assert drive["quick_stop_decel_dps2"]["exclusiveMinimum"] == 0


def test_a_wrong_type_for_it_exits_2_at_its_file_line_and_key(
        stand: tuple[Path, Path], capsys: pytest.CaptureFixture[str]) -> None:
    proc, stand_file = stand
    line = _edit(stand_file, "heartbeat_ms: 200, watchdog_ms: 1500}   # twins",
                 "heartbeat_ms: 200, watchdog_ms: 1500,\n              "
                 "quick_stop_decel_dps2: fast}   # twins")
    assert main(["validate", str(proc)]) == 2
    err = capsys.readouterr().err
    assert (f"{stand_file}:{line + 1}: axes.outer.drive.quick_stop_decel_dps2: expected a "
            f"number > 0 and <= 100000 deg/s^2, got text 'fast'") in err, err


def test_a_rule_between_keys_is_refused_at_the_key_it_names(
        stand: tuple[Path, Path], capsys: pytest.CaptureFixture[str]) -> None:
    """watchdog_ms must exceed twice heartbeat_ms: DriveSettings.__post_init__, raised in
    msgspec's conversion, placed at watchdog_ms's line by `bench validate` (it used to
    surface only when the axis opened)."""
    proc, stand_file = stand
    line = _edit(stand_file, "heartbeat_ms: 200, watchdog_ms: 1500}\n",
                 "heartbeat_ms: 200,\n              watchdog_ms: 300}\n")
    assert main(["validate", str(proc)]) == 2
    err = capsys.readouterr().err
    assert (f"{stand_file}:{line + 1}: axes.inner.drive.watchdog_ms: 300 must exceed twice "
            f"heartbeat_ms = 200") in err, err


def test_msgspec_paths_become_key_paths() -> None:
    at = ("axes", "outer", "drive")
    with pytest.raises(SettingsRefused) as info:
        struct_at(DriveSettings, {"interface": "virtual", "channel": "c", "node_id": 200,
                                  "max_rate_dps": 10, "max_accel_dps2": 10}, at)
    assert (info.value.path, info.value.message) == ((*at, "node_id"),
                                                     "Expected `int` <= 127")
    with pytest.raises(SettingsRefused) as info:
        struct_at(DriveSettings, {"interface": "virtual", "channel": "c", "node_id": 2,
                                  "max_rate_dps": 10, "max_accel_dps2": 10,
                                  "calibration": {"certificate": 7, "issuer": "L",
                                                  "due": "2027-01-31"}}, at)
    assert info.value.path == (*at, "calibration", "certificate")
    with pytest.raises(SettingsRefused) as info:
        struct_at(DriveSettings, {"interface": "virtual", "channel": "c", "node_id": 2,
                                  "max_rate_dps": 10, "max_accel_dps2": 10,
                                  "unit_factors": {"velocity": "furlong/s"}}, at)
    assert info.value.path == (*at, "unit_factors")
    assert "units one of" in info.value.message


@pytest.mark.timeout(30)
def test_the_driver_writes_it_at_connect_in_the_drives_units(twins: Twins) -> None:
    """500 deg/s^2 at 2^20 counts per turn and the twin's inc/s^2 is
    round(500 / (360 / 2^20)) = 1456356 in 0x6085, read back as written."""
    from drivers.axis import Axis
    from sims.clock import VirtualClock

    clock = VirtualClock(20.0)
    twin = twins.drive(one_axis_stand(clock))
    before = twin._get(Od.QUICK_STOP_DECELERATION)
    with Axis("outer", drive_settings(twin.channel, quick_stop_decel_dps2=500.0),
              clock=clock) as ax:
        assert twin._get(Od.QUICK_STOP_DECELERATION) == 1456356 != before
        assert ax.readback["drive.quick stop deceleration 0x6085"] == "500 deg/s^2"
