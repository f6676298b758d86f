"""The drift kind's instrument corrections (issue 58): a DMM's gain and offset, the pulse
generator's amplitude, as the run folder's corrections file states them.

Why a file in the run folder, never the register: the analysis of a run is a function of
the run folder alone (`bench analyze` recomputes everything from it); a correction the
lab decides to apply (`bench impact` writes one from an item's as-found error, in a copy
of the folder) is data beside the raw captures, stated in result.json and carried as a
budget row with its own uncertainty. A folder without the file is analysed as measured,
to the byte.

The file (shared with the rate ladder's counter correction):

    {"corrections": [{"where": "platform.gyros.x.dmm", "quantity": "gain_error_rel",
                      "value": g, "U": U(g)}, ...]}

`where` is the item's place in the stand file: `platform.gyros.<gyro>.dmm` (quantities
`gain_error_rel`, the DMM reads (1 + g) U + o, and `offset_error_v`, o) or `platform.awg`
(`amplitude_error_rel` a: every output x (1 + a)). `U` is the correction's expanded
uncertainty (its calibration certificate's, k = 2): u = U / 2. Where each enters:
docs/method.md B, "The drift kind's instrument corrections".
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from drivers.json_types import JsonValue
from procedures.drift_pulse.codec import corrections_file

#: the run folder's corrections file (as procedures/rate_ladder/analysis.py reads it)
CORRECTIONS = "corrections.json"
#: the coverage factor of a correction's stated U (a calibration certificate's, k = 2)
CORRECTION_U_COVERAGE = 2.0

DMM_QUANTITIES = ("gain_error_rel", "offset_error_v")
AWG_QUANTITIES = ("amplitude_error_rel",)


@dataclass(frozen=True)
class Correction:
    """One applied correction: the item's place, the quantity, its value and standard
    uncertainty (the file's U / 2; 0 when it states none)."""

    where: str
    quantity: str
    value: float
    ustd: float
    serial: str | None = None


@dataclass(frozen=True)
class DriftCorrections:
    """The corrections a drift run folder states: each gyro's DMM's, the generator's."""

    dmm: Mapping[str, Mapping[str, Correction]] = field(default_factory=dict)
    awg: Mapping[str, Correction] = field(default_factory=dict)
    stated: tuple[JsonValue, ...] = ()       # the file's entries as written (result.json)

    def __bool__(self) -> bool:
        return bool(self.dmm or self.awg)

    def gain_rel(self, gyro: str) -> float:
        c = self.dmm.get(gyro, {}).get("gain_error_rel")
        return c.value if c else 0.0

    def offset_v(self, gyro: str) -> float:
        c = self.dmm.get(gyro, {}).get("offset_error_v")
        return c.value if c else 0.0

    def of_gyro(self, gyro: str) -> tuple[Correction, ...]:
        """The corrections that act on this gyro's figures: its DMM's and the generator's
        (which drives every gyro's torque sensor)."""
        return (*self.dmm.get(gyro, {}).values(), *self.awg.values())

    def readings(self, gyro: str, u_v: np.ndarray) -> np.ndarray:
        """The angle-sensor voltages from this gyro's DMM readings: U = (reading - o) /
        (1 + g) (docs/method.md B, "The drift kind's instrument corrections"). Without a
        correction of this DMM the readings are returned untouched, to the bit."""
        g, o = self.gain_rel(gyro), self.offset_v(gyro)
        if gyro not in self.dmm:
            return u_v
        return (np.asarray(u_v, dtype=float) - o) / (1.0 + g)


def read_corrections(run_path: Path) -> DriftCorrections:
    """The drift corrections the run folder's corrections file states; none without one.
    A malformed entry for the drift kind's items raises, naming the file and the key: a
    correction is never half applied. Entries for other items (a counter) are left to
    the kind they belong to."""
    path = Path(run_path) / CORRECTIONS
    if not path.is_file():
        return DriftCorrections()
    dmm: dict[str, dict[str, Correction]] = {}
    awg: dict[str, Correction] = {}
    stated: list[JsonValue] = []
    for i, (c, written) in enumerate(corrections_file(path)):
        parts = c.where.split(".")
        is_dmm = len(parts) == 4 and parts[:2] == ["platform", "gyros"] and parts[3] == "dmm"
        if not (is_dmm or c.where == "platform.awg"):
            continue
        allowed = DMM_QUANTITIES if is_dmm else AWG_QUANTITIES
        if c.quantity not in allowed:
            raise ValueError(f"{path}: corrections[{i}].quantity: {c.where} takes "
                             f"{', '.join(allowed)}, got {c.quantity!r}")
        if not math.isfinite(c.value) or (c.quantity == "gain_error_rel" and c.value <= -1.0):
            want = "a gain error above -1" if math.isfinite(c.value) else "a finite number"
            raise ValueError(f"{path}: corrections[{i}].value: {want}, got {c.value!r}")
        corr = Correction(c.where, c.quantity, c.value,
                          0.0 if c.U is None else c.U / CORRECTION_U_COVERAGE,
                          str(c.serial) if c.serial else None)
        if is_dmm:
            dmm.setdefault(parts[2], {})[c.quantity] = corr
        else:
            awg[c.quantity] = corr
        stated.append(written)
    return DriftCorrections(dmm, awg, tuple(stated))
