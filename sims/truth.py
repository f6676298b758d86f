"""What the stand file's `sim:` block says is true of the stand: each axis's rate errors
and FOG (`AxisTruth`, CONTRACT §2) and the gyro platform (`PlatformTruth`).

Apart from the models that sample them (sims/stand.py, sims/platform.py), and without
numpy at load (each method that needs it imports it): the settings build these from the
stand file, and `bench validate` reads the files without the numerics.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from drivers.units import EARTH_RATE_DPH, SECONDS_PER_HOUR

if TYPE_CHECKING:
    import numpy as np


@dataclass(frozen=True)
class Harmonic:
    """w_true - w_set = w_set * amplitude_rel * cos(order * phi + phase) (CONTRACT §2)."""

    order: int
    amplitude_rel: float
    phase_deg: float = 0.0


@dataclass(frozen=True)
class Mains:
    """A tone in time: amplitude_dps * cos(2 pi f t + phase), while the axis turns."""

    frequency_hz: float = 50.0
    amplitude_dps: float = 0.0
    phase_deg: float = 0.0


@dataclass(frozen=True)
class FogTruth:
    """The FOG's true response: k * w_true + w0 + drift * t + white noise (CONTRACT §2)."""

    scale: float = 1.0
    bias_dps: float = 0.0
    misalignment_deg: float = 0.0
    noise_dps: float = 0.0
    bias_drift_dps_per_h: float = 0.0

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


@dataclass(frozen=True)
class AxisTruth:
    """Everything the `sim:` block says about one axis."""

    rate_bias_rel: float = 0.0
    harmonics: tuple[Harmonic, ...] = ()
    mains: Mains | None = None
    rate_noise_dps: float = 0.0
    turn_jitter_s: float = 0.0
    fog: FogTruth = field(default_factory=FogTruth)

    @classmethod
    def from_mapping(cls, d: Mapping[str, Any]) -> AxisTruth:
        """Build from a validated `sim.axes.<axis>` mapping of the stand file."""
        mains = d.get("mains")
        return cls(
            rate_bias_rel=float(d.get("rate_bias_rel", 0.0)),
            harmonics=tuple(Harmonic(**h) for h in d.get("harmonics", ())),
            mains=Mains(**mains) if mains else None,
            rate_noise_dps=float(d.get("rate_noise_dps", 0.0)),
            turn_jitter_s=float(d.get("turn_jitter_s", 0.0)),
            # `fog.units` is the FOG twin's (what it carries before configuration)
            fog=FogTruth(**{k: v for k, v in d.get("fog", {}).items() if k != "units"}),
        )

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
