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
from bench.report.sample_result import (
    DatesStated,
    FileStated,
    RawFileStated,
    SampleResult,
    StandStated,
)
from procedures.rate_ladder.result import (
    Averaged,
    Binned,
    Harmonic,
    IntraTurn,
    LadderAxis,
    LadderCheck,
    Mains,
    NoiseFloor,
    PairEntry,
    RateEntry,
    RateErrorBudget,
    Systematic,
)


class LadderSample(SampleResult, frozen=True, kw_only=True):
    """A rate-ladder result by hand: the frame, the ladder's axes (its model), its checks."""

    axes: dict[str, LadderAxis]
    checks: tuple[LadderCheck, ...]


def _rate(set_dps: float, turns: int, err: float, err_u: float, inst: float, inst_u: float,
          raw: float, corr: float, verdict: str, harmonics: tuple[Harmonic, ...],
          mains_dps: float, over: tuple[float, float, float],
          binned: Binned | None = None) -> RateEntry:
    mean = set_dps * (1 + err)
    spread = np.array([1.0, -1.0, -0.5, 0.5, 0.2, -0.2][:turns])
    spread = spread / spread.std(ddof=1) if turns > 1 else spread
    rates = mean + abs(mean) * inst * spread
    return RateEntry(
        set_rate_dps=set_dps, turns=turns, counter_rate_dps=tuple(float(r) for r in rates),
        mean_rate_dps=mean, rate_error_rel=err, rate_error_u_rel=err_u,
        rate_instability_rel=inst, rate_instability_u_rel=inst_u,
        rate_instability_floor_rel=1.0e-9 * abs(set_dps),
        rate_error_budget=RateErrorBudget(   # bench.analysis.turns.TurnsResult's
            timing_u_rel=3.8e-10 * abs(set_dps) / 10, timebase_u_rel=5.8e-10,
            repeatability_u_rel=err_u / 2, coverage_factor=2.0, timestamp_u_s=2e-11,
            trigger_jitter_s=2.7e-08, timebase_limit_rel=1e-09),
        intra_turn_instability_rel=raw, intra_turn_instability_corrected_rel=corr,
        intra_turn=IntraTurn(   # bench.analysis.random_part.RandomPartResult's
            instability_rel=raw, floor_rel=math.sqrt(raw * raw - corr * corr),
            floor_source="static record (Allan deviation)", corrected_rel=corr,
            corrected_upper_rel=corr * 1.25, resolved=True, bandwidth_hz=1000.0,
            std_dps=raw * abs(set_dps), samples=144_000,
            averaged=tuple(
                Averaged(angle_deg=a, instability_rel=v, floor_rel=v * 0.5,
                         corrected_rel=v * math.sqrt(0.75), blocks=n, samples_per_block=1.0)
                for a, v, n in zip((1.0, 10.0, 360.0), over, (1440, 144, 4), strict=True))),
        systematic=Systematic(
            harmonics=harmonics,
            mains=Mains(frequency_hz=50.0, amplitude_dps=mains_dps, amplitude_u_dps=3.0e-5,
                        phase_deg=12.0, phase_u_deg=9.0, detected=True),
            binned=binned),
        verdict=verdict)


def _outer_harmonics(sign: float) -> tuple[Harmonic, ...]:
    return (
        Harmonic(order=1, amplitude_rel=8.6e-4, amplitude_u_rel=1.23e-5,
                 phase_deg=40.3 if sign > 0 else -139.6, phase_u_deg=0.84, detected=True),
        Harmonic(order=2, amplitude_rel=1.5e-4, amplitude_u_rel=1.1e-5, phase_deg=-69.0,
                 phase_u_deg=4.2, detected=True),
        Harmonic(order=3, amplitude_rel=3.0e-6, amplitude_u_rel=1.1e-5, phase_deg=17.0,
                 phase_u_deg=180.0, detected=False),
    )


