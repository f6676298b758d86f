"""The CiA 402 tables and unit conversions, against values worked out by hand from the
profile (statusword/controlword bit patterns, transition numbers) and from arithmetic."""

from __future__ import annotations

import pytest

from drivers.cia402 import (
    MODES,
    PROFILE_VELOCITY,
    Command,
    DriveUnits,
    State,
    decode_command,
    decode_state,
    describe_error,
    path,
    transition,
    unwrap_int32,
    wrap_int32,
)


@pytest.mark.parametrize("statusword, state", [
    (0x0000, State.NOT_READY_TO_SWITCH_ON),
    (0x0250, State.SWITCH_ON_DISABLED),      # remote + switch on disabled + voltage
    (0x0231, State.READY_TO_SWITCH_ON),
    (0x0233, State.SWITCHED_ON),
    (0x1637, State.OPERATION_ENABLED),       # + target reached + speed 0
    (0x0217, State.QUICK_STOP_ACTIVE),       # bit 5 clear
    (0x021F, State.FAULT_REACTION_ACTIVE),
    (0x0218, State.FAULT),
    (0x0208, State.FAULT),
])
def test_statusword_decodes_to_the_402_state(statusword: int, state: State) -> None:
    assert decode_state(statusword) is state


@pytest.mark.parametrize("controlword, command", [
    (0x0006, Command.SHUTDOWN),
    (0x0007, Command.SWITCH_ON),
    (0x000F, Command.ENABLE_OPERATION),
    (0x0000, Command.DISABLE_VOLTAGE),
    (0x000D, Command.DISABLE_VOLTAGE),       # bit 1 clear wins
    (0x0002, Command.QUICK_STOP),
    (0x000B, Command.QUICK_STOP),
    (0x0080, None),                          # fault reset is an edge, handled apart
])
def test_controlword_decodes_to_its_command(controlword: int, command: Command | None) -> None:
    assert decode_command(controlword) is command


def test_command_words_are_what_the_profile_prints() -> None:
    assert [c.word for c in (Command.SHUTDOWN, Command.SWITCH_ON, Command.ENABLE_OPERATION,
                             Command.DISABLE_VOLTAGE, Command.QUICK_STOP,
                             Command.FAULT_RESET)] == [0x06, 0x07, 0x0F, 0x00, 0x02, 0x80]


def test_transitions_carry_their_profile_numbers() -> None:
    assert transition(State.OPERATION_ENABLED, Command.QUICK_STOP).number == 11
    # transition 16 only where 0x605A keeps the drive in quick stop active (codes 5-8,
    # CiA 402-2 quick stop option code): with code 2 a real drive refuses it (issue 24)
    assert transition(State.QUICK_STOP_ACTIVE, Command.ENABLE_OPERATION) is None
    assert transition(State.QUICK_STOP_ACTIVE, Command.ENABLE_OPERATION, 2) is None
    for code in (5, 6, 7, 8):
        assert transition(State.QUICK_STOP_ACTIVE, Command.ENABLE_OPERATION, code).number == 16
    assert transition(State.FAULT, Command.FAULT_RESET).number == 15
    assert transition(State.SWITCH_ON_DISABLED, Command.ENABLE_OPERATION) is None


def test_paths_go_one_step_at_a_time_and_never_coast() -> None:
    assert path(State.SWITCH_ON_DISABLED, State.OPERATION_ENABLED) == [
        Command.SHUTDOWN, Command.SWITCH_ON, Command.ENABLE_OPERATION]
    assert path(State.FAULT, State.OPERATION_ENABLED) == [
        Command.FAULT_RESET, Command.SHUTDOWN, Command.SWITCH_ON, Command.ENABLE_OPERATION]
    # from enabled: 5 or 8 first (they ramp, 0x605C/0x605B), then disable voltage (10 or 7);
    # never 9, which opens the power stage at speed and lets the table coast
    first, second = path(State.OPERATION_ENABLED, State.SWITCH_ON_DISABLED)
    assert first in (Command.SWITCH_ON, Command.SHUTDOWN)
    assert second is Command.DISABLE_VOLTAGE
    assert path(State.QUICK_STOP_ACTIVE, State.SWITCH_ON_DISABLED) == [Command.DISABLE_VOLTAGE]
    # the driver never takes transition 16 unless the configured 0x605A allows it
    with pytest.raises(ValueError):
        path(State.QUICK_STOP_ACTIVE, State.OPERATION_ENABLED, quick_stop_option=2)
    assert path(State.QUICK_STOP_ACTIVE, State.OPERATION_ENABLED, quick_stop_option=6) == [
        Command.ENABLE_OPERATION]
    with pytest.raises(ValueError, match="no controlword path"):
        path(State.SWITCH_ON_DISABLED, State.FAULT)


def test_modes_table() -> None:
    assert MODES[3] is PROFILE_VELOCITY
    assert PROFILE_VELOCITY.target == 0x60FF
    assert PROFILE_VELOCITY.supported_bit == 0x4  # 0x6502 bit 2


def test_units_by_hand() -> None:
    u = DriveUnits()  # 2^20 counts/rev, 0.001 counts/s, 1 count/s^2
    # 1 deg/s = 2^20 / 360 counts/s = 2912.7111 counts/s = 2912711 units of 0.001 counts/s
    assert u.dps_to_velocity(1.0) == 2912711
    assert u.dps_to_velocity(-400.0) == -1165084444
    assert u.velocity_to_dps(2912711) == pytest.approx(1.0, abs=360 / 2**20 * 1e-3)
    assert u.dps2_to_accel(200.0) == 582542
    assert u.deg_to_counts(90.0) == 2**18
    assert u.counts_to_deg(2**19) == 180.0
    # INTEGER32 0x60FF ends at (2^31 - 1) * 0.001 counts/s = 737.28 deg/s
    assert u.max_velocity_dps == pytest.approx(737.28, abs=1e-3)
    with pytest.raises(ValueError, match="counts_per_rev"):
        DriveUnits(counts_per_rev=0)


def test_int32_wrap_and_unwrap() -> None:
    assert wrap_int32(2**31) == -(2**31)
    assert wrap_int32(-(2**31) - 1) == 2**31 - 1
    assert unwrap_int32(2**31 - 10, -(2**31) + 5) == 15  # across the wrap, forwards
    assert unwrap_int32(-(2**31) + 5, 2**31 - 10) == -15


def test_error_codes_are_described() -> None:
    assert describe_error(0x8611) == "following error"
    assert describe_error(0x4310).startswith("excess temperature")
    assert describe_error(0x3210) == "voltage"  # by its CiA 301 class
