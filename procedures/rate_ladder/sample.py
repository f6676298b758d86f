"""A hand-made rate-ladder result.json that follows CONTRACT §3 and the engine's extra keys.

It lets the certificate be previewed (`python -m bench.app.certificate.sample OUT_DIR`) and
tested with values whose printed form is derived by hand. The numbers are chosen to
exercise every branch of the rendering: a pass, a value out of tolerance, one inside the
tolerance but within U of it (guard band), a check that misses the RMG 63-2003
capability rule, and harmonics that are and are not significant.
"""

from __future__ import annotations

import math

import numpy as np

from bench.core import rundir_layout as layout
from drivers.json_types import JsonObject, JsonValue


def _rate(set_dps: float, turns: int, err: float, err_u: float, inst: float, inst_u: float,
          raw: float, corr: float, verdict: str, harmonics: list[JsonValue],
          mains_dps: float, over: tuple[float, float, float],
          binned: JsonObject | None = None) -> JsonObject:
    mean = set_dps * (1 + err)
    spread = np.array([1.0, -1.0, -0.5, 0.5, 0.2, -0.2][:turns])
    spread = spread / spread.std(ddof=1) if turns > 1 else spread
    rates = mean + abs(mean) * inst * spread
    return {
        "set_rate_dps": set_dps,
        "turns": turns,
        "counter_rate_dps": [float(r) for r in rates],
        "mean_rate_dps": mean,
        "rate_error_rel": err,
        "rate_error_u_rel": err_u,
        "rate_instability_rel": inst,
        "rate_instability_u_rel": inst_u,
        "rate_instability_floor_rel": 1.0e-9 * abs(set_dps),
        "rate_error_budget": {   # bench.analysis.turns.TurnsResult.to_dict()
            "timing_u_rel": 3.8e-10 * abs(set_dps) / 10, "timebase_u_rel": 5.8e-10,
            "repeatability_u_rel": err_u / 2, "coverage_factor": 2.0,
            "timestamp_u_s": 2e-11, "trigger_jitter_s": 2.7e-08, "timebase_limit_rel": 1e-09},
        "intra_turn_instability_rel": raw,
        "intra_turn_instability_corrected_rel": corr,
        "intra_turn": {   # bench.analysis.random_part.RandomPartResult.to_dict()
            "instability_rel": raw, "floor_rel": math.sqrt(raw * raw - corr * corr),
            "floor_source": "static record (Allan deviation)", "corrected_rel": corr,
            "corrected_upper_rel": corr * 1.25, "resolved": True, "bandwidth_hz": 1000.0,
            "std_dps": raw * abs(set_dps), "samples": 144_000,
            "averaged": [
                {"angle_deg": a, "instability_rel": v, "floor_rel": v * 0.5,
                 "corrected_rel": v * math.sqrt(0.75), "blocks": n, "samples_per_block": 1.0}
                for a, v, n in zip((1.0, 10.0, 360.0), over, (1440, 144, 4), strict=True)],
        },
        "systematic": {
            "harmonics": harmonics,
            "mains": {"frequency_hz": 50.0, "amplitude_dps": mains_dps,
                      "amplitude_u_dps": 3.0e-5, "phase_deg": 12.0, "phase_u_deg": 9.0,
                      "detected": True},
            **({} if binned is None else {"binned": binned}),
        },
        "verdict": verdict,
    }


def _outer_harmonics(sign: float) -> list[JsonValue]:
    return [
        {"order": 1, "amplitude_rel": 8.6e-4, "amplitude_u_rel": 1.23e-5,
         "phase_deg": 40.3 if sign > 0 else -139.6, "phase_u_deg": 0.84, "detected": True},
        {"order": 2, "amplitude_rel": 1.5e-4, "amplitude_u_rel": 1.1e-5,
         "phase_deg": -69.0, "phase_u_deg": 4.2, "detected": True},
        {"order": 3, "amplitude_rel": 3.0e-6, "amplitude_u_rel": 1.1e-5,
         "phase_deg": 17.0, "phase_u_deg": 180.0, "detected": False},
    ]


def _binned(set_dps: float) -> JsonObject:
    """The paper's binned average by angle: the fitted model plus a deterministic ripple."""
    phi = np.arange(0.0, 360.0, 5.0) + 2.5
    r = np.radians(phi)
    model = 8.6e-4 * np.cos(r + math.radians(40.3)) + 1.5e-4 * np.cos(2 * r - math.radians(69))
    ripple = 2.0e-5 * np.sin(7.3 * r + 0.4)
    return {"bin_deg": 5.0, "centres_deg": phi.tolist(),
            "deviation_rel": (model + ripple).tolist(), "u_rel": [3.0e-5] * phi.size,
            "peak_to_peak_rel": float(np.ptp(model + ripple))}


