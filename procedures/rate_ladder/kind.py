"""The +/-w rate ladder of docs/method.md part A (seed 000), as a procedure kind.

Per axis: a record of the FOG at rest (its noise floor, docs/method.md A5); then for each rate
magnitude the halves of a +/- pair, by default in the order +w, -w, +w with the turns of
the + direction split around the - half, so a linear FOG bias drift cancels in the
cross-calibration (docs/method.md A3, "beyond the paper"); each half: set the rate, settle,
time N whole turns with the counter while the FOG streams; then cross-calibrate and
analyze the pair.
"""

from __future__ import annotations

import math
from collections.abc import Collection, Mapping
from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING, TypeVar

from bench.core.config import Config, StandSettings, stand_schema
from bench.core.plan import Duration, Plan, Step, check_actions, format_duration
from bench.core.progress import RELATIVE, Figure
from bench.core.schema import Map
from bench.core.yamlfile import Problem
from drivers.clock import Clock, stepped
from procedures.base import prompt
from procedures.rate_ladder.settings import (
    NAME,
    PROCEDURE,
    LadderSettings,
    halves,
    ladder_problems,
    tolerance_for,
    validation_notes,
)

# the instruments, the twins, the analysis, the certificate and the records are imported
# where the kind uses them: `bench validate` and `bench schema` load this module for its
# files alone
if TYPE_CHECKING:
    import numpy as np
    from numpy.typing import NDArray

    from bench.core.engine import RunContext
    from bench.core.instruments import Bench
    from bench.core.journal import RunDir
    from bench.core.protocols import Counter as CounterLike
    from bench.core.protocols import Fog as FogLike
    from bench.core.registry import StepHandler
    from bench.core.simbench import SimBench
    from bench.kind import Kind
    from bench.report.codec import KindResult
    from bench.report.dcc.parts import DccParts
    from drivers.counter import Acquisition, Counter
    from drivers.fog import Fog
    from procedures.rate_ladder.certificate import LadderCertificate
    from procedures.rate_ladder.events import PairLooked
    from procedures.rate_ladder.records import LadderRecords
    from procedures.rate_ladder.result import LadderBody
    from procedures.rate_ladder.station import LadderStation

#: what the analysis worker imports when it starts, before the first pair's look (the
#: look's modules and the fit's scipy; bench/core/engine.py `_preload`)
WORKER_PRELOAD = ("procedures.rate_ladder.analysis", "scipy.linalg")


def _turns(n: int) -> str:
    return f"{n} turn" if n == 1 else f"{n} turns"


D = TypeVar("D")


def _driver(value: CounterLike | FogLike | None, kind: type[D], what: str) -> D:
    """An axis's instrument as the ladder reads it: the driver's own class (the FOG's
    decoder stats and sample indices, the counter's acquisition and time tie)."""
    if not isinstance(value, kind):
        raise TypeError(f"{what}: the ladder needs a {kind.__module__}.{kind.__name__}, "
                        f"the bench holds {value!r}")
    return value


def _fog_of(ctx: RunContext, axis: str) -> Fog:
    from drivers.fog import Fog
    return _driver(ctx.bench.axes[axis].fog, Fog, f"{axis}'s FOG")


def _counter_of(ctx: RunContext, axis: str) -> Counter:
    from drivers.counter import Counter
    return _driver(ctx.bench.axes[axis].counter, Counter, f"{axis}'s counter")


def _fog_losses(fog: Fog) -> int:
    """Frames the FOG's decoder found lost or broken so far (a half's count: the change)."""
    st = fog.stats
    return int(st.lost_frames + st.crc_errors)


