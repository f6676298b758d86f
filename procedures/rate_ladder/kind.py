"""The +/-w rate ladder of METHOD.md part A (seed 000), as a procedure kind.

Per axis: a record of the FOG at rest (its noise floor, METHOD.md A5); then for each rate
magnitude the halves of a +/- pair, by default in the order +w, -w, +w with the turns of
the + direction split around the - half, so a linear FOG bias drift cancels in the
cross-calibration (METHOD.md A3, "beyond the paper"); each half: set the rate, settle,
time N whole turns with the counter while the FOG streams; then cross-calibrate and
analyze the pair.
"""

from __future__ import annotations

import math
from typing import Any

from bench.analysis.window import HalfRecord
from bench.config import STEP_MAX_S, Config, check_axis_names, stand_schema
from bench.engine import Abort, RunContext
from bench.instruments import DEFAULT_FOG_RANGE_DPS, Bench, abandon, open_axis
from bench.journal import RunDir
from bench.plan import Plan, Step, format_duration
from bench.schema import Map
from bench.simbench import SimBench
from bench.yamlfile import Problem
from drivers.clock import Clock
from procedures.base import StepDispatch
from procedures.rate_ladder.analysis import analyze_run, pair_summary
from procedures.rate_ladder.settings import NAME, PROCEDURE, SETTLE_DEFAULTS, halves, setting


