"""A fast simulated stand with one turning axis, for the counter's driver-to-twin tests.

VirtualClock(speed=200) and 360 deg/s: one turn is 1 virtual second, 5 ms real, so a
test times a handful of turns in well under a second. The axis carries the paper's
once-per-rev harmonic, a rate bias and the slot sensor's 27 ns edge jitter, so the
periods the twin reports differ from turn to turn and from 360/w_set: a driver that
returned nominal or shuffled values would fail the comparison with the stand's truth.
"""

from __future__ import annotations

import numpy as np

from drivers.counter_settings import CounterSettings
from sims.clock import VirtualClock
from sims.stand import AxisTruth, Harmonic, SimulatedStand, StandTruth

SPEED = 200.0
RATE_DPS = 360.0
PERIOD_S = 360.0 / RATE_DPS
AXIS = "outer"


def turning_stand(seed: int = 7, rate_dps: float = RATE_DPS) -> SimulatedStand:
    truth = StandTruth(seed=seed, axes={AXIS: AxisTruth(
        rate_bias_rel=2e-5,
        harmonics=(Harmonic(1, 8.6e-4, 40.0),),
        turn_jitter_s=27e-9,
    )})
    stand = SimulatedStand(truth, {AXIS: 200.0}, VirtualClock(SPEED))
    stand.axes[AXIS].command_rate(0.0, rate_dps, 1e6)
    return stand


def counter_block(model: str = "keysight-53230a") -> CounterSettings:
    """A stand's `counter:` block for a twin of `model` (its resource is the twin's own,
    given when it starts)."""
    return CounterSettings(resource="", model=model)


def truth_edges(stand: SimulatedStand, t_from_s: float, t_to_s: float) -> np.ndarray:
    """The stand's zero-mark edge times (with jitter, before any counter) in [from, to)."""
    axis = stand.axes[AXIS]
    axis.advance_to(stand.clock.now())
    return axis.zero_marks(t_from_s, t_to_s).t_edge_s