def _check_fog_indices(fog: Fog, upto: int, what: str) -> None:
    """Abort before a record whose FOG sample indices the driver no longer trusts.

    Frames lost in whole wraps of the sequence counter (a stalled, overrun link: what a
    loaded host or a USB adapter can do) leave no mark in the bytes, so every later
    sample would sit on the wrong time (docs/method.md A3-A4: shifted turns, harmonic
    phases off by w dt) while the analysis saw a clean record. The driver spots it from
    the clock (drivers/fog.py `index_uncertain_from`); such a half is not journaled, and
    `bench run --resume` measures it again on a new FOG session."""
    from bench.core.engine import Abort
    doubt = fog.stats.index_uncertain_from
    if doubt is not None and doubt < upto:
        cause = getattr(fog, "last_error", None) or "frames lost in whole counter wraps"
        raise Abort(f"{what}: the FOG's sample indices from {doubt} on are uncertain "
                    f"({cause}); this record is not used: `bench run --resume` measures "
                    "it again")


def fogs_opened_when_used(clock: Clock) -> bool:
    """Whether each axis's FOG is opened for its own steps only (`execute`).

    A FOG opened late places its first frame by the clock, exactly only within half a
    wrap of its sequence counter (drivers/fog.py: 64 ms at 1 kHz). That holds on
    hardware and on a clock at most real time (a port opens in milliseconds), and on
    the co-simulation, whose clock stands still while the port opens. A paced twin at
    N x real time would stretch those milliseconds N-fold (at 300x: 128 samples, a
    whole wrap), so there every FOG opens at the start, before the clock runs."""
    return stepped(clock) or float(getattr(clock, "speed", 1.0)) <= 1.0


# -- each action's parameters, made once where the plan is built (the static record's:
# bench.core.plan.Duration) ---------------------------------------------------------------

@dataclass(frozen=True, slots=True)
class SetRateParams:
    """A half's rate command: signed rate, and the ramp to it."""
    rate_dps: float
    accel_dps2: float


@dataclass(frozen=True, slots=True)
class SettleParams:
    """Settled: within the tolerance at this rate for hold_s, or a fault after timeout_s."""
    tolerance_dps: float
    hold_s: float
    timeout_s: float


@dataclass(frozen=True, slots=True)
class AcquireParams:
    """A half: N whole turns timed at the signed rate; `half` its index in the pair."""
    rate_dps: float
    turns: int
    half: int
    period_s: float


@dataclass(frozen=True, slots=True)
class AnalyzeParams:
    """The pair's first look: its rate magnitude."""
    rate_dps: float


@dataclass(frozen=True, slots=True)
class StopParams:
    """The ramp to rest."""
    accel_dps2: float


class LadderFiles:
    """The ladder's files (the kind's `settings` part): schemas, parse, checks, notes."""

    def procedure_schema(self) -> Map:
        return PROCEDURE

    def stand_schema(self) -> Map:
        return stand_schema()

    def cross_check(self, cfg: Config) -> list[Problem]:
        return ladder_problems(cfg)

    def parse(self, cfg: Config) -> LadderSettings:
        """The validated procedure as the ladder's frozen settings (bench/core/registry.py)."""
        return LadderSettings.parse(cfg)

    def notes(self, cfg: Config) -> list[str]:
        """Advice `bench validate` prints beside 'valid' (nothing wrong, something unstated)."""
        return validation_notes(cfg)

