"""Profile position mode (CiA 402, 0x6060 = 1): the 180 deg turn of the drift-pulse
procedure, the axis driver against its drive twin over a python-can virtual bus.

Truth: the stand model's angle (which the twin's position actual reports) and the
targets asked; the stand's table turns 100 ppm fast (tests/test_axis.py's rig), so
the drive's position loop must correct the landing."""

from __future__ import annotations

import pytest

from drivers.axis import AxisError, DriveFault, LimitError, PositionError
from drivers.cia402 import FOLLOWING_ERROR, PROFILE_POSITION, PROFILE_VELOCITY, State
from tests.test_axis import Rig, make_rig, rig  # noqa: F401 - the fixture

pytestmark = pytest.mark.timeout(30)


def test_a_180_degree_turn_lands_within_tolerance_and_back(rig: Rig) -> None:  # noqa: F811
    with rig.axis(position_tolerance_deg=0.005) as ax:
        start = ax.position_deg
        end = ax.move_to(start + 180.0, rate_dps=30.0, accel_dps2=30.0)
        assert ax.mode is PROFILE_POSITION
        rig.stand.advance()
        truth = rig.model.angle_deg
        assert abs(truth - (start + 180.0)) <= 0.005      # the table, not only the report
        assert abs(end - truth) <= 2 * 360.0 / 2**20       # position actual is the table's
        assert rig.at_rest()
        back = ax.move_to(start, rate_dps=30.0, accel_dps2=30.0)
        assert abs(back - start) <= 0.005
        # a short move is a triangle: it never reaches the cruise rate, and still lands
        ax.move_to(start + 0.5, rate_dps=30.0, accel_dps2=30.0)
        rig.stand.advance()
        assert abs(rig.model.angle_deg - (start + 0.5)) <= 0.005
        # back to rates: set_rate takes profile velocity again
        ax.set_rate(10.0)
        assert ax.mode is PROFILE_VELOCITY
    assert rig.at_rest()
    moves = [r for k, r in rig.journal if k == "moved"]
    assert len(moves) == 3 and all(abs(r["error_deg"]) <= 0.005 for r in moves)


def test_landing_outside_the_stand_tolerance_is_a_position_error() -> None:
    """A drive whose own position window (0.05 deg) is looser than the stand's tolerance
    (0.005 deg) reports 'target reached' 0.009 deg short of a 90 deg move (its table
    turns 100 ppm fast): the driver checks the position itself and refuses."""
    r = make_rig(position_window_deg=0.05)
    r.twin.start()
    try:
        with r.axis(position_tolerance_deg=0.005) as ax, \
                pytest.raises(PositionError, match="outside the position tolerance"):
            ax.move_to(ax.position_deg + 90.0, rate_dps=45.0, accel_dps2=45.0)
        r.stand.advance()
        assert r.model.angle_deg == pytest.approx(90.0 * (1 + 1e-4), abs=1e-4)
    finally:
        r.twin.stop()


def test_refusals_before_anything_moves(rig: Rig) -> None:  # noqa: F811
    with rig.axis() as ax:
        with pytest.raises(LimitError, match="over the stand's max_rate_dps"):
            ax.move_to(180.0, rate_dps=1000.0)
        with pytest.raises(LimitError, match="rate > 0"):
            ax.move_to(180.0, rate_dps=0.0)
        ax.set_rate(20.0)
        ax.wait_settled(rig.twin.servo_tolerance_dps, 0.2, 30.0)
        with pytest.raises(AxisError, match="starts from rest"):
            ax.move_to(180.0, rate_dps=30.0)


@pytest.mark.timeout(20)
def test_a_fault_during_the_turn_raises_and_the_axis_ends_at_rest(rig: Rig) -> None:  # noqa: F811
    import threading

    with pytest.raises(DriveFault) as info, rig.axis() as ax:
        threading.Timer(1.0 / rig.clock.speed * 2.0, rig.twin.inject,
                        args=(FOLLOWING_ERROR,)).start()     # 2 s of stand time into the turn
        ax.move_to(ax.position_deg + 180.0, rate_dps=30.0, accel_dps2=30.0)
    assert info.value.code == FOLLOWING_ERROR.code
    assert rig.at_rest()
    assert rig.twin.state is State.FAULT
    assert abs(rig.model.angle_deg) < 179.0   # it stopped short: the turn was cut


def test_the_profile_position_row_of_the_tables() -> None:
    from drivers.cia402 import MODES, Cw, Od, Sw

    assert MODES[1] is PROFILE_POSITION
    assert PROFILE_POSITION.target == Od.TARGET_POSITION == 0x607A
    assert PROFILE_POSITION.supported_bit == 0x1            # 0x6502 bit 0
    assert PROFILE_POSITION.speed_zero_bit is None          # bit 12 is set-point ack in PP
    assert Cw.NEW_SET_POINT == 0x10 and Sw.SET_POINT_ACKNOWLEDGE == 0x1000
    assert Od.PROFILE_VELOCITY_PP == 0x6081 and Od.POSITION_WINDOW == 0x6067
