"""The pulse generator and the digitizing DMM against their twins over real SCPI sockets,
checked against the platform twin's truth (docs/method.md B), on both simulated clocks:
the co-simulation (sims/clock.py SteppedClock, where the drivers' waits pass stand time)
and the paced clock of rehearsals (VirtualClock, where they are real seconds)."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from drivers.awg import AwgError, WaveformGenerator
from drivers.dmm import SPAN_SLACK_REL, Digitizer, DmmError, DmmOverload, DmmTimeout
from procedures.drift_pulse import analysis as dp
from sims.clock import SteppedClock, VirtualClock
from sims.gyro_rig import start_gyro_rig
from sims.platform import GyroTruth, PlatformTruth
from sims.stand import AxisTruth, SimulatedStand, StandTruth

pytestmark = pytest.mark.timeout(60)

TC_S = 5.0
AWG_POINTS = 1000                  # per pulse: 200 Sa/s
INTERVAL_S = 0.5e-3                # 2 kHz
APERTURE_S = 0.4e-3
LEAD_POINTS = 1
SPEED = 50.0


def truth(**errors: float) -> PlatformTruth:
    g = dict(precession_dps_per_v=0.1, k_as_v_per_deg=2.0, angle_offset_deg=0.3, **errors)
    return PlatformTruth(70.0, 80.0, {"x": GyroTruth(own_drift_dph=0.35, **g),
                                      "y": GyroTruth(own_drift_dph=-0.42, **g)},
                         table_axis="turntable", seed=5)


CLOCKS = ("stepped", "paced")


def rig_for(t: PlatformTruth, kind: str = "stepped", **options):
    clock = SteppedClock(running=False) if kind == "stepped" else VirtualClock(SPEED, running=False)
    stand = SimulatedStand(StandTruth(t.seed, {"turntable": AxisTruth()}),
                           {"turntable": 100.0}, clock)
    rig = start_gyro_rig(stand, t, {"x": 1, "y": 2}, **options)
    awg = WaveformGenerator.open(rig.awg.resource, "keysight-33500b", clock)
    dmms = {g: Digitizer.open(d.resource, "keysight-34465a", clock, timeout_margin_s=1.0)
            for g, d in rig.dmms.items()}
    clock.start()
    return rig, awg, dmms, clock


def close(rig, awg, dmms) -> None:
    for d in dmms.values():
        d.close()
    awg.close()
    rig.stop()


def load(awg, dmms, shape="rectangular", amplitude_v=1.0):
    pair = dp.SHAPES[shape].pair_points(AWG_POINTS)
    loaded = {g: awg.load_pair(ch, pair, AWG_POINTS / TC_S, amplitude_v,
                               lead_points=LEAD_POINTS, trigger_out=(ch == 1))
              for g, ch in (("x", 1), ("y", 2))}
    lead_s = loaded["x"].lead_s
    count = int(math.ceil((2 * TC_S + lead_s) / INTERVAL_S)) + 20
    # the middle of sample 0's aperture one interval after the edge: on the sample grid
    setups = {g: d.configure(10.0, APERTURE_S, INTERVAL_S, count,
                             trigger_delay_s=INTERVAL_S - APERTURE_S / 2)
              for g, d in dmms.items()}
    return loaded, setups


def cycle(awg, dmms, loaded, setups, clock, table_deg=0.0):
    for d in dmms.values():
        d.arm()
    t0 = awg.trigger()
    u = {g: d.fetch() for g, d in dmms.items()}
    return {g: dp.CycleRecord(u[g], INTERVAL_S,
                              float(setups[g].sample_time_s(0)) - loaded[g].lead_s, TC_S,
                              t0, table_deg) for g in dmms}


@pytest.mark.parametrize("kind", CLOCKS)
def test_identity_and_a_noise_free_cycle_gives_the_true_drift(kind: str) -> None:
    t = truth()
    rig, awg, dmms, clock = rig_for(t, kind)
    try:
        assert "33522B" in awg.identify()
        assert "34465A" in dmms["x"].identify()
        loaded, setups = load(awg, dmms)
        assert setups["x"].sample_time_s(0) - loaded["x"].lead_s == pytest.approx(-4.5e-3)
        recs = cycle(awg, dmms, loaded, setups, clock)
        for g, r in recs.items():
            fit = dp.fit_offset(r, dp.SHAPES["rectangular"])
            # the samples' middles sit on the edges (the aperture rounds each kink a little)
            assert abs(fit.offset_s) < 1e-7
            # U amplitude: k_as * precession * volts (LOAD INF: the volts asked, into 10 kohm)
            assert fit.amplitude_v_per_dps == pytest.approx(2.0 * 0.1 * 1.0 * 1e4 / 10050,
                                                            rel=1e-5)
            w, _ = dp.cycle_drift_dph(r, dp.SHAPES["rectangular"], 2.0, 0.0, 0.1)
            assert w == pytest.approx(t.total_drift_dph(g), abs=1e-5)
        assert [ch for ch, _ in rig.awg.bursts] == [1, 2]
    finally:
        close(rig, awg, dmms)


@pytest.mark.parametrize("kind", CLOCKS)
def test_trigger_latency_is_seen_as_a_start_offset(kind: str) -> None:
    """The DMM's trigger latency and the trigger output's skew move the samples later
    against the pulses: the fit finds minus their sum (twin truth)."""
    t = truth(angle_noise_arcsec=0.2)
    rig, awg, dmms, clock = rig_for(
        t, kind, awg_options={"trigger_out_skew_s": 1e-6}, dmm_options={"trigger_latency_s": 60e-6})
    try:
        loaded, setups = load(awg, dmms, amplitude_v=5.0)
        recs = [cycle(awg, dmms, loaded, setups, clock) for _ in range(2)]
        for g in "xy":
            fits = [dp.fit_offset(r[g], dp.SHAPES["rectangular"]) for r in recs]
            pooled = dp.pool_offsets(fits, INTERVAL_S)
            assert pooled.offset_s == pytest.approx(-61e-6, abs=3 * pooled.offset_u_s + 1e-7)
            assert pooled.significant
    finally:
        close(rig, awg, dmms)


@pytest.mark.parametrize("kind", CLOCKS)
def test_triangular_pair_through_the_instruments(kind: str) -> None:
    t = truth()
    rig, awg, dmms, clock = rig_for(t, kind)
    try:
        loaded, setups = load(awg, dmms, shape="triangular")
        recs = cycle(awg, dmms, loaded, setups, clock)
        for g, r in recs.items():
            w, _ = dp.cycle_drift_dph(r, dp.SHAPES["triangular"], 2.0, 0.0, 0.1)
            # the 16-bit DAC rounds the staircase symmetrically: no control residue
            assert w == pytest.approx(t.total_drift_dph(g), abs=1e-4)
    finally:
        close(rig, awg, dmms)


def test_refusals_name_the_problem_before_anything_is_sent() -> None:
    t = truth()
    rig, awg, dmms, clock = rig_for(t)
    try:
        sent = len(rig.awg.received)
        with pytest.raises(AwgError, match=r"values must lie in \[-1, 1\]"):
            awg.load_pair(1, np.array([1.5, -1.5] * 8), 100.0, 1.0)
        with pytest.raises(AwgError, match="amplitude"):
            awg.load_pair(1, np.array([1.0, -1.0] * 8), 100.0, 50.0)
        with pytest.raises(AwgError, match="no channel 3"):
            awg.load_pair(3, np.array([1.0, -1.0] * 8), 100.0, 1.0)
        assert len(rig.awg.received) == sent
        with pytest.raises(DmmError, match="shorter than the aperture"):
            dmms["x"].configure(10.0, 1e-3, 0.5e-3, 100)
        with pytest.raises(DmmError, match="reading memory"):
            dmms["x"].configure(10.0, 0.4e-3, 0.5e-3, 60_000)
    finally:
        close(rig, awg, dmms)


@pytest.mark.parametrize("kind", CLOCKS)
def test_overload_and_a_missing_trigger_are_errors_by_name(kind: str) -> None:
    t = replace(truth(), gyros={g: replace(v, angle_offset_deg=6.0)
                                for g, v in truth().gyros.items()})   # 12 V > 1.2 x 10 V
    rig, awg, dmms, clock = rig_for(t, kind)
    try:
        loaded, setups = load(awg, dmms)
        with pytest.raises(DmmOverload, match="beyond the 10 V range"):
            cycle(awg, dmms, loaded, setups, clock)
        rig.dmms["y"].inject("no-trigger")
        for d in dmms.values():
            d.arm()
        awg.trigger()
        with pytest.raises(DmmTimeout, match="Ext Trig"):
            dmms["y"].fetch()
    finally:
        close(rig, awg, dmms)


def test_on_the_co_simulation_the_record_ends_in_stand_time_fixed_by_the_data() -> None:
    """On a stepped clock the DMM's waits (armed, then the record) let stand time pass and
    nothing else: the bench learns that the record is complete at the first poll at or
    after its end (polls 1/50 of the record's length plus slack apart, drivers/dmm.py),
    the same stand time on every host and at any load; a second cycle starts there."""
    rig, awg, dmms, clock = rig_for(truth(), "stepped")
    try:
        loaded, setups = load(awg, dmms)
        setup = setups["x"]
        poll_s = setup.duration_s * (1.0 + SPAN_SLACK_REL) / 50.0
        assert clock.now() == 0.0                 # configuring took no stand time
        cycle(awg, dmms, loaded, setups, clock)
        t_end = clock.now()
        assert setup.duration_s - 1e-9 <= t_end < setup.duration_s + poll_s
        assert [t for _, t in rig.awg.bursts] == [0.0, 0.0]   # *TRG at the armed instant
        cycle(awg, dmms, loaded, setups, clock)
        assert [t for _, t in rig.awg.bursts][2:] == [t_end, t_end]
        assert setup.duration_s - 1e-9 <= clock.now() - t_end < setup.duration_s + poll_s
    finally:
        close(rig, awg, dmms)