class LadderPlan:
    """The ladder's steps (the kind's `plan` part), checked against the actions its
    steps handle."""

    def __init__(self, actions: Collection[str]) -> None:
        self._actions = actions

    def build_plan(self, cfg: Config) -> Plan:
        steps: list[Step] = []
        ladder = LadderSettings.from_config(cfg)
        settle = ladder.settle
        static_s = ladder.static_record_s
        for axis, spec in ladder.axes.items():
            turns = spec.turns
            accel = spec.accel_dps2
            if ladder.prompts:
                text = spec.prompt or (
                    f"Mount the FOG on the {axis} axis (sensitive axis along the table axis), "
                    f"connect the {axis} zero-mark sensor to the counter")
                steps.append(Step("prompt", axis, text))
            if static_s > 0:
                steps.append(Step("static", axis, f"FOG at rest for {static_s:g} s (noise floor, "
                                  "docs/method.md A5)", static_s, f"{axis}/static",
                                  Duration(static_s)))
            steps.append(Step("enable", axis, "drive to Operation Enabled, profile velocity",
                              1.0))
            rate_now = 0.0
            for rate in spec.rates_dps:
                unit = f"{axis}/{rate:g}dps"
                parts = halves(turns, ladder.sequence)
                for j, (sign, n) in enumerate(parts):
                    target = sign * rate
                    steps.append(Step("set_rate", axis, f"{target:+g} deg/s",
                                      abs(target - rate_now) / accel, unit,
                                      SetRateParams(target, accel)))
                    tol = settle.tolerance_at(rate)
                    steps.append(Step("settle", axis, f"within {tol:.3g} deg/s for "
                                      f"{settle.hold_s:g} s", settle.hold_s + 0.5, unit,
                                      SettleParams(tol, settle.hold_s, settle.timeout_s)))
                    period = 360.0 / rate
                    steps.append(Step("acquire", axis, f"{_turns(n)} at {target:+g} deg/s "
                                      f"(half {j + 1}/{len(parts)}, "
                                      f"{format_duration((n + 1) * period)} with the "
                                      "lead-in turn)",
                                      (n + 1) * period, unit,
                                      AcquireParams(target, n, j, period)))
                    rate_now = target
                steps.append(Step("analyze", axis, f"cross-calibrate and analyze the "
                                  f"+/-{rate:g} deg/s pair", 0.0, unit, AnalyzeParams(rate)))
            steps.append(Step("stop", axis, "ramp to zero, disable", abs(rate_now) / accel,
                              None, StopParams(accel)))
        title = ladder.title
        warnings = tuple(
            f"axis {axis}: {spec.turns} turns with sequence +-+ split the + direction "
            f"{halves(spec.turns, '+-+')[0][1]}/{halves(spec.turns, '+-+')[2][1]} around the "
            "- half; an even count splits it evenly (a linear FOG drift then cancels "
            "exactly, docs/method.md A3)"
            for axis, spec in ladder.axes.items()
            if ladder.sequence == "+-+" and spec.turns >= 3 and spec.turns % 2)
        return check_actions(Plan(title, tuple(steps), warnings), self._actions)

    # -- resume ----------------------------------------------------------------------
    def resume_plan(self, plan: Plan, run: RunDir) -> Plan:
        """What a --resume still runs: every half already acquired is kept (docs/resume.md).

        `plan` holds the units not done; of each, the halves acquired in earlier sessions
        are dropped with their set-rate and settle steps. A pair must keep one session
        that holds both signs (its FOG calibration, bench/analysis/pair.py): when neither
        an earlier session nor what is left would hold both, the pair is acquired whole.
        """
        from procedures.rate_ladder.analysis import unit_acquisitions

        events = run.events()
        kept: dict[str, dict[int, int]] = {}  # unit -> half -> (sign) of the kept halves
        sessions: dict[str, dict[int, set[int]]] = {}
        for h in unit_acquisitions(events):
            kept.setdefault(h.unit, {})[h.half] = h.sign
            sessions.setdefault(h.unit, {}).setdefault(h.session, set()).add(h.sign)
        drop: dict[str, set[int]] = {}
        for unit, halves_done in kept.items():
            left = {(1 if s.params_as(AcquireParams).rate_dps > 0 else -1) for s in plan.steps
                    if s.unit == unit and s.action == "acquire"
                    and s.params_as(AcquireParams).half not in halves_done}
            whole_session = any(signs == {1, -1} for signs in sessions[unit].values())
            if whole_session or left == {1, -1}:
                drop[unit] = set(halves_done)
        steps: list[Step] = []
        pending: list[Step] = []  # a half's set_rate and settle wait for its acquire
        for s in plan.steps:
            if s.unit in drop and s.action in ("set_rate", "settle"):
                pending.append(s)
                continue
            if s.unit in drop and s.action == "acquire":
                if s.params_as(AcquireParams).half not in drop[s.unit]:
                    steps += [*pending, s]
                pending = []
                continue
            steps += pending
            pending = []
            steps.append(s)
        return Plan(plan.title, tuple(steps + pending))


