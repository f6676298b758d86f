"""Pulse cycles straight from the platform twin, as a digitizer in step with the pulses
would record them (no instruments): for the analysis tests."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from procedures.drift_pulse.analysis import CycleRecord, PulseShape
from sims.clock import VirtualClock
from sims.platform import GyroPlatform, GyroTruth, PlatformTruth
from sims.stand import AxisTruth, SimulatedStand, StandTruth

TC_S = 5.0
FS_HZ = 2000.0
N_PRE = 20
TURN_RATE_DPS = 30.0


def paper_truth(seed: int = 3, **errors: float) -> PlatformTruth:
    """The paper's simulation case: latitude 70 deg, azimuth 80 deg (docs/method.md B)."""
    gyro = dict(precession_dps_per_v=0.1, k_as_v_per_deg=2.0, angle_offset_deg=0.3, **errors)
    return PlatformTruth(70.0, 80.0, {"x": GyroTruth(own_drift_dph=0.35, **gyro),
                                      "y": GyroTruth(own_drift_dph=-0.42, **gyro)},
                         table_axis="turntable", seed=seed)


def turn(stand: SimulatedStand, t_s: float, by_deg: float) -> float:
    """Turn the turntable by `by_deg` from t_s (trapezoid, 30 deg/s, 30 deg/s^2); the end."""
    axis = stand.axis("turntable")
    a = v = TURN_RATE_DPS
    d = abs(by_deg)
    t_acc = min(v / a, math.sqrt(d / a))
    t_cruise = max(d - a * t_acc * t_acc, 0.0) / (a * t_acc)
    axis.command_rate(t_s, math.copysign(a * t_acc, by_deg), a)
    axis.profile.command(t_s + t_acc + t_cruise, 0.0, a)
    return t_s + 2 * t_acc + t_cruise


def record_cycles(truth: PlatformTruth, shape: PulseShape, cycles: int = 10,
                  timing_cycles: int = 0, amplitude_v: float = 1.0,
                  timing_amplitude_v: float = 10.0, shift_s: float = 0.0,
                  aperture_s: float = 0.0, positions: tuple[float, ...] = (0.0, 180.0),
                  period_s: float = 11.0
                  ) -> tuple[dict[str, list[CycleRecord]], GyroPlatform]:
    """Every gyro's cycles at each turntable position.

    `shift_s` delays the digitizer's samples against the pulses (a start offset the
    analysis is not told of). Returns the records and the platform (for its truth).
    """
    truth = replace(truth, table_axis="turntable")
    stand = SimulatedStand(StandTruth(truth.seed, {"turntable": AxisTruth()}),
                           {"turntable": 100.0}, VirtualClock(1.0, running=False))
    plat = GyroPlatform(truth, stand)
    dt = 1.0 / FS_HZ
    n = int(round(TC_S * FS_HZ))
    k_samples = np.arange(2 * n + 2 * N_PRE + 1) - N_PRE
    recs: dict[str, list[CycleRecord]] = {g: [] for g in truth.gyros}
    t, at = 1.0, 0.0
    for k, pos in enumerate(positions):
        if pos != at:
            t = turn(stand, t, pos - at) + 1.0
            at = pos
        for i in range(-timing_cycles if k == 0 else 0, cycles):
            volts = shape.pair_points(n) * (timing_amplitude_v if i < 0 else amplitude_v)
            for g in truth.gyros:
                plat.apply_voltage(g, t, dt, volts)
                u = plat.sample_u(g, t + shift_s + k_samples * dt, aperture_s)
                recs[g].append(CycleRecord(u, dt, -N_PRE * dt + aperture_s / 2, TC_S, t, pos,
                                           timing_only=i < 0))
            t += period_s
    return recs, plat