def _rates() -> tuple[list[JsonValue], list[JsonValue]]:
    """(outer, inner): outer at +/-10 and +/-50 deg/s, failing its tolerance at 50 with
    the paper's binned average there; inner at +/-20 deg/s with one harmonic."""
    h_in: list[JsonValue] = [{"order": 1, "amplitude_rel": 2.0e-4, "amplitude_u_rel": 2.4e-5,
             "phase_deg": 120.0, "phase_u_deg": 7.0, "detected": True}]
    outer: list[JsonValue] = [
        _rate(10.0, 4, 3.04e-7, 1.23e-7, 2.6e-8, 2.2e-8, 1.06e-3, 1.2e-5, "pass",
              _outer_harmonics(1), 2.0e-4, (2.1e-4, 3.3e-5, 1.1e-6)),
        _rate(-10.0, 4, -2.1e-7, 1.2e-7, 3.1e-8, 2.6e-8, 1.04e-3, 1.3e-5, "pass",
              _outer_harmonics(-1), 1.9e-4, (2.0e-4, 3.1e-5, 1.0e-6)),
        _rate(50.0, 4, 1.42e-6, 1.1e-7, 4.4e-8, 3.7e-8, 2.15e-4, 1.05e-5, "fail",
              _outer_harmonics(1), 2.1e-4, (4.4e-5, 6.6e-6, 2.4e-7), _binned(50.0)),
        _rate(-50.0, 4, 9.5e-7, 1.0e-7, 2.0e-8, 1.7e-8, 2.11e-4, 1.0e-5, "fail",
              _outer_harmonics(-1), 2.0e-4, (4.3e-5, 6.5e-6, 2.2e-7)),
    ]
    inner: list[JsonValue] = [
        _rate(20.0, 4, 1.8e-7, 1.5e-7, 1.9e-8, 1.6e-8, 5.3e-4, 6.0e-6, "pass",
              h_in, 1.0e-4, (1.0e-4, 1.6e-5, 5.0e-7)),
        _rate(-20.0, 4, -1.0e-7, 3.5e-7, 2.2e-8, 1.9e-8, 5.2e-4, 6.1e-6, "pass",
              h_in, 1.1e-4, (1.0e-4, 1.5e-5, 5.1e-7)),
    ]
    return outer, inner


def _pairs() -> tuple[list[JsonValue], list[JsonValue]]:
    """(outer, inner): each pair's k and w0 with U, the bias drift fitted out."""
    drift: JsonObject = {"method": "lsq-drift", "drift_source": "the three halves (+, -, +)"}
    pairs_outer: list[JsonValue] = [
        {"rate_dps": 10.0, "k": 1.000299, "k_u": 2.34e-6, "w0_dps": 0.002013,
         "w0_u_dps": 1.17e-4, "drift_dps_per_h": 0.00104, "drift_u_dps_per_h": 0.00031,
         **drift},
        {"rate_dps": 50.0, "k": 1.0002934, "k_u": 4.6e-7, "w0_dps": 0.002051,
         "w0_u_dps": 1.2e-4, "drift_dps_per_h": 0.00097, "drift_u_dps_per_h": 0.00029,
         **drift},
    ]
    pairs_inner: list[JsonValue] = [{"rate_dps": 20.0, "k": 0.9994985, "k_u": 1.2e-6, "w0_dps": -0.002994,
                    "w0_u_dps": 1.2e-4, "drift_dps_per_h": 0.00201,
                    "drift_u_dps_per_h": 0.00030, **drift}]
    return pairs_outer, pairs_inner