class LadderSteps:
    """The ladder on the bench (the kind's `steps` part): twins, instruments, and one
    handler per action of its plan."""

    def __init__(self) -> None:
        self.handlers: Mapping[str, StepHandler] = {
            "prompt": prompt, "static": self._do_static, "enable": self._do_enable,
            "set_rate": self._do_set_rate, "settle": self._do_settle,
            "acquire": self._do_acquire, "analyze": self._do_analyze, "stop": self._do_stop}

    # -- bench -----------------------------------------------------------------------
    def axes(self, cfg: Config) -> list[str]:
        """The procedure's axes (every axis of the stand for `bench devices`)."""
        return list(LadderSettings.from_config(cfg).axes or cfg.stand_settings.axes)

    def start_sim(self, cfg: Config) -> tuple[SimBench, StandSettings]:
        from bench.core.simbench import SimBench
        sim = SimBench(cfg.stand_settings, self.axes(cfg))
        return sim, sim.start()

    def open_bench(self, cfg: Config, stand: StandSettings, clock: Clock,
                   run: RunDir | None) -> Bench:
        from bench.core.instruments import Bench, StandClaimError, open_axis
        bench = Bench()
        try:
            later = fogs_opened_when_used(clock)
            for axis in self.axes(cfg):
                open_axis(bench, stand.axes[axis], clock, run, fog_when_used=later)
            refused = uncommandable_rates(cfg, bench)
        except BaseException as e:
            bench.abandon(e)
            raise
        if refused:
            error = StandClaimError("; ".join(refused))
            bench.abandon(error)
            raise error
        return bench

    # -- steps (each action's handler: `handlers`) --------------------------------------
    def execute(self, step: Step, ctx: RunContext) -> None:
        """An axis's FOG streams for that axis's steps only: opened after the axis's
        prompt (the operator mounts it then), closed when the next axis begins
        (bench.core.instruments.fog_for_axis). Its first frame's index comes from the
        clock; the `fog_capture` event keeps it for the analysis of the raw file."""
        from bench.core.events import FogCapture
        from bench.core.instruments import fog_for_axis, identity_record
        ax = ctx.bench.axes.get(step.axis) if step.axis else None
        if ax is not None:
            fog = fog_for_axis(ctx.bench, ax.name, ctx.run, opening=step.action != "prompt")
            if fog is not None:
                ctx.run.write(FogCapture(axis=ax.name, first_index=fog.first_index,
                                         rate_hz=fog.rate_hz))
                ctx.run.write(identity_record(ax))
        self.handlers[step.action](step, ctx)

    def _do_enable(self, step: Step, ctx: RunContext) -> None:
        ctx.bench.axes[step.on_axis].drive.enable()

    def _do_static(self, step: Step, ctx: RunContext) -> None:
        from procedures.rate_ladder.events import StaticRecorded

        fog = _fog_of(ctx, step.on_axis)
        duration = step.params_as(Duration).duration_s
        # the first sample at or after now, and not before the capture's first (a FOG
        # opened at this instant, execute(): its first frame is the first sample after it)
        due = max(math.ceil(ctx.clock.now() * fog.rate_hz), fog.first_index or 0)
        # co-simulation: the stand's sample n is at n / rate, and whether the sample due at
        # this instant has reached the reader yet is thread scheduling: the clock alone says
        # where the record starts, or a loaded machine moves it by one sample. Hardware:
        # the FOG's oscillator and the host's differ, so never before what has arrived.
        i0 = due if stepped(ctx.clock) else max(fog.end_index, due)
        n = int(round(duration * fog.rate_hz))
        lost0 = _fog_losses(fog)
        mark = fog.checkpoint()  # where the record starts in the raw capture (or before)
        self._wait_fog(ctx, fog, i0 + n, duration, f"{step.axis}: FOG at rest")
        _check_fog_indices(fog, i0 + n, f"{step.axis}: FOG at rest")
        ctx.run.write(StaticRecorded(   # the samples stay in the raw capture
            axis=step.on_axis, unit=step.in_unit, fog_from=i0, fog_to=i0 + n,
            rate_hz=fog.rate_hz, lost=_fog_losses(fog) - lost0, fog_capture=mark))
        mean = _fog_mean_dps(fog)
        if mean is not None:
            ctx.progress.reading("FOG mean", f"{step.axis} at rest",
                                 Figure("", mean, unit="°/s", signed=True))

    def _wait_fog(self, ctx: RunContext, fog: Fog, index: int, span_s: float, label: str) -> None:
        t_end = ctx.clock.now() + span_s
        while True:
            left = t_end - ctx.clock.now()
            ctx.progress.advance(min(span_s - left, span_s), span_s,
                                 f"{label}: {span_s - max(left, 0):.0f} of {span_s:g} s")
            if left <= 0:
                break
            ctx.clock.sleep(min(left, max(span_s / 20, 0.5)))
            for ax in ctx.bench.axes.values():
                ax.drive.check()
        fog.wait_for_index(index, timeout_s=max(5.0, span_s * 0.2))

    def _do_set_rate(self, step: Step, ctx: RunContext) -> None:
        drive = ctx.bench.axes[step.on_axis].drive
        p = step.params_as(SetRateParams)
        drive.set_rate(p.rate_dps, p.accel_dps2)

    def _do_settle(self, step: Step, ctx: RunContext) -> None:
        from procedures.rate_ladder.events import Settled
        drive = ctx.bench.axes[step.on_axis].drive
        p = step.params_as(SettleParams)
        def held(held_s: float) -> None:
            ctx.progress.advance(held_s, p.hold_s, f"within ±{p.tolerance_dps:g} deg/s "
                                 f"for {min(held_s, p.hold_s):.1f} of {p.hold_s:g} s")

        rate = drive.wait_settled(p.tolerance_dps, p.hold_s, p.timeout_s,
                                  on_hold=held)
        ripple = getattr(drive, "last_settle", None)
        if ripple is None:
            ctx.run.write(Settled(axis=step.on_axis, unit=step.in_unit, rate_dps=rate))
            return
        # drivers/settle.py: the turn's steady ripple set aside, and stated
        ctx.run.write(Settled(axis=step.on_axis, unit=step.in_unit, rate_dps=rate,
                              rule="ripple set aside", ripple_peak_dps=ripple.ripple_peak_dps,
                              ripple_orders=ripple.orders, turns=ripple.turns,
                              worst_residual_dps=ripple.worst_residual_dps))
        if ripple.ripple_peak_dps > 0.5 * p.tolerance_dps:
            ctx.progress.line(f"  {step.axis}: settled at {rate:+.6g} deg/s; a steady "
                              f"ripple of the turn, {ripple.ripple_peak_dps:.3g} deg/s peak "
                              f"(orders 1-{ripple.orders}), set aside: the rest stayed "
                              f"within ±{p.tolerance_dps:g} deg/s for {p.hold_s:g} s")

    def _do_acquire(self, step: Step, ctx: RunContext) -> None:
        from bench.core.engine import Abort
        from procedures.rate_ladder.analysis import fog_bracket, read_half_ahead, static_record
        from procedures.rate_ladder.events import HalfAcquired

        ax = ctx.bench.axes[step.on_axis]
        p = step.params_as(AcquireParams)
        n = p.turns
        period = p.period_s
        counter, fog, drive = _counter_of(ctx, step.on_axis), _fog_of(ctx, step.on_axis), ax.drive
        rec0 = ax.logs["counter"].count if "counter" in ax.logs else 0
        lost0 = _fog_losses(fog)
        mark = fog.checkpoint()  # the raw capture up to here holds no sample of this half
        counter.arm(n + 1, period)
        t_arm = ctx.clock.now()
        t_end = t_arm + (n + 1) * period
        while (left := t_end - ctx.clock.now()) > 0:
            turn = min(n, max(int((ctx.clock.now() - t_arm) / period) - 1, 0))
            ctx.progress.advance(turn, n, f"{turn} of {_turns(n)} timed at "
                                 f"{p.rate_dps:+g} deg/s, {format_duration(left)} left")
            ctx.clock.sleep(min(left, max(period / 4, 0.25)))
            drive.check()
        edges = counter.fetch()
        acq = counter.last_acquisition
        if acq is None:
            raise Abort(f"{step.axis}: the counter kept no acquisition of its fetch")
        if len(edges) != n + 1:
            raise Abort(f"{step.axis}: the counter returned {len(edges)} edges, expected {n + 1}")
        # the FOG samples that bracket the timed turns (the analysis integrates exactly
        # from the first edge to the last, interpolating between samples); one rule, the
        # analysis's, which a corrected re-analysis applies again
        i_from, i_to = fog_bracket(edges, fog.rate_hz)
        rec1 = ax.logs["counter"].count if "counter" in ax.logs else 0
        fog.wait_for_index(i_to, timeout_s=max(10.0, period))
        _check_fog_indices(fog, i_to, f"{step.axis} {p.rate_dps:+g} deg/s half {p.half}")
        lost = _fog_losses(fog) - lost0
        # the FOG samples stay in the raw capture: the pair's analysis reads them there;
        # this event completes the half (a --resume keeps it, docs/resume.md)
        half = HalfAcquired(
            axis=step.on_axis, unit=step.in_unit, half=p.half, set_rate_dps=p.rate_dps, turns=n,
            edges_s=[float(e) for e in edges], counter_records=[rec0, rec1],
            fog_from=i_from, fog_to=i_to, rate_hz=fog.rate_hz,
            counter_t0_s=acq.t_start_s, counter_t0_u_s=acq.t_start_u_s,
            counter_readback=dict(counter.readback), fog_lost=lost,
            fog_capture=mark, time_tie=time_tie_record(counter, acq, fog),
            session=ctx.run.session)
        ctx.run.write(half)
        # the worker reads the half's FOG window now, the pair's first look later; a
        # failure here shows again, and is reported, when the first look reads it
        ctx.worker.submit(read_half_ahead, str(ctx.run.path), ctx.cfg, half,
                          static_record(ctx.run.events(), step.on_axis),
                          on_done=lambda _result, _error: None)
        if lost:
            ctx.progress.warn(f"  WARNING {step.axis}: {lost} FOG frames lost or broken "
                              "during this half (CRC or sequence gaps); the analysis uses "
                              "the rest")
        self._show_half(ctx, step.on_axis, p.rate_dps, edges, _fog_mean_dps(fog))

    @staticmethod
    def _show_half(ctx: RunContext, axis: str, set_dps: float, edges: NDArray[np.float64],
                   fog_mean_dps: float | None) -> None:
        """The half just timed: its per-turn rate deviations ω_i/ω_set − 1 (docs/method.md A1)
        to 3 significant digits, as the certificate's annex prints them; the FOG mean."""
        dev = [360.0 / (b - a) / abs(set_dps) - 1.0
               for a, b in zip(edges[:-1], edges[1:], strict=True)]
        mean = 360.0 * (len(edges) - 1) / (edges[-1] - edges[0]) / abs(set_dps) - 1.0
        label = f"{axis} {set_dps:+g} deg/s"
        ctx.progress.reading("per-turn rate deviation", f"{label}, turn {len(dev)}",
                             Figure("", dev[-1], unit=RELATIVE, signed=True, digits=3))
        if fog_mean_dps is not None:
            ctx.progress.reading("FOG mean", f"end of the {label} half",
                                 Figure("", fog_mean_dps, unit="°/s", signed=True, digits=6))
        ctx.progress.result(f"{label}, {_turns(len(dev))} timed",
                            Figure("mean rate deviation", mean, unit=RELATIVE, signed=True,
                                   digits=3),
                            *[Figure(f"turn {i + 1}", d, unit=RELATIVE, signed=True, digits=3)
                              for i, d in enumerate(dev)])

    def _do_analyze(self, step: Step, ctx: RunContext) -> None:
        """A first look at the pair, in the analysis worker: acquisition goes on meanwhile
        (the result.json analysis is made again from the raw files at the end)."""
        import msgspec

        from procedures.rate_ladder.analysis import (
            FirstLook,
            pair_summary,
            static_record,
            unit_halves,
        )
        from procedures.rate_ladder.events import PairFailed

        axis, unit, rate = step.on_axis, step.in_unit, step.params_as(AnalyzeParams).rate_dps
        events = ctx.run.events()  # the halves may come from earlier sessions (--resume)

        def done(look: object, error: BaseException | None) -> None:
            if error is not None:
                ctx.run.write(PairFailed(axis=axis, unit=unit, error=repr(error)))
                ctx.progress.warn(f"  WARNING {axis} +/-{rate:g} deg/s: the first look at the "
                                  f"pair failed ({error}); the final analysis will say more")
                return
            if not isinstance(look, FirstLook):
                raise TypeError(f"the first look answered a {type(look).__name__}")
            summary = look.summary
            ctx.run.memo[look.key] = look.analysis   # the final analysis reuses them
            ctx.run.memo.update(look.temperatures)
            ctx.run.write(msgspec.structs.replace(summary, axis=axis, unit=unit))
            ctx.progress.result(f"{axis} ±{rate:g} deg/s", *pair_figures(summary))

        ctx.worker.submit(pair_summary, str(ctx.run.path), ctx.cfg, axis, rate,
                          unit_halves(events, unit, ctx.run.session),
                          static_record(events, axis), on_done=done)

    def _do_stop(self, step: Step, ctx: RunContext) -> None:
        ctx.bench.rest(step.on_axis)

