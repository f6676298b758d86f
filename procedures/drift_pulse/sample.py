"""A hand-made drift-pulse result.json that follows CONTRACT §3: two horizontal axes at
latitude 70 deg, azimuth 80 deg (the paper's case), for previews
(`python -m bench.app.certificate.sample OUT_DIR`) and tests derived by hand.
"""

from __future__ import annotations

import math

import numpy as np

from bench.core import rundir_layout as layout
from bench.report.sample_result import (
    DatesStated,
    FileStated,
    RawFileStated,
    SampleResult,
    StandStated,
)
from procedures.drift_pulse.result import (
    AxisFigures,
    CycleFigures,
    DriftCheck,
    DriftFigures,
    ExampleCycle,
    PositionFigures,
    StartOffsetFigures,
)

#: the sample's command angle sensor scale (V/deg), pulse duration Tc (s), precession (deg/s)
K_AS_V_PER_DEG = 0.2
TC_S = 5.0
AMPLITUDE_DPS = 0.5


def _example() -> ExampleCycle:
    """U(t) and the signed integral of one rectangular pulse pair (docs/method.md B)."""
    t = np.linspace(0.0, 10.0, 201)
    alpha = np.where(t <= TC_S, AMPLITUDE_DPS * t, AMPLITUDE_DPS * (2 * TC_S - t))  # deg
    u_v = K_AS_V_PER_DEG * alpha
    sign = np.where(t <= TC_S, 1.0, -1.0)
    integ = np.concatenate([[0.0], np.cumsum(0.5 * (u_v[1:] * sign[1:] + u_v[:-1] * sign[:-1])
                                             * np.diff(t))])
    return ExampleCycle(t_s=tuple(t.tolist()), u_v=tuple(u_v.tolist()),
                        integral_vs=tuple(integ.tolist()), tc_s=TC_S,
                        note="time from the first pulse edge (where the fit puts it)")


def drift_figures() -> DriftFigures:
    """Two horizontal axes at latitude 70 deg, azimuth 80 deg (the paper's case), 4 cycles per
    position, no budgets (the certificate then says U is as result.json states it)."""
    wh = 15.041 * math.cos(math.radians(70.0))
    app = {"x": wh * math.cos(math.radians(80.0)), "y": -wh * math.sin(math.radians(80.0))}
    own = {"x": 0.0523, "y": -0.0311}
    axes = {}
    for name in ("x", "y"):
        cycles: list[CycleFigures] = []
        positions = []
        for k, pos in enumerate((0.0, 180.0)):
            w = [own[name] + (app[name] if pos == 0 else -app[name])
                 + 0.004 * math.sin(1.7 * i + (0 if name == "x" else 1) + pos / 90)
                 for i in range(4)]
            # w = -U_int / (k_as Tc^2) (docs/method.md B), so U_int = -w k_as Tc^2
            cycles += [CycleFigures(drift_dph=x, drift_nominal_dph=x + 0.0011,
                                    u_int_vs=(u_int := -x / 3600.0 * K_AS_V_PER_DEG * TC_S ** 2),
                                    ustd_int_vs=u_int, amplitude_dps=AMPLITUDE_DPS,
                                    offset_s=2.5e-4, offset_u_s=1.0e-5, offset_ustd_s=1.0e-5,
                                    residual_rms_v=2.0e-5, t_start_s=12.0 * (4 * k + i),
                                    table_deg=pos) for i, x in enumerate(w)]
            std = float(np.std(w, ddof=1))
            positions.append(PositionFigures(table_deg=pos, cycles=4, mean_dph=float(np.mean(w)),
                                             std_dph=std, mean_ustd_dph=std / 2.0, dof=3,
                                             drifts_dph=tuple(w)))
        axes[name] = AxisFigures(
            own_dph=own[name], own_u_dph=0.0031, own_U_dph=0.0031, apparent_dph=app[name],
            apparent_u_dph=0.0042, apparent_U_dph=0.0042,
            own_nominal_edges_dph=own[name] + 0.0011,
            apparent_nominal_edges_dph=app[name] + 0.0011, amplitude_dps=AMPLITUDE_DPS,
            vertical=False,
            start_offset=StartOffsetFigures(offset_s=2.5e-4, offset_u_s=1.0e-5,
                                            offset_U_s=1.0e-5, offset_samples=0.5,
                                            detected=True, cycles=8),
            budgets=(), positions=tuple(positions), cycles=tuple(cycles),
            example_cycle=_example() if name == "x" else None)
    return DriftFigures(axes=axes, latitude_deg=70.0, earth_horizontal_expected_dph=wh,
                        azimuth_deg=80.02, azimuth_u_deg=0.031, azimuth_U_deg=0.031,
                        earth_horizontal_dph=wh + 0.002, earth_horizontal_u_dph=0.0045,
                        earth_horizontal_U_dph=0.0045, earth_horizontal_consistent=True)


class DriftSample(SampleResult, frozen=True, kw_only=True):
    """A drift-pulse result by hand: the frame, the kind's figures, its checks (none)."""

    drift: DriftFigures
    checks: tuple[DriftCheck, ...] = ()


def drift_pulse_result() -> DriftSample:
    """A whole result.json around `drift_figures`, for previews of the certificate."""
    return DriftSample(
        procedure="drift-pulse", verdict="pass",
        title="Platform drift and azimuth, demo (simulated platform)",
        procedure_file=FileStated("drift-demo.yaml", "ef" * 32),
        stand=StandStated(maker="Simulated Platforms Ltd", model="GSP-3 gyro platform",
                          serial="SIM-P-01", file="sim-platform.yaml", sha256="12" * 32),
        instruments={"x": {"generator": "Keysight Technologies,33522B,MY5200,5.02",
                           "digitizer": "Keysight Technologies,34465A,MY5900,A.03"}},
        dates=DatesStated("2025-03-05T09:00:00.000+00:00", "2025-03-05T09:03:10.000+00:00"),
        conditions={"latitude_deg": 70.0},
        certificate={"laboratory": "Rate Table Metrology Lab (demo)"},
        decision_rule="simple",
        method={"pulse_shape": "rectangular", "tc_s": 5.0, "amplitude_dps": 0.5,
                "cycles": 4, "positions_deg": [0, 180], "sample_rate_hz": 2000},
        raw_files=(RawFileStated(layout.raw_relpath(1, "x-digitizer.jsonl"), "34" * 32,
                                 800_000),),
        sessions=1, drift=drift_figures())