def _checks() -> list[JsonValue]:
    """The rate error per rate under the guard-band rule (each of its three outcomes),
    and one instability check."""
    def check(axis: str, rate: float, value: float, u: float, verdict: str, reason: str,
              quantity: str = "rate_error", tol: float = 1.0e-6) -> JsonValue:
        return {"axis": axis, "set_rate_dps": rate, "quantity": quantity,
                "value_rel": value, "u_rel": u, "tolerance_rel": tol, "verdict": verdict,
                "rule": "guard-band", "reason": reason, "capability_ratio": u / tol,
                "capability_ok": u / tol <= 0.3}

    checks: list[JsonValue] = [
        check("outer", 10.0, 3.04e-7, 1.23e-7, "pass", "|δ| + U ≤ T"),
        check("outer", -10.0, -2.1e-7, 1.2e-7, "pass", "|δ| + U ≤ T"),
        check("outer", 50.0, 1.42e-6, 1.1e-7, "fail", "|δ| > T: out of tolerance"),
        check("outer", -50.0, 9.5e-7, 1.0e-7, "fail",
              "|δ| ≤ T but |δ| + U > T: within U of the limit (guard band)"),
        check("inner", 20.0, 1.8e-7, 1.5e-7, "pass", "|δ| + U ≤ T"),
        check("inner", -20.0, -1.0e-7, 3.5e-7, "pass", "|δ| + U ≤ T"),
        check("outer", 10.0, 2.6e-8, 2.2e-8, "pass", "σ + U ≤ T", "rate_instability", 1e-5),
    ]
    return checks


def _raw_files() -> list[JsonValue]:
    """The raw files of one session, each hashed."""
    files = [(layout.raw_relpath(1, name), size) for name, size in (
        (layout.fog_capture("outer"), 4_321_000), (layout.counter_log("outer"), 18_211),
        (layout.drive_log("outer"), 120_554), (layout.fog_capture("inner"), 2_160_000),
        (layout.counter_log("inner"), 9_120), (layout.drive_log("inner"), 60_100))]
    return [{"path": p, "sha256": f"{i:02x}" * 32, "bytes": n}
            for i, (p, n) in enumerate(files, start=1)]


def rate_ladder_result() -> JsonObject:
    """Two axes; outer 10 and 50 deg/s, inner 20 deg/s; guard-band decision rule."""
    outer, inner = _rates()
    pairs_outer, pairs_inner = _pairs()
    return {
        "schema": "bench.result/1",
        "procedure": "rate-ladder",
        "verdict": "fail",
        "title": "Demo attestation, outer and inner axis (simulated bench)",
        "procedure_file": {"name": "demo.yaml", "sha256": "ab" * 32},
        "stand": {"maker": "Simulated Tables Ltd", "model": "ST-2A two-axis rate table",
                  "serial": "SIM-0001", "location": "virtual bench",
                  "file": "sim-two-axis.yaml", "sha256": "cd" * 32},
        "instruments": {
            "outer": {"drive": "CiA 402 drive node 2, vendor 0x0000029C, product 0x00000402",
                      "counter": "Keysight Technologies,53230A,MY50001234,02.05-1519.666",
                      "fog": "KVH DSP-1760 (kvh-a, 1000 Hz, axis z)"},
            "inner": {"drive": "CiA 402 drive node 3, vendor 0x0000029C, product 0x00000402",
                      "counter": "Keysight Technologies,53230A,MY50005678,02.05-1519.666",
                      "fog": "KVH DSP-1760 (kvh-a, 1000 Hz, axis z)"},
        },
        "dates": {"started_utc": "2025-03-04T08:15:02.120+00:00",
                  "completed_utc": "2025-03-04T11:47:40.871+00:00"},
        "conditions": {"temperature_c": "20 +/- 2", "humidity": "45 %",
                       "note": "simulated bench"},
        "certificate": {"laboratory": "Rate Table Metrology Lab (demo)",
                        "customer": "Demo customer"},
        "decision_rule": "guard-band",
        "method": {"sequence": "+-+", "harmonics": 3, "mains_hz": 50.0,
                   "static_record_s": 30.0, "turns": 4, "decision_rule": "guard-band",
                   "tolerance": {"rate_error": [{"below_dps": 10, "rel": 1.0e-5},
                                                {"rel": 1.0e-6}],
                                 "rate_instability": [{"rel": 1.0e-5}]}},
        "raw_files": _raw_files(),
        "sessions": 2,
        "aborted": False,
        "axes": {
            "outer": {"rates": outer, "pairs": pairs_outer,
                      "noise_floor": {"source": "static record", "noise_dps": 0.0100,
                                      "rate_hz": 1000.0, "duration_s": 30.0}},
            "inner": {"rates": inner, "pairs": pairs_inner,
                      "noise_floor": {"source": "static record", "noise_dps": 0.0101,
                                      "rate_hz": 1000.0, "duration_s": 30.0}},
        },
        "checks": _checks(),
    }