class LadderAnalysis:
    """result.json of a ladder run (the kind's `analysis` part)."""

    def analyze(self, run: RunDir, cfg: Config) -> KindResult[LadderBody]:
        import msgspec

        from bench.report.codec import KindResult
        from procedures.rate_ladder.analysis import analyze_run
        from procedures.rate_ladder.conditions import fog_temperatures
        from procedures.rate_ladder.result import ConditionsMeasured, FogTemperature

        # the body after the frame, then what the bench measured itself (the FOG's
        # temperature; none when no half recorded it)
        result = analyze_run(run, cfg)
        fog = fog_temperatures(run, cfg)
        return KindResult(result.head, msgspec.structs.replace(
            result.body, conditions_measured=ConditionsMeasured(
                FogTemperature(axes=fog) if fog else None)))


class RateLadder:
    """The rate ladder as a kind (bench/kind.py `Kind`): its parts, the heavy ones
    (numpy, the certificate, the records, the station's tables) imported when first
    used."""

    name = NAME
    settings = LadderFiles()
    steps = LadderSteps()
    plan = LadderPlan(steps.handlers)
    analysis = LadderAnalysis()

    @cached_property
    def certificate(self) -> LadderCertificate:
        from procedures.rate_ladder.certificate import LadderCertificate
        return LadderCertificate()

    @cached_property
    def dcc(self) -> DccParts:
        from procedures.rate_ladder.dcc import LadderDcc
        return LadderDcc()

    @cached_property
    def records(self) -> LadderRecords:
        from procedures.rate_ladder.records import LadderRecords
        return LadderRecords()

    @cached_property
    def station(self) -> LadderStation:
        from procedures.rate_ladder.station import LadderStation
        return LadderStation()


