"""The drive twin's object dictionary: typed access to its canopen LocalNode's data
store, the power-on values the twin's settings give it, and the CiA 402 factor group
(0x608F, 0x6091, 0x6096, 0x6097, 0x60A9, 0x60AA) that sets the units those values are in.

The bottom layer of the drive twin (sims/drive_twin.py): the motion model, the state
machine and the CAN node above it read and write the drive's objects only through it.
"""

from __future__ import annotations

import contextlib
import dataclasses
import threading
from collections.abc import Callable
from typing import Any

import canopen
from canopen.objectdictionary import ODVariable
from canopen.pdo.base import PdoBase, PdoMaps
from canopen.sdo import SdoAbortedError

from drivers.cia402 import (
    NAMED_SI_UNITS,
    UINT32_MAX,
    DriveUnits,
    Od,
    State,
    UnitFactors,
)
from sims.clock import SteppedClock, VirtualClock
from sims.stand import AxisModel

# SDO abort codes (CiA 301) the twin answers with
ABORT_VALUE_RANGE = 0x06090030
ABORT_VALUE_TOO_HIGH = 0x06090031
ABORT_VALUE_TOO_LOW = 0x06090032
ABORT_DEVICE_STATE = 0x08000022

UINT16_MAX = 0xFFFF

#: objects whose value the twin computes when read (SDO or TPDO)
LIVE_OBJECTS = frozenset({Od.STATUSWORD, Od.MODES_OF_OPERATION_DISPLAY, Od.POSITION_ACTUAL,
                   Od.VELOCITY_ACTUAL, Od.ERROR_CODE, Od.ERROR_REGISTER})

#: a deg-based setting of the twin's: (setting name, value in deg/s or deg/s2, the
#: largest value its object holds), by (index, sub), under "velocity" or "accel"
DegValues = dict[str, dict[tuple[int, int], tuple[str, float, int]]]