class RateLadder(StepDispatch):
    name = NAME

    # -- files -----------------------------------------------------------------------
    def procedure_schema(self) -> Map:
        return PROCEDURE

    def stand_schema(self) -> Map:
        return stand_schema()

    def cross_check(self, cfg: Config) -> list[Problem]:
        out = check_axis_names(cfg)
        pdoc, sdoc = cfg.procedure_doc, cfg.stand_doc
        accel = cfg.procedure.get("accel_dps2")
        for axis, spec in cfg.procedure["axes"].items():
            if axis not in cfg.stand["axes"]:
                continue
            stand_axis = cfg.stand["axes"][axis]
            drive = stand_axis["drive"]
            fog = stand_axis.get("fog")
            for what in ("counter", "fog"):
                if not stand_axis.get(what):
                    out.append(sdoc.problem(("axes", axis), f"the rate ladder needs a {what} "
                                                            f"on axis {axis!r}"))
            counter = stand_axis.get("counter")
            if counter and "level_v" not in counter and not cfg.has_sim:
                # the counter refuses to arm without it; say so before anything moves
                out.append(sdoc.problem(("axes", axis, "counter"), "missing level_v: a real "
                                        "stand needs an absolute trigger level in volts (a "
                                        "once-per-rev pulse is too slow for auto-level)"))
            fog_range = (fog or {}).get("range_dps", DEFAULT_FOG_RANGE_DPS)
            turns = int(spec.get("turns", setting(cfg, "turns")))
            for i, rate in enumerate(spec["rates_dps"]):
                where = ("axes", axis, "rates_dps", i)
                if (turns + 1) * 360.0 / rate > STEP_MAX_S:
                    out.append(pdoc.problem(where, f"{turns} turns at {rate:g} deg/s take "
                               f"{format_duration(turns * 360.0 / rate)} of bench time per "
                               f"direction (more than {format_duration(STEP_MAX_S)})"))
                if rate > drive["max_rate_dps"]:
                    out.append(pdoc.problem(where, f"{rate:g} deg/s exceeds axis {axis!r}'s "
                               f"max_rate_dps {drive['max_rate_dps']:g} "
                               f"({sdoc.path}:{sdoc.line(('axes', axis, 'drive'))})"))
                if fog and rate > fog_range:
                    out.append(pdoc.problem(where, f"{rate:g} deg/s exceeds the FOG's range "
                                                   f"{fog_range:g} deg/s on axis {axis!r}"))
            if accel is not None and accel > drive["max_accel_dps2"]:
                out.append(pdoc.problem(("accel_dps2",), f"{accel:g} deg/s^2 exceeds axis "
                           f"{axis!r}'s max_accel_dps2 {drive['max_accel_dps2']:g}"))
            if fog:
                mains = cfg.stand.get("sim", {}).get("axes", {}).get(axis, {}).get("mains")
                if mains and 2 * mains.get("frequency_hz", 50) >= fog["rate_hz"]:
                    out.append(sdoc.problem(("axes", axis, "fog", "rate_hz"),
                                            "the FOG rate must exceed twice the mains frequency"))
        for name in ("rate_error", "rate_instability", "intra_turn_instability"):
            bands = cfg.procedure.get("tolerance", {}).get(name)
            if bands and "below_dps" in bands[-1]:
                out.append(pdoc.problem(("tolerance", name, len(bands) - 1),
                                        "the last band must have no below_dps (it covers "
                                        "every rate above the others)"))
        return out

    # -- plan ------------------------------------------------------------------------
    def accel(self, cfg: Config, axis: str) -> float:
        limit = cfg.stand["axes"][axis]["drive"]["max_accel_dps2"]
        return min(cfg.procedure.get("accel_dps2", limit), limit)

    def settle(self, cfg: Config) -> dict[str, float]:
        return {**SETTLE_DEFAULTS, **cfg.procedure.get("settle", {})}

    def build_plan(self, cfg: Config) -> Plan:
        steps: list[Step] = []
        settle = self.settle(cfg)
        static_s = float(setting(cfg, "static_record_s"))
        for axis, spec in cfg.procedure["axes"].items():
            turns = int(spec.get("turns", setting(cfg, "turns")))
            accel = self.accel(cfg, axis)
            if setting(cfg, "prompts"):
                text = spec.get("prompt") or (
                    f"Mount the FOG on the {axis} axis (sensitive axis along the table axis), "
                    f"connect the {axis} zero-mark sensor to the counter")
                steps.append(Step("prompt", axis, text))
            if static_s > 0:
                steps.append(Step("static", axis, f"FOG at rest for {static_s:g} s (noise floor, "
                                  "METHOD.md A5)", static_s, f"{axis}/static",
                                  {"duration_s": static_s}))
            steps.append(Step("enable", axis, "drive to Operation Enabled, profile velocity",
                              1.0))
            rate_now = 0.0
            for rate in spec["rates_dps"]:
                unit = f"{axis}/{rate:g}dps"
                parts = halves(turns, setting(cfg, "sequence"))
                for j, (sign, n) in enumerate(parts):
                    target = sign * rate
                    steps.append(Step("set_rate", axis, f"{target:+g} deg/s",
                                      abs(target - rate_now) / accel, unit,
                                      {"rate_dps": target, "accel_dps2": accel}))
                    tol = max(settle["tolerance_dps"], settle["tolerance_rel"] * rate)
                    steps.append(Step("settle", axis, f"within {tol:.3g} deg/s for "
                                      f"{settle['hold_s']:g} s", settle["hold_s"] + 0.5, unit,
                                      {"tolerance_dps": tol, "hold_s": settle["hold_s"],
                                       "timeout_s": settle["timeout_s"]}))
                    period = 360.0 / rate
                    steps.append(Step("acquire", axis, f"{n} turns at {target:+g} deg/s "
                                      f"(half {j + 1}/{len(parts)}, "
                                      f"{format_duration(n * period)})",
                                      (n + 1) * period, unit,
                                      {"rate_dps": target, "turns": n, "half": j,
                                       "period_s": period}))
                    rate_now = target
                steps.append(Step("analyze", axis, f"cross-calibrate and analyze the "
                                  f"+/-{rate:g} deg/s pair", 0.0, unit, {"rate_dps": rate}))
            steps.append(Step("stop", axis, "ramp to zero, disable", abs(rate_now) / accel,
                              None, {"accel_dps2": accel}))
        title = cfg.procedure.get("title", cfg.procedure_path.stem)
        return Plan(title, tuple(steps))

    # -- bench -----------------------------------------------------------------------
    def axes(self, cfg: Config) -> list[str]:
        """The procedure's axes (every axis of the stand for `bench devices`)."""
        return list(cfg.procedure.get("axes") or cfg.stand["axes"])

    def start_sim(self, cfg: Config) -> tuple[SimBench, dict[str, Any]]:
        sim = SimBench(cfg.stand, self.axes(cfg))
        return sim, sim.start()

    def open_bench(self, cfg: Config, stand: dict[str, Any], clock: Clock,
                   run: RunDir | None) -> Bench:
        bench = Bench()
        try:
            for axis in self.axes(cfg):
                open_axis(bench, axis, stand["axes"], clock, run)
        except BaseException as e:
            abandon(bench, e)
            raise
        return bench

    # -- steps (each action is a `_do_<action>` method) --------------------------------
    def _do_enable(self, step: Step, ctx: RunContext) -> None:
        ctx.bench.axes[step.axis].drive.enable()

    def _do_static(self, step: Step, ctx: RunContext) -> None:
        ax = ctx.bench.axes[step.axis]
        fog = ax.fog
        duration = step.params["duration_s"]
        i0 = max(fog.end_index, math.ceil(ctx.clock.now() * fog.rate_hz))
        n = int(round(duration * fog.rate_hz))
        self._wait_fog(ctx, fog, i0 + n, duration, f"{step.axis}: FOG at rest")
        s = fog.samples(i0, i0 + n)
        ctx.state.setdefault("live", {})[step.unit] = s.rate_dps[s.valid]
        ctx.run.event("static", axis=step.axis, unit=step.unit, fog_from=i0, fog_to=i0 + n,
                      rate_hz=fog.rate_hz, lost=int(n - s.valid.sum()))

    def _wait_fog(self, ctx: RunContext, fog: Any, index: int, span_s: float, label: str) -> None:
        t_end = ctx.clock.now() + span_s
        while True:
            left = t_end - ctx.clock.now()
            ctx.progress.detail(f"  {label}: {max(left, 0):.0f} s left")
            if left <= 0:
                break
            ctx.clock.sleep(min(left, max(span_s / 20, 0.5)))
            for ax in ctx.bench.axes.values():
                ax.drive.check()
        fog.wait_for_index(index, timeout_s=max(5.0, span_s * 0.2))

    def _do_set_rate(self, step: Step, ctx: RunContext) -> None:
        drive = ctx.bench.axes[step.axis].drive
        drive.set_rate(step.params["rate_dps"], step.params["accel_dps2"])

    def _do_settle(self, step: Step, ctx: RunContext) -> None:
        drive = ctx.bench.axes[step.axis].drive
        p = step.params
        rate = drive.wait_settled(p["tolerance_dps"], p["hold_s"], p["timeout_s"])
        ctx.run.event("settled", axis=step.axis, unit=step.unit, rate_dps=rate)

    def _do_acquire(self, step: Step, ctx: RunContext) -> None:
        ax = ctx.bench.axes[step.axis]
        p = step.params
        n = p["turns"]
        period = p["period_s"]
        counter, fog, drive = ax.counter, ax.fog, ax.drive
        rec0 = ax.logs["counter"].count if "counter" in ax.logs else 0
        counter.arm(n + 1, period)
        t_arm = ctx.clock.now()
        t_end = t_arm + (n + 1) * period
        while (left := t_end - ctx.clock.now()) > 0:
            turn = min(n, int((ctx.clock.now() - t_arm) / period))
            ctx.progress.detail(f"  {step.axis} {p['rate_dps']:+g} deg/s: turn {turn}/{n}, "
                                f"{format_duration(left)} of this half left")
            ctx.clock.sleep(min(left, max(period / 4, 0.25)))
            drive.check()
        edges = counter.fetch()
        acq = counter.last_acquisition
        if len(edges) != n + 1:
            raise Abort(f"{step.axis}: the counter returned {len(edges)} edges, expected {n + 1}")
        # the FOG samples that bracket the timed turns (the analysis integrates exactly
        # from the first edge to the last, interpolating between samples)
        i_from = math.floor(edges[0] * fog.rate_hz)
        i_to = math.floor(edges[-1] * fog.rate_hz) + 2
        rec1 = ax.logs["counter"].count if "counter" in ax.logs else 0
        fog.wait_for_index(i_to, timeout_s=max(10.0, period))
        s = fog.samples(i_from, i_to)
        lost = int(s.valid.size - s.valid.sum())
        ctx.state.setdefault("live", {}).setdefault(step.unit, []).append(
            HalfRecord(1 if p["rate_dps"] > 0 else -1, edges, s.t_s[s.valid],
                       s.rate_dps[s.valid]))
        ctx.run.event("acquire", axis=step.axis, unit=step.unit, half=p["half"],
                      set_rate_dps=p["rate_dps"], turns=n, edges_s=[float(e) for e in edges],
                      counter_t0_s=acq.t_start_s, counter_t0_u_s=acq.t_start_u_s,
                      counter_records=[rec0, rec1], fog_from=i_from, fog_to=i_to,
                      rate_hz=fog.rate_hz, fog_lost=lost)
        if lost:
            ctx.progress.line(f"  WARNING {step.axis}: {lost} FOG samples lost in this half "
                              "(CRC or sequence gaps); the analysis uses the rest")
        w = 360.0 * n / (edges[-1] - edges[0])
        ctx.progress.line(f"  {step.axis} {p['rate_dps']:+g} deg/s: {n} turns timed, "
                          f"mean {math.copysign(w, p['rate_dps']):+.7f} deg/s")

    def _do_analyze(self, step: Step, ctx: RunContext) -> None:
        summary = pair_summary(ctx, step.axis, step.unit, step.params["rate_dps"])
        ctx.run.event("pair", axis=step.axis, unit=step.unit, **summary)
        ctx.progress.line(f"  {step.axis} +/-{step.params['rate_dps']:g} deg/s: "
                          + ", ".join(f"{k} {v:.6g}" for k, v in summary.items()
                                      if isinstance(v, float)))
        live = ctx.state.get("live", {})
        live.pop(step.unit, None)
        fog = ctx.bench.axes[step.axis].fog
        fog.discard_before(fog.end_index)

    def _do_stop(self, step: Step, ctx: RunContext) -> None:
        drive = ctx.bench.axes[step.axis].drive
        drive.stop()
        drive.disable()

    # -- analysis --------------------------------------------------------------------
    def analyze(self, run: RunDir, cfg: Config) -> dict[str, Any]:
        return analyze_run(run, cfg)


KIND = RateLadder()