KIND: Kind = RateLadder()


def time_tie_record(counter: Counter, acq: Acquisition, fog: Fog
                    ) -> dict[str, str | float | None]:
    """The half's time tie as journaled (HalfAcquired.time_tie): the tie's settings, the
    sync pulse number behind the start (fog-sync), the arming time, and the FOG index
    convention, so the start can be placed again on the session's FOG axis."""
    tie = counter.time_tie
    rec: dict[str, str | float | None] = {**tie.as_record(), "t_start_s": acq.t_start_s,
                           "t_start_u_s": acq.t_start_u_s, "armed_at_s": acq.armed_at_s,
                           "fog_rate_hz": fog.rate_hz,
                           "fog_index_origin": "first frame received = index 0 = stand "
                                               "time 0 of this session"}
    if tie.uses_external_trigger:
        rec["sync_pulse"] = round((acq.t_start_s - tie.latency_s) / tie.sync_period_s)
        rec["fog_index_at_start"] = (acq.t_start_s - tie.latency_s) * fog.rate_hz
    return rec


def _fog_mean_dps(fog: Fog, span_s: float = 1.0) -> float | None:
    """The mean of the FOG's last `span_s` of valid samples (the live store keeps about a
    minute); None when there are none."""
    i_to = fog.end_index
    try:
        s = fog.samples(max(i_to - int(span_s * fog.rate_hz), 0), i_to)
    except ValueError:        # discarded or not yet arrived: nothing to show
        return None
    return float(s.rate_dps[s.valid].mean()) if s.valid.any() else None


