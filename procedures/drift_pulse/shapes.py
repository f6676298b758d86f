"""The drift-pulse procedure's pulse shapes: the unit precession rate g(u) of one pulse and
its angle G(u), for the pair's waveform (the generator), the fit (analysis.py) and the
settings' checks (settings.py: the shape's name and its angle G(1)).

Apart from the analysis, and without numpy at load (each method that computes imports
it): `bench validate` checks a procedure file's pulse against these without the fits.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import numpy as np


@dataclass(frozen=True)
class PulseShape:
    """A pulse's unit precession-rate shape g(u) on u = t / Tc in [0, 1], peak 1.

    The pair is +g over [0, Tc] then -g over [Tc, 2 Tc]; G(u) = int_0^u g is its angle.
    """

    name: str
    rate_fn: Callable[[np.ndarray], np.ndarray]
    angle_fn: Callable[[np.ndarray], np.ndarray]
    angle_end: float             # G(1)
    angle_mean: float            # int_0^1 G du

    @property
    def control_coeff(self) -> float:
        """c_shape = 2 int_0^1 G du - G(1): the control term per a Tc^2 (docs/method.md B)."""
        return 2.0 * self.angle_mean - self.angle_end

    @property
    def symmetric(self) -> bool:
        return abs(self.control_coeff) < 1e-12

    def rate(self, u: np.ndarray) -> np.ndarray:
        import numpy as np

        u = np.asarray(u, dtype=float)
        return np.where((u >= 0) & (u < 1), self.rate_fn(np.clip(u, 0, 1)), 0.0)

    def angle(self, u: np.ndarray) -> np.ndarray:
        import numpy as np

        u = np.asarray(u, dtype=float)
        return np.where(u <= 0, 0.0, np.where(u >= 1, self.angle_end,
                                              self.angle_fn(np.clip(u, 0, 1))))

    def pair_rate(self, t_s: np.ndarray, tc_s: float) -> np.ndarray:
        """Precession rate of the unit pair (peak 1) at t from the first edge."""
        import numpy as np

        u = np.asarray(t_s, dtype=float) / tc_s
        rate: np.ndarray = self.rate(u) - self.rate(u - 1.0)
        return rate

    def pair_angle(self, t_s: np.ndarray, tc_s: float) -> np.ndarray:
        """Angle of the unit pair (deg per deg/s of amplitude) at t from the first edge."""
        import numpy as np

        u = np.asarray(t_s, dtype=float) / tc_s
        angle: np.ndarray = tc_s * (self.angle(u) - self.angle(u - 1.0))
        return angle

    def pair_points(self, n_per_pulse: int) -> np.ndarray:
        """The pair for an arbitrary waveform generator, in [-1, 1], 2 n points.

        Sampled at the middle of each hold step: a zero-order hold of these points is
        then as symmetric in time as the shape (sampling at the step's start would
        delay it by half a step and leave a control residue).
        """
        if n_per_pulse < 1:
            raise ValueError(f"n_per_pulse must be >= 1, got {n_per_pulse}")
        import numpy as np

        g = self.rate((np.arange(n_per_pulse) + 0.5) / n_per_pulse)
        return np.concatenate((g, -g))


def _rect_rate(u: np.ndarray) -> np.ndarray:
    import numpy as np

    return np.ones_like(u)


def _tri_rate(u: np.ndarray) -> np.ndarray:
    import numpy as np

    return 1.0 - np.abs(2.0 * u - 1.0)


def _tri_angle(u: np.ndarray) -> np.ndarray:
    import numpy as np

    angle: np.ndarray = np.where(u <= 0.5, u * u, 2.0 * u - u * u - 0.5)
    return angle


SHAPES: dict[str, PulseShape] = {
    "rectangular": PulseShape("rectangular", _rect_rate, lambda u: u,
                              1.0, 0.5),
    "triangular": PulseShape("triangular", _tri_rate, _tri_angle,
                             0.5, 0.25),
    # not symmetric in time: shows the control term at work (c_shape = -1/6)
    "sawtooth": PulseShape("sawtooth", lambda u: u, lambda u: 0.5 * u * u, 0.5, 1.0 / 6.0),
}


def pulse_shape(name: str) -> PulseShape:
    try:
        return SHAPES[name]
    except KeyError:
        raise ValueError(f"unknown pulse shape {name!r}; known: {', '.join(SHAPES)}") from None