class DriveObjects:
    """The object dictionary of one drive twin, in the units its factor group sets."""

    axis: str
    model: AxisModel
    clock: VirtualClock | SteppedClock
    #: the unit-dependent objects as deg-based values, refitted when the units change
    _deg_values: DegValues
    _initial: dict[tuple[int, int], int]
    factors: UnitFactors
    units: DriveUnits
    _factors0: UnitFactors
    _tpdo_event_timer_ms: int | None
    _node: canopen.LocalNode | None
    _network: canopen.Network | None
    #: the motion lock: every change of the drive's state and objects is made holding it
    _lock: threading.RLock
    #: the CiA 402 state (sims/drive_state_machine.py): the factor group changes only
    #: while the power stage is off
    _state: State

    def _power_on_values(self, position_window_deg: float, controller_node_id: int,
                         watchdog_s: float, serial_number: int) -> dict[tuple[int, int], int]:
        """The objects the twin's settings give, over the EDS's defaults, at power-on and
        at each reset of their area (_load_defaults)."""
        f = self.factors
        return {
            **self._unit_objects(),
            (Od.GEAR_RATIO, 1): f.gear_motor_revs, (Od.GEAR_RATIO, 2): f.gear_shaft_revs,
            (Od.SI_UNIT_VELOCITY, 0): f.velocity_si,
            (Od.SI_UNIT_ACCELERATION, 0): f.acceleration_si,
            (Od.POSITION_WINDOW, 0): self._fit("position_window_deg", position_window_deg,
                                               self.units.deg_to_counts, UINT32_MAX),
            (Od.POSITION_ENCODER_RESOLUTION, 1): f.encoder_increments,
            (Od.POSITION_ENCODER_RESOLUTION, 2): f.motor_revolutions,
            (Od.CONSUMER_HEARTBEAT, 1): (controller_node_id << 16)
            | self._fit("watchdog_s", watchdog_s, lambda s: round(s * 1000), UINT16_MAX),
            (Od.IDENTITY, 4): serial_number,
        }

    def _unit_objects(self, units: DriveUnits | None = None,
                      saturate: bool = False) -> dict[tuple[int, int], int]:
        """Every velocity and acceleration object in `units` (default: the present ones).
        `saturate`: a value its object cannot hold takes the object's nearest (a change of
        the factor group, see _change_units); otherwise it is the twin's own error."""
        u = self.units if units is None else units
        convert = {"velocity": u.dps_to_velocity, "accel": u.dps2_to_accel}
        if saturate:
            return {key: min(max(convert[kind](value), 0), limit)
                    for kind, table in self._deg_values.items()
                    for key, (name, value, limit) in table.items()}
        return {key: self._fit(name, value, convert[kind], limit)
                for kind, table in self._deg_values.items()
                for key, (name, value, limit) in table.items()}

    #: the factor group's objects -> the UnitFactors field each sub-index sets
    _FACTOR_FIELDS: dict[tuple[int, int], str] = {
        (Od.POSITION_ENCODER_RESOLUTION, 1): "encoder_increments",
        (Od.POSITION_ENCODER_RESOLUTION, 2): "motor_revolutions",
        (Od.GEAR_RATIO, 1): "gear_motor_revs", (Od.GEAR_RATIO, 2): "gear_shaft_revs",
        (Od.SI_UNIT_VELOCITY, 0): "velocity_si", (Od.SI_UNIT_ACCELERATION, 0): "acceleration_si",
        (Od.VELOCITY_FACTOR, 1): "velocity_factor", (Od.VELOCITY_FACTOR, 2): "velocity_factor",
        (Od.ACCELERATION_FACTOR, 1): "acceleration_factor",
        (Od.ACCELERATION_FACTOR, 2): "acceleration_factor",
    }

    def _change_units(self, index: int, sub: int, code: int) -> None:
        """A factor-group object written (0x608F, 0x6091, 0x6096, 0x6097, 0x60A9,
        0x60AA): new units, applied as a drive applies them; the limits keep their meaning
        in deg/s. Refused while the power stage is on (abort 0x08000022), or with a value
        that gives no whole positive number of increments a turn (0x06090030).

        Issue 41: the factor group is consistent at every step. A write is checked whole
        before anything changes (a refused one leaves the twin's units and the OD as they
        were: it used to take the new factors but leave the OD behind, so a gear ratio
        answered with a general error 0x08000000 made the next write of 0x6091, back to
        1:1, fail too, until Reset Node), and a limit its UNSIGNED16/32 object cannot hold
        in the new units (0x606D's 0.02 deg/s at twice the increments) takes the object's
        nearest value: the ratio itself is valid (0x6091: motor revolutions per shaft
        revolutions), and keeping the limits in deg/s is the twin's own rule, not the
        profile's, so it must not refuse a ratio for it."""
        if self._state.power_stage_on:
            raise SdoAbortedError(ABORT_DEVICE_STATE)
        field = self._FACTOR_FIELDS[(index, sub)]
        f = self.factors
        value: Any = code   # a field of UnitFactors: its ratio or a code
        if field in ("velocity_factor", "acceleration_factor"):
            old = getattr(f, field)
            value = (code, old[1]) if sub == 1 else (old[0], code)
        new = dataclasses.replace(f, **{field: value})
        try:
            units = new.drive_units(apply_factors=True)
            if units.counts_per_rev <= 0:
                raise ValueError("no increments")
            values = self._unit_objects(units, saturate=True)
        except (ValueError, ZeroDivisionError, OverflowError) as e:
            raise SdoAbortedError(ABORT_VALUE_RANGE) from e
        self.factors, self.units = new, units      # all at once, once nothing can fail
        for (i, s), v in values.items():
            self._put(i, s, v)

    def _load_defaults(self, first: int, last: int) -> None:
        """Objects first..last back to their power-on values (the EDS's, then the twin's)."""
        node = self._node
        assert node is not None
        for index in [i for i in node.data_store if first <= i <= last]:
            del node.data_store[index]
        if first <= Od.POSITION_ENCODER_RESOLUTION <= last:
            self.factors, self.units = self._factors0, self._factors0.drive_units()
        for (index, sub), value in self._initial.items():
            if first <= index <= last:
                self._put(index, sub, value)
        if first <= 0x1800 <= last and self._tpdo_event_timer_ms is not None:
            for n in range(4):  # e.g. 0: TPDOs only on change
                with contextlib.suppress(KeyError):
                    self._put(0x1800 + n, 5, self._tpdo_event_timer_ms)

    @staticmethod
    def _fit(key: str, value: float, convert: Callable[[float], int], limit: int) -> int:
        units = convert(value)
        if not 0 <= units <= limit:
            raise ValueError(f"drive twin {key} = {value} is {units} drive units, "
                             f"outside its object's range 0..{limit}")
        return units

    def _put(self, index: int, sub: int, value: int) -> None:
        assert self._node is not None
        var = self._odvar(index, sub)
        self._node.data_store.setdefault(index, {})[sub] = var.encode_raw(value)

    def _get(self, index: int, sub: int = 0) -> int:
        assert self._node is not None
        return integer_value(self._odvar(index, sub), self._node.get_data(index, sub))

    def _odvar(self, index: int, sub: int) -> ODVariable:
        assert self._node is not None
        obj = self._node.object_dictionary[index]
        return obj if isinstance(obj, ODVariable) else obj[sub]


def pdo_maps(pdos: PdoBase) -> PdoMaps:
    """A node's TPDO or RPDO maps: canopen types PdoBase.map Optional, TPDO and RPDO set it."""
    assert pdos.map is not None
    return pdos.map


def si_unit_code(unit: str | int) -> int:
    """An SI unit object's value: a name of cia402.NAMED_SI_UNITS, or the code itself."""
    return unit if isinstance(unit, int) else NAMED_SI_UNITS[unit]


def integer_value(var: ODVariable, data: bytes) -> int:
    """An object's value: every object of the twin's dictionary is an integer (its EDS,
    drivers/profiles), so anything else is a dictionary the twin was not built for."""
    value = var.decode_raw(data)
    if not isinstance(value, int):
        raise TypeError(f"drive twin: object 0x{var.index:04X}.{var.subindex} holds "
                        f"{value!r}, not an integer")
    return value
