"""CiA 402 unit factors and PDO timing: read (or set) at connect, against the drive twin.

Sources:
- Synapticon SOMANET object reference, 0x60A9 "SI unit velocity": 1 RPM = 0x00B44700
  (11814656), 0.1 RPM = 0xFFB44700, 0.01 RPM = 0xFEB44700, 0.001 RPM = 0xFDB44700.
- Nanotec PD4-E technical manual 5.3.1 "Units": unit codes revolution 0xB4, degree 0x41,
  radian 0x10; the factor objects 0x608F, 0x6091, 0x6092 take part.
- AMK DS402 object 0x608F "Position encoder resolution": sub 1 encoder increments, sub 2
  motor revolutions.
- CiA 301 TPDO communication parameter 0x1800: sub 2 transmission type (254/255 event
  driven), sub 5 event timer in ms (0: no timer; events are then changes of the data).
Unverified (CiA 402-2 is not public): the increment code 0xB5, the second 0x03 and the
layout of 0x60AA; drivers/cia402.py says so.
"""

from __future__ import annotations

import pytest

from drivers.axis import AxisError, LimitError
from drivers.cia402 import NAMED_SI_UNITS, UnitFactors, si_unit_deg
from tests.test_axis import MAX_RATE, RATE_BIAS_REL, make_rig

pytestmark = pytest.mark.timeout(40)


def test_si_unit_codes_as_the_manuals_print_them():
    cpr = 2**20
    assert si_unit_deg(0x00B44700, cpr, accel=False) == pytest.approx(6.0)       # 1 rpm
    assert si_unit_deg(0xFDB44700, cpr, accel=False) == pytest.approx(0.006)     # 0.001 rpm
    assert si_unit_deg(0xFFB44700, cpr, accel=False) == pytest.approx(0.6)       # 0.1 rpm
    assert NAMED_SI_UNITS["rpm"] == 11814656 and NAMED_SI_UNITS["0.001 rpm"] == 4256450304
    # 0.001 inc/s at 2^20 increments a turn: the controller's old hard-wired unit
    u = UnitFactors(cpr, 1, 1, 1, NAMED_SI_UNITS["0.001 inc/s"],
                    NAMED_SI_UNITS["inc/s2"]).drive_units()
    assert u.velocity_unit_counts_per_s == pytest.approx(1e-3)
    assert u.accel_unit_counts_per_s2 == pytest.approx(1.0)
    # a 1:4 gear (0x6091 = 4 motor revs per shaft rev) quadruples the increments a turn
    assert UnitFactors(cpr, 1, 4, 1, NAMED_SI_UNITS["rpm"],
                       NAMED_SI_UNITS["rpm/s"]).counts_per_rev == 4 * cpr
    with pytest.raises(ValueError, match="0x6096 velocity factor = 3/2"):
        UnitFactors(cpr, 1, 1, 1, NAMED_SI_UNITS["rpm"], NAMED_SI_UNITS["rpm/s"],
                    velocity_factor=(3, 2)).drive_units()


@pytest.mark.parametrize("velocity, accel, rate_dps", [
    ("rpm", "rpm/s", 60.0),          # 10 rpm: whole drive units
    ("inc/s", "inc/s2", 45.0),
])
def test_drive_in_its_own_units_settles_in_deg_s_and_refuses_over_limit(velocity, accel,
                                                                         rate_dps):
    r = make_rig(velocity_unit=velocity, acceleration_unit=accel)
    r.twin.start()
    try:
        with r.axis() as ax:          # unit_factors: read (the default)
            assert ax.readback["drive.factor 0x60A9"].startswith(
                {"rpm": "rev/min", "inc/s": "inc/s"}[velocity])
            ax.enable()
            sent = ax.set_rate(rate_dps)
            assert sent == pytest.approx(rate_dps, rel=1e-9)
            mean = ax.wait_settled(0.05, 2.0, 30.0)
            # the table's truth (100 ppm fast) is seen in deg/s through the drive's units
            r.stand.advance()
            assert r.model.rate_dps == pytest.approx(rate_dps * (1 + RATE_BIAS_REL),
                                                     abs=0.05)
            assert abs(mean - rate_dps) <= 0.05   # rpm: 60 deg/s is 10 whole units
            with pytest.raises(LimitError, match="over the stand's max_rate_dps"):
                ax.set_rate(MAX_RATE + 1.0)
            ax.stop()
    finally:
        r.twin.stop()


def test_unit_factors_set_at_connect_are_written_and_read_back():
    r = make_rig(velocity_unit="rpm", acceleration_unit="rpm/s")
    r.twin.start()
    try:
        with r.axis(unit_factors={"velocity": "0.001 inc/s", "acceleration": "inc/s2"}) as ax:
            assert ax.units.velocity_unit_counts_per_s == pytest.approx(1e-3)
            assert "0xFDB50300" in ax.readback["drive.factor 0x60A9"]
        assert r.twin.factors.velocity_si == NAMED_SI_UNITS["0.001 inc/s"]
    finally:
        r.twin.stop()


def test_tpdos_only_on_change_are_refused_or_set():
    r = make_rig(tpdo_event_timer_ms=0)
    r.twin.start()
    try:
        with pytest.raises(AxisError, match=r"drive.pdo \(TPDO1\): transmission type 254, "
                                            r"event timer 0 ms"):
            with r.axis():
                pass
        with r.axis(pdo="set") as ax:
            assert ax.readback["drive.pdo (TPDO1) transmission type"] == 255
            assert ax.readback["drive.pdo (TPDO1) event timer ms"] == 10
            ax.enable()
            ax.stop()              # the standstill wait needs feedback at rest
    finally:
        r.twin.stop()


def test_a_coarse_unit_never_rounds_a_command_beyond_the_stand_limit():
    """1 rpm = 6 deg/s: 400 deg/s is 66.7 rpm, nearest 67 rpm = 402 deg/s, over the stand's
    400; the command steps one unit toward zero instead (396 deg/s). The same for the
    acceleration: 200 deg/s^2 is 33.3 rpm/s, sent as 33 (198 deg/s^2), never 34."""
    u = UnitFactors(2**20, 1, 1, 1, NAMED_SI_UNITS["rpm"],
                    NAMED_SI_UNITS["rpm/s"]).drive_units()
    assert u.dps_to_velocity(400.0) == 67                      # nearest, unbounded
    assert u.dps_to_velocity(400.0, limit_dps=400.0) == 66
    assert u.dps_to_velocity(-400.0, limit_dps=400.0) == -66
    assert u.dps_to_velocity(102.0, limit_dps=400.0) == 17     # inside the limit: nearest
    assert u.dps2_to_accel(200.0, limit_dps2=200.0) == 33
    r = make_rig(velocity_unit="rpm", acceleration_unit="rpm/s")
    r.twin.start()
    try:
        with r.axis() as ax:
            ax.enable()
            assert ax.set_rate(MAX_RATE) == pytest.approx(396.0)
            ax.stop()
    finally:
        r.twin.stop()