def pair_figures(summary: PairLooked) -> list[Figure]:
    """A pair's first look (docs/method.md A3 k and ω0; eq. 1 δ per direction) with U (k = 2)."""
    out = [Figure("k", summary.k, summary.k_U),
           Figure("ω0", summary.w0_dps, summary.w0_U_dps, "°/s", signed=True)]
    for value, u, name in ((summary.rate_error_plus_rel, summary.rate_error_plus_U_rel, "δ(+)"),
                           (summary.rate_error_minus_rel, summary.rate_error_minus_U_rel,
                            "δ(−)")):
        if value is not None:
            out.append(Figure(name, value, u, RELATIVE, signed=True))
    return out


#: with no rate-error tolerance stated, the command may miss the rate by at most this
#: (1 ppm, the finest band of CONTRACT's example): the rate error is measured against it
COMMAND_RESOLUTION_REL_MAX = 1e-6


def uncommandable_rates(cfg: Config, bench: Bench) -> list[str]:
    """Rates the drive, in the units it reported at connect, cannot be told exactly enough.

    The rate error (docs/method.md A2, eq. 1) is taken against the commanded rate: a
    command rounded to a coarse unit (1 rpm = 6 deg/s: 100 deg/s is sent as 102) would be
    certified as a table error. Refused before anything moves when the rounding exceeds a
    tenth of the rate-error tolerance at that rate, or COMMAND_RESOLUTION_REL_MAX."""
    ladder = LadderSettings.from_config(cfg)   # no axes: `bench devices`, a stand alone
    bands = ladder.tolerance.get("rate_error")
    out: list[str] = []
    for axis, spec in ladder.axes.items():
        if axis not in bench.axes:
            continue
        drive = bench.axes[axis].drive
        for rate in spec.rates_dps:
            sent = drive.units.velocity_to_dps(
                drive.units.dps_to_velocity(rate, limit_dps=drive.max_rate_dps))
            off_rel = abs(sent - rate) / rate
            tol = tolerance_for(bands, rate)
            limit = 0.1 * tol if tol else COMMAND_RESOLUTION_REL_MAX
            if off_rel > limit:
                step = drive.units.velocity_to_dps(1)
                out.append(f"axis {axis}: {rate:g} deg/s cannot be commanded in the drive's "
                           f"velocity unit ({step:.6g} deg/s, read from 0x60A9 at connect): "
                           f"it would be sent as {sent:.9g} deg/s, {off_rel:.2g} off, more "
                           f"than {limit:.2g}; set a finer unit (stand key "
                           f"axes.{axis}.drive.unit_factors.velocity) or another rate")
    return out
