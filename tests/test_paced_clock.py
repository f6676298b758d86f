"""The paced simulation clock: a twin that lags slows the stand's clock, never aborts a run.

The clock's bounds are checked as upper bounds on virtual time, which a loaded machine
can only make smaller: no test here depends on how fast the machine is.
"""

from __future__ import annotations

import json
import math
import threading
import time
from pathlib import Path
from typing import Any

import pytest
import yaml

from bench.app.commands import EXIT_PASS, run_session
from bench.core.journal import RunDir
from bench.core.loader import load_config
from sims.clock import SteppedClock, VirtualClock, parse_speed
from tests.conftest import CONFIGS, journal_lines
from tests.test_run_e2e import check_against_truth

STAND = CONFIGS / "stands" / "sim-two-axis.yaml"


def test_clock_speed_max_and_numbers_parse() -> None:
    assert parse_speed("max") == math.inf
    assert parse_speed(None) == math.inf  # the default for simulated stands
    assert parse_speed(300) == 300.0
    with pytest.raises(ValueError, match="max"):
        parse_speed("fast")
    with pytest.raises(ValueError, match="> 0"):
        parse_speed(0)


def test_a_fixed_speed_clock_without_pacers_runs_at_its_speed() -> None:
    clock = VirtualClock(50.0)
    assert clock.speed == clock.min_speed == 50.0
    assert not clock.paced


def test_a_pacer_holds_the_clock_within_its_lead() -> None:
    delivered = [10.0]
    clock = VirtualClock("max", lead_s=1.0, running=False)
    unpace = clock.pace(lambda: delivered[0])
    assert clock.min_speed == 1.0  # a paced clock promises real time, no more
    m0 = time.monotonic()
    clock.start()
    time.sleep(0.2)
    # the twin delivered up to 10 s: the clock may lead it by 1 s, plus real time
    assert clock.now() <= 10.0 + 1.0 + (time.monotonic() - m0) * clock.floor_speed
    delivered[0] = 50.0
    clock.sleep_until(40.0)  # the twin caught up: the clock follows at once
    assert 40.0 <= clock.now() <= 51.0 + (time.monotonic() - m0)
    unpace()
    assert not clock.paced


def _procedure(tmp_path: Path, clock_speed: Any) -> Path:
    stand = yaml.safe_load(STAND.read_text())
    stand["sim"]["clock_speed"] = clock_speed
    stand_path = tmp_path / "stand.yaml"
    stand_path.write_text(yaml.safe_dump(stand))
    proc = tmp_path / "p.yaml"
    proc.write_text(yaml.safe_dump({
        "procedure": "rate-ladder", "stand": str(stand_path), "turns": 4,
        "static_record_s": 5, "harmonics": 2, "axes": {"outer": {"rates_dps": [100, 200]}},
    }))
    return proc


FROZEN_FRAMES_PER_S = 30_000.0   # a FOG at 1 kHz slowed to 30x real time


@pytest.mark.timeout(180)
def test_a_slowed_twin_slows_the_clock_and_the_run_completes(tmp_path: Path) -> None:
    """clock_speed 300 with a FOG that can only keep 30x: before pacing this aborted."""
    cfg = load_config(_procedure(tmp_path, 300))
    run = RunDir.create(tmp_path / "runs", cfg.procedure_path, cfg.stand_path)
    started: list[float] = []

    def slow(sim: Any) -> None:
        started.append(time.monotonic())
        sim.twins["outer.fog"].slow_down(FROZEN_FRAMES_PER_S)

    status = run_session(cfg, run, yes=True, on_sim_started=slow)
    real_s = time.monotonic() - started[0]
    events = journal_lines(run)
    assert status == EXIT_PASS, [e for e in events if e["event"] == "abort"]
    done = next(e for e in events if e["event"] == "completed")
    lead_s = 20.0
    # the clock never ran more than its lead ahead of what the slowed FOG had sent
    # (plus the moment before the slow-down took hold, at the top speed)
    assert done["t_s"] <= FROZEN_FRAMES_PER_S / 1000.0 * real_s + lead_s + 300 * 0.5, \
        (done["t_s"], real_s)
    result = json.loads((run.path / "result.json").read_text())
    assert result["verdict"] == "pass"
    assert [r["set_rate_dps"] for r in result["axes"]["outer"]["rates"]] == [100, -100,
                                                                             200, -200]
    check_against_truth(result)


