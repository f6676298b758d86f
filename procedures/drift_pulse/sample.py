"""A hand-made drift-pulse result.json that follows CONTRACT §3: two horizontal axes at
latitude 70 deg, azimuth 80 deg (the paper's case), for previews
(`python -m bench.app.certificate.sample OUT_DIR`) and tests derived by hand.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from bench.core import rundir_layout as layout


def drift_pulse_result() -> dict[str, Any]:
    """Two horizontal axes at latitude 70 deg, azimuth 80 deg (the paper's case)."""
    wh = 15.041 * math.cos(math.radians(70.0))
    app = {"x": wh * math.cos(math.radians(80.0)), "y": -wh * math.sin(math.radians(80.0))}
    own = {"x": 0.0523, "y": -0.0311}
    axes: dict[str, Any] = {}
    for name in ("x", "y"):
        cycles, positions = [], []
        for pos in (0.0, 180.0):
            w = [own[name] + (app[name] if pos == 0 else -app[name])
                 + 0.004 * math.sin(1.7 * i + (0 if name == "x" else 1) + pos / 90)
                 for i in range(4)]
            cycles += [{"drift_dph": x, "drift_nominal_dph": x + 0.0011, "table_deg": pos}
                       for x in w]
            positions.append({"table_deg": pos, "cycles": 4, "mean_dph": float(np.mean(w)),
                              "std_dph": float(np.std(w, ddof=1)),
                              "mean_ustd_dph": float(np.std(w, ddof=1)) / 2.0, "dof": 3,
                              "drifts_dph": w})
        axes[name] = {"own_dph": own[name], "own_u_dph": 0.0031,
                      "apparent_dph": app[name], "apparent_u_dph": 0.0042,
                      "own_nominal_edges_dph": own[name] + 0.0011,
                      "start_offset": {"offset_s": 2.5e-4, "offset_u_s": 1.0e-5,
                                       "offset_samples": 0.5, "detected": True},
                      "positions": positions, "cycles": cycles}
    t = np.linspace(0.0, 10.0, 201)
    tc = 5.0
    alpha = np.where(t <= tc, 0.5 * t, 0.5 * (2 * tc - t))  # deg, rectangular pulses
    u_v = 0.2 * alpha
    sign = np.where(t <= tc, 1.0, -1.0)
    integ = np.concatenate([[0.0], np.cumsum(0.5 * (u_v[1:] * sign[1:] + u_v[:-1] * sign[:-1])
                                             * np.diff(t))])
    axes["x"]["example_cycle"] = {"t_s": t.tolist(), "u_v": u_v.tolist(),
                                  "integral_vs": integ.tolist(), "tc_s": tc}
    return {
        "schema": "bench.result/1",
        "procedure": "drift-pulse",
        "verdict": "pass",
        "title": "Platform drift and azimuth, demo (simulated platform)",
        "procedure_file": {"name": "drift-demo.yaml", "sha256": "ef" * 32},
        "stand": {"maker": "Simulated Platforms Ltd", "model": "GSP-3 gyro platform",
                  "serial": "SIM-P-01", "file": "sim-platform.yaml", "sha256": "12" * 32},
        "instruments": {"x": {"generator": "Keysight Technologies,33522B,MY5200,5.02",
                              "digitizer": "Keysight Technologies,34465A,MY5900,A.03"}},
        "dates": {"started_utc": "2025-03-05T09:00:00.000+00:00",
                  "completed_utc": "2025-03-05T09:03:10.000+00:00"},
        "conditions": {"latitude_deg": 70.0},
        "certificate": {"laboratory": "Rate Table Metrology Lab (demo)"},
        "decision_rule": "simple",
        "method": {"pulse_shape": "rectangular", "tc_s": 5.0, "amplitude_dps": 0.5,
                   "cycles": 4, "positions_deg": [0, 180], "sample_rate_hz": 2000},
        "raw_files": [{"path": layout.raw_relpath(1, "x-digitizer.jsonl"), "sha256": "34" * 32,
                       "bytes": 800_000}],
        "sessions": 1,
        "aborted": False,
        "drift": {"latitude_deg": 70.0, "azimuth_deg": 80.02, "azimuth_u_deg": 0.031,
                  "earth_horizontal_dph": wh + 0.002, "earth_horizontal_u_dph": 0.0045,
                  "earth_horizontal_expected_dph": wh, "earth_horizontal_consistent": True,
                  "axes": axes},
        "checks": [],
    }