def _binned(set_dps: float) -> Binned:
    """The paper's binned average by angle: the fitted model plus a deterministic ripple."""
    phi = np.arange(0.0, 360.0, 5.0) + 2.5
    r = np.radians(phi)
    model = 8.6e-4 * np.cos(r + math.radians(40.3)) + 1.5e-4 * np.cos(2 * r - math.radians(69))
    ripple = 2.0e-5 * np.sin(7.3 * r + 0.4)
    return Binned(bin_deg=5.0, centres_deg=tuple(phi.tolist()),
                  deviation_rel=tuple((model + ripple).tolist()), u_rel=(3.0e-5,) * phi.size,
                  peak_to_peak_rel=float(np.ptp(model + ripple)))


def _rates() -> tuple[tuple[RateEntry, ...], tuple[RateEntry, ...]]:
    """(outer, inner): outer at +/-10 and +/-50 deg/s, failing its tolerance at 50 with
    the paper's binned average there; inner at +/-20 deg/s with one harmonic."""
    h_in = (Harmonic(order=1, amplitude_rel=2.0e-4, amplitude_u_rel=2.4e-5, phase_deg=120.0,
                     phase_u_deg=7.0, detected=True),)
    outer = (
        _rate(10.0, 4, 3.04e-7, 1.23e-7, 2.6e-8, 2.2e-8, 1.06e-3, 1.2e-5, "pass",
              _outer_harmonics(1), 2.0e-4, (2.1e-4, 3.3e-5, 1.1e-6)),
        _rate(-10.0, 4, -2.1e-7, 1.2e-7, 3.1e-8, 2.6e-8, 1.04e-3, 1.3e-5, "pass",
              _outer_harmonics(-1), 1.9e-4, (2.0e-4, 3.1e-5, 1.0e-6)),
        _rate(50.0, 4, 1.42e-6, 1.1e-7, 4.4e-8, 3.7e-8, 2.15e-4, 1.05e-5, "fail",
              _outer_harmonics(1), 2.1e-4, (4.4e-5, 6.6e-6, 2.4e-7), _binned(50.0)),
        _rate(-50.0, 4, 9.5e-7, 1.0e-7, 2.0e-8, 1.7e-8, 2.11e-4, 1.0e-5, "fail",
              _outer_harmonics(-1), 2.0e-4, (4.3e-5, 6.5e-6, 2.2e-7)),
    )
    inner = (
        _rate(20.0, 4, 1.8e-7, 1.5e-7, 1.9e-8, 1.6e-8, 5.3e-4, 6.0e-6, "pass",
              h_in, 1.0e-4, (1.0e-4, 1.6e-5, 5.0e-7)),
        _rate(-20.0, 4, -1.0e-7, 3.5e-7, 2.2e-8, 1.9e-8, 5.2e-4, 6.1e-6, "pass",
              h_in, 1.1e-4, (1.0e-4, 1.5e-5, 5.1e-7)),
    )
    return outer, inner


def _pairs() -> tuple[tuple[PairEntry, ...], tuple[PairEntry, ...]]:
    """(outer, inner): each pair's k and w0 with U, the bias drift fitted out."""
    def pair(rate: float, k: float, k_u: float, w0: float, w0_u: float, drift: float,
             drift_u: float) -> PairEntry:
        return PairEntry(rate_dps=rate, k=k, k_u=k_u, w0_dps=w0, w0_u_dps=w0_u,
                         drift_dps_per_h=drift, drift_u_dps_per_h=drift_u,
                         method="lsq-drift", drift_source="the three halves (+, -, +)")

    return ((pair(10.0, 1.000299, 2.34e-6, 0.002013, 1.17e-4, 0.00104, 0.00031),
             pair(50.0, 1.0002934, 4.6e-7, 0.002051, 1.2e-4, 0.00097, 0.00029)),
            (pair(20.0, 0.9994985, 1.2e-6, -0.002994, 1.2e-4, 0.00201, 0.00030),))


