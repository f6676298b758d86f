"""What the stand file's `sim:` block says is true of the stand: each axis's rate errors
and FOG (`AxisTruth`, CONTRACT §2) and the gyro platform (`PlatformTruth`).

Apart from the models that sample them (sims/stand.py, sims/platform.py), and without
numpy at load (each method that needs it imports it): the settings build these from the
stand file, and `bench validate` reads the files without the numerics.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Annotated, Any, Literal

import msgspec
from msgspec import Meta, Struct

from drivers.units import EARTH_RATE_DPH, SECONDS_PER_HOUR
from sims.drive_truth import DriveTruth

if TYPE_CHECKING:
    import numpy as np


def _m(description: str, unit: str = "", **bounds: float) -> Meta:
    """A key's meaning, unit and bounds (ge, gt, le), as the stand schema shows them."""
    kw: dict[str, Any] = {"description": description, **bounds}
    if unit:
        kw["extra"] = {"unit": unit}
    return Meta(**kw)


class Harmonic(Struct, frozen=True, forbid_unknown_fields=True):
    """w_true - w_set = w_set * amplitude_rel * cos(order * phi + phase) (CONTRACT §2)."""

    order: Annotated[int, _m("h: cycles per turn", ge=1)]
    amplitude_rel: Annotated[float, _m("a, relative to the set rate", ge=0)]
    phase_deg: Annotated[float, _m("p, at the zero mark", "deg")] = 0.0


class Mains(Struct, frozen=True, forbid_unknown_fields=True):
    """A tone in time: amplitude_dps * cos(2 pi f t + phase), while the axis turns."""

    frequency_hz: Annotated[float, _m("the ripple's frequency", "Hz", gt=0)] = 50.0
    amplitude_dps: Annotated[float, _m("its amplitude", "deg/s", ge=0)] = 0.0
    phase_deg: Annotated[float, _m("its phase at t = 0", "deg")] = 0.0


