"""A real stand (no sim: block) must state what no driver can guess (issue 11):
the FOG's units (KVH power-on default: delta radians) and the counter's time tie."""

from __future__ import annotations

from pathlib import Path

import pytest

from bench.core.config import ConfigError
from bench.core.loader import load_config

ROOT = Path(__file__).resolve().parents[1]
PROCEDURE = """procedure: rate-ladder
stand: stand.yaml
turns: 4
axes:
  outer: {rates_dps: [10]}
tolerance:
  rate_error:
    - {rel: 1.0e-6}
"""
STAND = """stand: {maker: A, model: B, serial: "1"}
axes:
  outer:
    drive:   {interface: socketcan, channel: can0, node_id: 2, max_rate_dps: 400,
              max_accel_dps2: 200%(factors)s}
    counter: {resource: "TCPIP0::192.0.2.5::5025::SOCKET", model: keysight-53230a,
              level_v: 2.5, reference: internal%(tie)s}
    fog:     {port: /dev/ttyUSB0, format: kvh-a, axis: z, rate_hz: 1000%(units)s}
"""
TIE = (",\n              time_tie: {source: fog-sync, sync_period_s: 5, latency_s: 2.0e-6, "
       "latency_u_s: 2.0e-7}")


def load(tmp_path: Path, tie: str, units: str, factors: str = ", unit_factors: read"):
    (tmp_path / "p.yaml").write_text(PROCEDURE)
    (tmp_path / "stand.yaml").write_text(STAND % {"tie": tie, "units": units,
                                                  "factors": factors})
    return load_config(tmp_path / "p.yaml")


def test_a_real_stand_without_fog_units_is_refused_by_file_line_key(tmp_path):
    with pytest.raises(ConfigError) as e:
        load(tmp_path, TIE, "")
    assert "stand.yaml:9: axes.outer.fog: missing required key 'units'" in str(e.value)


def test_a_real_stand_without_a_time_tie_is_refused(tmp_path):
    with pytest.raises(ConfigError) as e:
        load(tmp_path, "", ", units: rad, configure: verify")
    assert "stand.yaml:6: axes.outer.counter: a real stand must state counter.time_tie" \
        in str(e.value)


def test_a_real_stand_without_drive_unit_factors_is_refused(tmp_path):
    with pytest.raises(ConfigError) as e:
        load(tmp_path, TIE, ", units: rad", factors="")
    assert "stand.yaml:4: axes.outer.drive: a real stand must state drive.unit_factors" \
        in str(e.value)


def test_a_fog_sync_tie_without_its_latency_uncertainty_is_refused(tmp_path):
    """Without latency_u_s the tie's term in the counter budget would silently be 0."""
    with pytest.raises(ConfigError) as e:
        load(tmp_path, TIE.replace(", latency_u_s: 2.0e-7", ""), ", units: rad")
    assert ("stand.yaml:8: axes.outer.counter.time_tie: a fog-sync time tie on a real "
            "stand must state latency_u_s") in str(e.value), str(e.value)


def test_stated_it_validates(tmp_path):
    cfg = load(tmp_path, TIE, ", units: deg/s, configure: set")
    assert cfg.stand["axes"]["outer"]["fog"]["configure"] == "set"


def test_every_counter_profile_names_its_manual_or_says_unverified():
    from bench.core.instruments import with_readback
    from drivers.counter_profiles import PROFILES

    manuals = {m: p.manual for m, p in PROFILES.items()}
    assert manuals["generic-scpi-period"].startswith("unverified")      # AKIP-5102
    assert "p. 240" in manuals["keysight-53230a"] and "p. 459" in manuals["keysight-53230a"]
    assert "p. 8-35" in manuals["pendulum-cnt-91"]
    text = with_readback("AKIP,AKIP-5102/1,1,1.00", {"counter.level_v": "+2.5E+00"},
                         "UNVERIFIED (no manual found)")
    assert text == ("AKIP,AKIP-5102/1,1,1.00; read back: counter.level_v = +2.5E+00; "
                    "driver checked against: UNVERIFIED (no manual found)")


def test_a_simulated_stand_must_also_say_its_fog_units(tmp_path):
    """The FOG twin powers on in delta radians as the unit does: no units, no run."""
    stand = (ROOT / "configs" / "stands" / "sim-two-axis.yaml").read_text()
    stand = stand.replace("units: deg/s, configure: set}   # from its power-on delta radians",
                          "}")
    (tmp_path / "stand.yaml").write_text(stand)
    (tmp_path / "p.yaml").write_text(PROCEDURE)
    with pytest.raises(ConfigError) as e:
        load_config(tmp_path / "p.yaml")
    line = stand[:stand.index("    fog:")].count("\n") + 1
    assert f"stand.yaml:{line}: axes.outer.fog: missing required key 'units'" in str(e.value)


@pytest.mark.parametrize("stated,expected", [
    ("", "stand.yaml:6: axes.outer.counter: a real stand must state counter.reference"),
    (", reference: external", "axes.outer.counter.reference: reference: external needs the "
                              "external reference's timebase_limit_rel"),
    (", reference: internal, timebase_limit_rel: 1.0e-9",
     "axes.outer.counter.timebase_limit_rel: 1e-09 is below the keysight-53230a's internal "
     "oscillator limit"),
])
def test_the_counter_reference_is_stated_and_agrees_with_the_budget(tmp_path, stated,
                                                                    expected):
    """Issue 26: a counter without reference silently got the internal 1 ppm limit in its
    budget while reading back EXT; the stand states it and the budget follows it."""
    (tmp_path / "p.yaml").write_text(PROCEDURE)
    (tmp_path / "stand.yaml").write_text(
        (STAND % {"tie": TIE, "units": ", units: deg/s", "factors": ", unit_factors: read"}
         ).replace(", reference: internal", stated))
    with pytest.raises(ConfigError) as e:
        load_config(tmp_path / "p.yaml")
    assert expected in str(e.value), str(e.value)