def _checks() -> tuple[LadderCheck, ...]:
    """The rate error per rate under the guard-band rule (each of its three outcomes),
    and one instability check."""
    def check(axis: str, rate: float, value: float, u: float, verdict: str, reason: str,
              quantity: str = "rate_error", tol: float = 1.0e-6) -> LadderCheck:
        return LadderCheck(axis=axis, set_rate_dps=rate, quantity=quantity, value_rel=value,
                           u_rel=u, tolerance_rel=tol, verdict=verdict, rule="guard-band",
                           reason=reason, capability_ratio=u / tol,
                           capability_ok=u / tol <= 0.3)

    return (
        check("outer", 10.0, 3.04e-7, 1.23e-7, "pass", "|δ| + U ≤ T"),
        check("outer", -10.0, -2.1e-7, 1.2e-7, "pass", "|δ| + U ≤ T"),
        check("outer", 50.0, 1.42e-6, 1.1e-7, "fail", "|δ| > T: out of tolerance"),
        check("outer", -50.0, 9.5e-7, 1.0e-7, "fail",
              "|δ| ≤ T but |δ| + U > T: within U of the limit (guard band)"),
        check("inner", 20.0, 1.8e-7, 1.5e-7, "pass", "|δ| + U ≤ T"),
        check("inner", -20.0, -1.0e-7, 3.5e-7, "pass", "|δ| + U ≤ T"),
        check("outer", 10.0, 2.6e-8, 2.2e-8, "pass", "σ + U ≤ T", "rate_instability", 1e-5),
    )


def _raw_files() -> tuple[RawFileStated, ...]:
    """The raw files of one session, each hashed."""
    files = [(layout.raw_relpath(1, name), size) for name, size in (
        (layout.fog_capture("outer"), 4_321_000), (layout.counter_log("outer"), 18_211),
        (layout.drive_log("outer"), 120_554), (layout.fog_capture("inner"), 2_160_000),
        (layout.counter_log("inner"), 9_120), (layout.drive_log("inner"), 60_100))]
    return tuple(RawFileStated(p, f"{i:02x}" * 32, n)
                 for i, (p, n) in enumerate(files, start=1))


def rate_ladder_result() -> LadderSample:
    """Two axes; outer 10 and 50 deg/s, inner 20 deg/s; guard-band decision rule."""
    outer, inner = _rates()
    pairs_outer, pairs_inner = _pairs()
    # the FOG at rest: the sample states where its floor comes from and for how long
    floor = NoiseFloor(source="static record", duration_s=30.0)
    return LadderSample(
        procedure="rate-ladder", verdict="fail",
        title="Demo attestation, outer and inner axis (simulated bench)",
        procedure_file=FileStated("demo.yaml", "ab" * 32),
        stand=StandStated(maker="Simulated Tables Ltd", model="ST-2A two-axis rate table",
                          serial="SIM-0001", location="virtual bench",
                          file="sim-two-axis.yaml", sha256="cd" * 32),
        instruments={
            "outer": {"drive": "CiA 402 drive node 2, vendor 0x0000029C, product 0x00000402",
                      "counter": "Keysight Technologies,53230A,MY50001234,02.05-1519.666",
                      "fog": "KVH DSP-1760 (kvh-a, 1000 Hz, axis z)"},
            "inner": {"drive": "CiA 402 drive node 3, vendor 0x0000029C, product 0x00000402",
                      "counter": "Keysight Technologies,53230A,MY50005678,02.05-1519.666",
                      "fog": "KVH DSP-1760 (kvh-a, 1000 Hz, axis z)"},
        },
        dates=DatesStated("2025-03-04T08:15:02.120+00:00", "2025-03-04T11:47:40.871+00:00"),
        conditions={"temperature_c": "20 +/- 2", "humidity": "45 %",
                    "note": "simulated bench"},
        certificate={"laboratory": "Rate Table Metrology Lab (demo)",
                     "customer": "Demo customer"},
        decision_rule="guard-band",
        method={"sequence": "+-+", "harmonics": 3, "mains_hz": 50.0,
                "static_record_s": 30.0, "turns": 4, "decision_rule": "guard-band",
                "tolerance": {"rate_error": [{"below_dps": 10, "rel": 1.0e-5},
                                             {"rel": 1.0e-6}],
                              "rate_instability": [{"rel": 1.0e-5}]}},
        raw_files=_raw_files(), sessions=2,
        axes={"outer": LadderAxis(rates=outer, pairs=pairs_outer, noise_floor=floor),
              "inner": LadderAxis(rates=inner, pairs=pairs_inner, noise_floor=floor)},
        checks=_checks())