class _Ticker:
    """A participant that acts every `period_s` and is settled a while after each act
    (a twin whose output takes real time to be consumed)."""

    def __init__(self, clock: SteppedClock, period_s: float) -> None:
        self.clock, self.period_s = clock, period_s
        self.acts: list[float] = []
        self._ready_at = 0.0

    def next_event_s(self, t_s: float) -> float:
        return (math.floor(t_s / self.period_s + 1e-9) + 1) * self.period_s

    def advance(self, t_s: float) -> None:
        if abs(t_s / self.period_s - round(t_s / self.period_s)) < 1e-9:
            self.acts.append(t_s)
            self._ready_at = time.monotonic() + 0.002

    def settled(self, t_s: float, final: bool) -> bool:
        return time.monotonic() >= self._ready_at


def test_a_stepped_clock_passes_time_only_in_waits_and_stops_at_every_event() -> None:
    """The co-simulation clock (issue 27): time stands while nothing waits, a wait steps
    through every participant's events in order, and a channel not drained holds it."""
    clock = SteppedClock(max_step_s=10.0)
    ticker = _Ticker(clock, 0.25)
    leave = clock.join(ticker)
    assert clock.stepped and clock.now() == 0.0
    time.sleep(0.05)
    assert clock.now() == 0.0                   # no wait: no time
    clock.sleep(1.1)
    assert clock.now() == pytest.approx(1.1)
    assert ticker.acts == pytest.approx([0.25, 0.5, 0.75, 1.0])
    # a channel: the wait ends only once its consumer has taken what was sent
    clock.channel_opened("pty")
    clock.sent("pty", 100)
    assert clock.backlog("pty") == 100

    class _Pty:
        def next_event_s(self, t_s: float) -> float:
            return math.inf

        def advance(self, t_s: float) -> None:
            pass

        def settled(self, t_s: float, final: bool) -> bool:
            return clock.backlog("pty") == 0 or not final

    leave_pty = clock.join(_Pty())
    done = threading.Event()
    threading.Thread(target=lambda: (clock.sleep_until(2.0), done.set()), daemon=True).start()
    time.sleep(0.1)
    assert not done.is_set()
    clock.consumed("pty", 100)
    assert done.wait(5.0)
    assert clock.now() == pytest.approx(2.0)
    leave_pty()
    leave()
    clock.channel_closed("pty")
    clock.sent("pty", 5)                         # nobody reads: nothing to wait for
    assert clock.backlog("pty") == 0


def test_a_fog_opened_between_waits_starts_at_the_first_sample_after_it() -> None:
    """A FOG opened at stand time 0.05 s (after the drive's identity waits). Its twin
    sent nothing while no reader had the port (samples 0 .. 50, t <= 0.05 s, went
    nowhere, as a real FOG's do), so the capture starts at sample 51 by hand, the
    first after 0.05 s, on every run: the first look at the FOG (after `drain`,
    SimBench.start_clock) is the same on any machine load."""
    from drivers.fog import Fog
    from sims.fog_twin import FogTwin
    from sims.stand import AxisTruth, SimulatedStand, StandTruth

    seen = []
    for _ in range(5):
        clock = SteppedClock()
        stand = SimulatedStand(StandTruth(seed=1, axes={"outer": AxisTruth()}),
                               {"outer": 1000.0}, clock)
        with FogTwin(stand, "outer") as twin:
            clock.sleep(0.05)            # the drive's opening waits; the FOG is not read yet
            with Fog(twin.path, rate_hz=1000.0, raw_path=None, clock=clock,
                     units="rad") as fog:
                clock.drain()
                first, end = fog.first_index, fog.end_index
                fog.wait_for_index(60, timeout_s=1.0)
                s = fog.samples(51, 61)
                seen.append((first, end, int(s.index[0]), bool(s.received.all())))
    assert seen == [(51, 51, 51, True)] * 5