class ScaleStep(Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    """A FOG whose scale steps between runs (bench/core/simdrift.py, bench control)."""

    from_run: Annotated[int, _m("the first run with the step", ge=1)]
    rel: Annotated[float, _m("the step, a fraction of the scale")]


class ScaleRamp(Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    """A FOG whose scale creeps from run to run (bench/core/simdrift.py)."""

    from_run: Annotated[int, _m("the first run of the ramp", ge=1)]
    rel_per_run: Annotated[float, _m("the change per run, a fraction of the scale")]


class FogTruth(Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    """The FOG's true response: k * w_true + w0 + drift * t + white noise (CONTRACT §2)."""

    scale: Annotated[float, _m("scale factor M")] = 1.0
    bias_dps: Annotated[float, _m("bias w0", "deg/s")] = 0.0
    misalignment_deg: Annotated[float, _m("sensitive axis to table axis, g", "deg")] = 0.0
    noise_dps: Annotated[float, _m("white noise std per sample", "deg/s")] = 0.0
    bias_drift_dps_per_h: Annotated[float, _m("linear bias drift from the start of the run",
                                              "deg/s/h")] = 0.0
    # a FOG that drifts across runs (bench/core/simdrift.py, bench control)
    scale_step: Annotated[ScaleStep, _m("scale x (1 + rel) from run from_run "
                                        "on")] | None = None
    scale_ramp: Annotated[ScaleRamp, _m("scale x (1 + rel_per_run per run) from run "
                                        "from_run on")] | None = None
    units: Annotated[Literal["deg/s", "rad/s", "deg", "rad"], _m(
        "what the twin carries before the bench configures it (default: delta radians, or "
        "the declared fog.units)")] | None = None

    @property
    def k(self) -> float:
        """docs/method.md A3: k = M cos(g)."""
        return self.scale * math.cos(math.radians(self.misalignment_deg))

    @property
    def w0_dps(self) -> float:
        return self.bias_dps

    def bias_at(self, t_s: np.ndarray | float) -> np.ndarray | float:
        """Bias including its linear drift from the start of the run, deg/s."""
        import numpy as np
        return self.bias_dps + self.bias_drift_dps_per_h * np.asarray(t_s) / SECONDS_PER_HOUR


class CounterTruth(Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    """The counter twin's own errors, unknown to the lab."""

    timebase_offset_rel: Annotated[float, _m(
        "the counter's true time-base offset e, unknown to the lab: every period the twin times is scaled by "
        "1 + e (issue 58)")] = 0.0


class TieTruth(Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    """The FOG sync to counter trigger link as it truly is (drivers/time_tie.py)."""

    latency_s: Annotated[float, _m("true latency (left out: exactly the latency the stand "
                                   "declares)", "s", ge=0)] | None = None
    jitter_s: Annotated[float, _m("its jitter, std", "s", ge=0)] = 0.0


class Serials(Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    """The serial each twin reports (left out: the twin's own)."""

    counter: Annotated[str, _m("the counter twin's *IDN? serial")] | None = None
    drive: Annotated[int, _m("the drive twin's serial number, 0x1018:4",
                             ge=0, le=2**32 - 1)] | None = None


class AxisTruth(Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    """Everything the stand file's `sim.axes.<axis>:` block says is true of one axis,
    declared once: the stand schema reads its keys, units and defaults from here
    (bench/core/config.py), and the twins take the parts whole."""

    rate_bias_rel: Annotated[float, _m("mean table rate = set x (1 + this)")] = 0.0
    harmonics: Annotated[tuple[Harmonic, ...], _m(
        "w_true - w_set = w_set x sum a cos(h phi + p)")] = ()
    mains: Annotated[Mains, _m("a mains-frequency rate ripple")] | None = None
    rate_noise_dps: Annotated[float, _m("white table rate noise while turning, std per FOG "
                                        "sample", "deg/s", ge=0)] = 0.0
    turn_jitter_s: Annotated[float, _m("zero-mark edge timing std", "s", ge=0)] = 0.0
    fog: Annotated[FogTruth, _m("the FOG's truth: k = scale cos(misalignment), w0 = "
                                "bias")] = msgspec.field(default_factory=FogTruth)
    counter_external_reference: Annotated[bool, _m(
        "a valid 10 MHz is wired to the counter's Ext Ref In")] = True
    counter: Annotated[CounterTruth, _m("the counter twin's own errors")] \
        = msgspec.field(default_factory=CounterTruth)
    counter_first_value: Annotated[Literal["from-start", "edge-to-edge"], _m(
        "how the 53230A twin reads its first timestamp value: from the trigger or edge to "
        "edge (the Programmer's Reference's SENSe:TSTamp:RATE example)")] = "from-start"
    time_tie: Annotated[TieTruth, _m("the FOG sync to counter trigger link: true "
                                     "latency and jitter")] \
        = msgspec.field(default_factory=TieTruth)
    serials: Annotated[Serials, _m(
        "the serial each twin reports: the counter's *IDN? serial field, the drive's "
        "identity object 0x1018:4")] = msgspec.field(default_factory=Serials)
    drive: Annotated[DriveTruth, _m(
        "the drive twin's own configuration: its factor group (e.g. rpm, rpm/s), TPDO event "
        "timer, limits and windows (sims/drive_truth.py)")] \
        = msgspec.field(default_factory=DriveTruth)

    @classmethod
    def from_mapping(cls, d: Mapping[str, Any]) -> AxisTruth:
        """Build from a validated `sim.axes.<axis>` mapping of the stand file."""
        return msgspec.convert(d, cls)

    def mean_turn_rate_rel(self) -> float:
        """The per-turn rate's relative deviation from w_set that this truth implies.

        A counter averages over a turn in time: 360 / T with T = integral dphi / w(phi),
        the harmonic mean of w over angle, so harmonics lower it by ~ sum(a^2) / 2.
        """
        import numpy as np
        phi = np.arange(0.0, 360.0, 360.0 / 4096)
        return float(1.0 / np.mean(1.0 / (1.0 + self.shape_rel(phi))) - 1.0)

    def shape_rel(self, phi_deg: np.ndarray) -> np.ndarray:
        """Relative deviation of the rate from w_set at angle phi: bias + harmonics."""
        import numpy as np
        out = np.full(np.shape(phi_deg), self.rate_bias_rel, dtype=float)
        phi_rad = np.radians(phi_deg)
        for h in self.harmonics:
            out += h.amplitude_rel * np.cos(h.order * phi_rad + math.radians(h.phase_deg))
        return out



#: how the twin's gyros are mounted: each horizontal gyro's input axis from the X axis,
#: and which gyros are vertical (the platform as built; the estimator has its own copy
#: of this convention, so a mistake in either shows up as a test failure)
HORIZONTAL_OFFSET_DEG = {"x": 0.0, "y": 90.0}
VERTICAL_GYROS = ("z",)


@dataclass(frozen=True)
class GyroTruth:
    """One gyro of the platform: its drift, torque sensor, angle sensor and error sources."""

    own_drift_dph: float = 0.0
    precession_dps_per_v: float = 0.1      # k_ts * amplifier gain / H
    k_as_v_per_deg: float = 2.0            # command angle sensor's transfer coefficient
    angle_offset_deg: float = 0.0          # alpha0: the sensor's zero is arbitrary
    angle_noise_arcsec: float = 0.0        # per digitizer sample, sensor plus readout
    pulse_mismatch_rel: float = 0.0        # - polarity gain = (1 + this) * + polarity gain
    pulse_jitter_s: float = 0.0            # std of each pulse edge's time (switch, amplifier)
    drift_random_walk_dph_per_rth: float = 0.0

    @classmethod
    def from_mapping(cls, d: Mapping[str, Any]) -> GyroTruth:
        known = cls.__dataclass_fields__
        unknown = set(d) - set(known)
        if unknown:
            raise ValueError(f"unknown gyro truth key(s) {', '.join(sorted(unknown))}; "
                             f"known: {', '.join(known)}")
        return cls(**{k: float(v) for k, v in d.items()})


@dataclass(frozen=True)
class PlatformTruth:
    """The stand file's `sim.platform` block."""

    latitude_deg: float
    azimuth_deg: float                     # X input axis, from north, clockwise from above
    gyros: dict[str, GyroTruth]
    table_axis: str | None = None          # the stand axis the platform sits on
    seed: int = 0

    @classmethod
    def from_mapping(cls, d: Mapping[str, Any], seed: int = 0) -> PlatformTruth:
        gyros = {name: GyroTruth.from_mapping(g or {}) for name, g in d.get("gyros", {}).items()}
        for name in gyros:
            if name not in HORIZONTAL_OFFSET_DEG and name not in VERTICAL_GYROS:
                raise ValueError(f"platform gyro {name!r}: expected x, y (horizontal) or z "
                                 f"(vertical)")
        return cls(latitude_deg=float(d["latitude_deg"]), azimuth_deg=float(d["azimuth_deg"]),
                   gyros=gyros, table_axis=d.get("table_axis"), seed=int(seed))

    @property
    def earth_horizontal_dph(self) -> float:
        """W_h = 15.041 cos(latitude) (docs/method.md B)."""
        return EARTH_RATE_DPH * math.cos(math.radians(self.latitude_deg))

    @property
    def earth_vertical_dph(self) -> float:
        return EARTH_RATE_DPH * math.sin(math.radians(self.latitude_deg))

    def apparent_dph(self, gyro: str, table_deg: float | np.ndarray = 0.0) -> np.ndarray:
        """Earth-rate projection on the gyro's input axis (docs/method.md B convention)."""
        import numpy as np
        if gyro in VERTICAL_GYROS:
            return self.earth_vertical_dph + 0.0 * np.asarray(table_deg)
        heading = self.azimuth_deg + HORIZONTAL_OFFSET_DEG[gyro] + np.asarray(table_deg)
        return self.earth_horizontal_dph * np.cos(np.radians(heading))

    def total_drift_dph(self, gyro: str, table_deg: float = 0.0) -> float:
        """Own plus apparent drift at a turntable angle (the nominal own drift)."""
        return self.gyros[gyro].own_drift_dph + float(self.apparent_dph(gyro, table_deg))
