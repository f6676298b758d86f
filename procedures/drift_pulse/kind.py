"""Gyro drift by alternating-sign pulses (docs/method.md B, seed 004), as a procedure kind.

The gyro platform sits on a turntable axis of the stand. At each turntable position
(0 and 180 deg by default) the bench runs N cycles; in each, one bus trigger makes the
waveform generator play the +/- pulse pair into every gyro's torque sensor at once and,
through its trigger output, starts every gyro's digitizing DMM on the angle sensor, in
step with the pulses. The first position begins with a few large-amplitude timing
cycles, which only locate the pulses in the records (the digitizer's start offset: the
half-sample pitfall of docs/method.md B); the drift comes from the measuring cycles. Between
positions the drive turns the platform in profile position mode (CiA 402, 0x6060 = 1).

Timing, so that samples lie on the pulse edges: the generator's sample rate divides the
DMM's, the waveform starts with one zero point (so the record begins before the first
edge) and the DMM's trigger delay is one interval minus half its aperture, so the middle
of every integrating reading falls on the sample grid of the pulse edges.

Units of resumption: every cycle. A turn is absolute (`move_to`), so repeating it on a
resumed run is harmless. The analysis reads the DMMs' raw SCPI replies back from the run
directory (`bench analyze` recomputes everything from them).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from bench.analysis import drift_pulse as dp
from bench.config import (
    CALIBRATION,
    COMMON_PROCEDURE_KEYS,
    IDENTITY,
    Config,
    StandSettings,
    stand_schema,
)
from bench.conformity import judge
from bench.engine import Abort, RunContext
from bench.instruments import Bench, manual_note, open_axis, raw_text_logger, with_readback
from bench.journal import RunDir, read_jsonl
from bench.plan import Plan, Step
from bench.progress import Figure
from bench.schema import Key, ListOf, Map, MapOf, Num, Str
from bench.simbench import SIM_GYRO_KEYS, SimBench, gyro_rig_factory
from bench.yamlfile import Problem
from drivers.awg import PROFILES as AWG_PROFILES
from drivers.awg import WaveformGenerator
from drivers.clock import Clock
from drivers.dmm import PROFILES as DMM_PROFILES
from drivers.dmm import Digitizer
from drivers.scpi import parse_numbers
from procedures.base import StepDispatch, result_document
from procedures.drift_pulse.certificate import DriftCertificate

NAME = "drift-pulse"
GYRO_NAMES = ("x", "y", "z")

# -- files ------------------------------------------------------------------------------

PULSE = Map({
    "shape": Key(Str(tuple(dp.SHAPES)), True, "rectangular, triangular (or sawtooth)"),
    "duration_s": Key(Num(min=0, exclusive_min=True, unit="s"), True, "Tc, each pulse"),
    "amplitude_v": Key(Num(min=0, exclusive_min=True, unit="V"), True,
                       "peak voltage into the torque-sensor current amplifier"),
    "points": Key(Num(min=4, max=500_000, integer=True), False,
                  "waveform points per pulse (default 1000)"),
})
DIGITIZER = Map({
    "sample_rate_hz": Key(Num(min=0, exclusive_min=True, unit="Hz"), False, "default 2000"),
    "aperture_s": Key(Num(min=0, exclusive_min=True, unit="s"), False,
                      "default 0.8 of the interval"),
    "range_v": Key(Num(min=0, exclusive_min=True, unit="V"), False, "default 10"),
    "margin_s": Key(Num(min=0, unit="s"), False, "recorded after the pair (default 0.05)"),
})
TURN = Map({
    "rate_dps": Key(Num(min=0, exclusive_min=True, unit="deg/s"), True),
    "accel_dps2": Key(Num(min=0, exclusive_min=True, unit="deg/s^2"), True),
})
PROCEDURE = Map({
    **COMMON_PROCEDURE_KEYS,
    "site": Key(Map({"latitude_deg": Key(Num(min=-90, max=90, unit="deg"), True),
                     "name": Key(Str())}), True),
    "pulse": Key(PULSE, True),
    "cycles": Key(Num(min=4, max=10_000, integer=True), False,
                  "measuring cycles per position (default 10; 4 at least for the scatter)"),
    "timing_cycles": Key(Num(min=0, max=1000, integer=True), False,
                         "large-amplitude cycles that locate the pulses (default 4)"),
    "timing_amplitude_v": Key(Num(min=0, exclusive_min=True, unit="V"), False,
                              "default 8 x the pulse amplitude, within the DMM range"),
    "positions_deg": Key(ListOf(Num(min=-360, max=360, unit="deg"), min_len=2), False,
                         "turntable positions (default [0, 180])"),
    "gap_s": Key(Num(min=0, unit="s"), False, "pause between cycles (default 0.5)"),
    "settle_s": Key(Num(min=0, unit="s"), False, "pause after a turn (default 5)"),
    "turn": Key(TURN, False, "default: the drive's max rate and acceleration"),
    "digitizer": Key(DIGITIZER),
    "gyros": Key(ListOf(Str(GYRO_NAMES), min_len=1), False,
                 "which of the platform's gyros (default: all)"),
    "tolerance": Key(Map({"own_drift_dph": Key(Num(min=0, exclusive_min=True, unit="deg/h"))})),
})

GYRO = Map({
    "model": Key(Str(), False, "the gyro's model (printed as part of the item calibrated)"),
    "serial": Key(Str(), False, "the gyro's serial number (printed as part of the item)"),
    "awg_channel": Key(Num(min=1, max=4, integer=True), True),
    "dmm": Key(Map({"resource": Key(Str(), True, "VISA resource string"),
                    "model": Key(Str(tuple(DMM_PROFILES)), True),
                    "calibration": Key(CALIBRATION, False, "the DMM's certificate")}), True),
    "k_as_v_per_deg": Key(Num(min=0, exclusive_min=True, unit="V/deg"), True,
                          "the command angle sensor's transfer coefficient"),
    "k_as_u_rel": Key(Num(min=0), False, "its standard uncertainty, relative"),
    "precession_dps_per_v": Key(Num(min=0, exclusive_min=True, unit="deg/s per V"), True,
                                "nominal k_ts * gain / H (range checks only)"),
    "pulse_mismatch_max_rel": Key(Num(min=0), False, "bound of the +/- amplitude mismatch"),
    "drift_random_walk_dph_per_rth": Key(Num(min=0), False, "the gyro's spec"),
})
PLATFORM = Map({
    "identity": Key(IDENTITY, False, "the platform under test"),
    "table_axis": Key(Str(), True, "the stand axis the platform sits on"),
    "awg": Key(Map({"resource": Key(Str(), True),
                    "model": Key(Str(tuple(AWG_PROFILES)), True),
                    "calibration": Key(CALIBRATION, False, "the generator's certificate")}),
               True),
    "gyros": Key(MapOf(GYRO, min_len=1), True),
})
SIM_PLATFORM = Map({
    "latitude_deg": Key(Num(min=-90, max=90), True),
    "azimuth_deg": Key(Num(), True, "the X input axis at turntable 0, from north"),
    "gyros": Key(MapOf(Map({k: Key(Num()) for k in SIM_GYRO_KEYS})), True),
})
SIM_AWG = Map({"output_latency_s": Key(Num(min=0)), "trigger_out_skew_s": Key(Num()),
               "trigger_out_width_s": Key(Num(min=0)), "load_ohm": Key(Num(min=1)),
               "serial": Key(Str(), False, "the serial the twin reports (*IDN? field 3)")})
SIM_DMM = Map({"trigger_latency_s": Key(Num(min=0)),
               "serials": Key(MapOf(Str()), False, "gyro: the serial its DMM twin reports")})

DEFAULTS: dict[str, Any] = {"cycles": 10, "timing_cycles": 4, "positions_deg": [0.0, 180.0],
                            "gap_s": 0.5, "settle_s": 5.0, "decision_rule": "simple",
                            "prompts": True}
DIGITIZER_DEFAULTS = {"sample_rate_hz": 2000.0, "range_v": 10.0, "margin_s": 0.05}
DEFAULT_POINTS = 1000
TIMING_GAIN = 8.0
#: real-bench seconds a cycle costs beyond its record: arming, transfer, SCPI checks
CYCLE_OVERHEAD_S = 0.5
#: how far the turn may land from its angle when the stand file does not say
DEFAULT_POSITION_TOLERANCE_DEG = 0.01


def setting(cfg: Config, key: str) -> Any:
    return cfg.procedure.get(key, DEFAULTS.get(key))


@dataclass(frozen=True)
class Timing:
    """Where the samples are against the pulses, from the procedure's settings."""

    tc_s: float
    points: int                  # generator points per pulse
    awg_rate_hz: float
    interval_s: float
    aperture_s: float
    range_v: float
    count: int                   # DMM samples per cycle
    trigger_delay_s: float
    lead_points: int = 1

    @property
    def lead_s(self) -> float:
        return self.lead_points / self.awg_rate_hz

    @property
    def first_sample_s(self) -> float:
        """Sample 0's middle, from the first pulse edge (on the grid of the edges)."""
        return self.trigger_delay_s + 0.5 * self.aperture_s - self.lead_s

    @property
    def record_s(self) -> float:
        return self.trigger_delay_s + self.count * self.interval_s

    @classmethod
    def of(cls, cfg: Config) -> Timing:
        p = cfg.procedure["pulse"]
        d = {**DIGITIZER_DEFAULTS, **cfg.procedure.get("digitizer", {})}
        tc = float(p["duration_s"])
        points = int(p.get("points", DEFAULT_POINTS))
        interval = 1.0 / float(d["sample_rate_hz"])
        aperture = float(d.get("aperture_s", 0.8 * interval))
        lead_s = 1.0 / (points / tc)
        count = int(math.ceil((2 * tc + lead_s + float(d["margin_s"])) / interval)) + 1
        return cls(tc, points, points / tc, interval, aperture, float(d["range_v"]), count,
                   max(interval - 0.5 * aperture, 0.0))


def _near_int(x: float) -> bool:
    return abs(x - round(x)) < 1e-6 * max(1.0, abs(x))


class DriftPulse(StepDispatch, DriftCertificate):
    name = NAME

    def procedure_schema(self) -> Map:
        return PROCEDURE

    def stand_schema(self) -> Map:
        return stand_schema(extra_top={"platform": Key(PLATFORM, True)},
                            extra_sim={"platform": Key(SIM_PLATFORM), "awg": Key(SIM_AWG),
                                       "dmm": Key(SIM_DMM)})

    # -- checks that need both files --------------------------------------------------
    def gyros(self, cfg: Config) -> list[str]:
        return list(cfg.procedure.get("gyros") or cfg.stand["platform"]["gyros"])

    def cross_check(self, cfg: Config) -> list[Problem]:
        pdoc, sdoc = cfg.procedure_doc, cfg.stand_doc
        plat = cfg.stand["platform"]
        out: list[Problem] = []
        table = plat["table_axis"]
        if table not in cfg.stand["axes"]:
            out.append(sdoc.problem(("platform", "table_axis"), f"the stand has no axis "
                                    f"{table!r} (it has {', '.join(cfg.stand['axes'])})"))
        for g in plat["gyros"]:
            if g not in GYRO_NAMES:
                out.append(sdoc.problem(("platform", "gyros", g), "a gyro is x, y "
                                        "(horizontal) or z (vertical)"))
        for i, g in enumerate(cfg.procedure.get("gyros") or []):
            if g not in plat["gyros"]:
                out.append(pdoc.problem(("gyros", i), f"the stand's platform has no gyro {g!r}"))
        awg = AWG_PROFILES[plat["awg"]["model"]]
        channels: dict[int, str] = {}
        for g, spec in plat["gyros"].items():
            ch = spec["awg_channel"]
            if ch not in awg.channels:
                out.append(sdoc.problem(("platform", "gyros", g, "awg_channel"),
                                        f"the {awg.model} has channels {awg.channels}"))
            if ch in channels:
                out.append(sdoc.problem(("platform", "gyros", g, "awg_channel"),
                                        f"channel {ch} already drives gyro {channels[ch]}"))
            channels[ch] = g
        out += self._check_timing(cfg)
        out += self._check_positions(cfg)
        lat = cfg.procedure["site"]["latitude_deg"]
        if abs(lat) > 84.0:
            out.append(pdoc.problem(("site", "latitude_deg"), "within 6 deg of a pole the "
                                    "Earth's horizontal rate is too small for an azimuth"))
        if table in cfg.stand["axes"]:
            drive = cfg.stand["axes"][table]["drive"]
            turn = cfg.procedure.get("turn", {})
            for key, limit in (("rate_dps", "max_rate_dps"), ("accel_dps2", "max_accel_dps2")):
                if key in turn and turn[key] > drive[limit]:
                    out.append(pdoc.problem(("turn", key), f"{turn[key]:g} exceeds the drive's "
                                            f"{limit} {drive[limit]:g}"))
        sim = cfg.stand.get("sim")
        if sim is not None:
            sp = sim.get("platform")
            if sp is None:
                out.append(sdoc.problem(("sim",), "a simulated drift-pulse bench needs "
                                        "sim.platform (the platform's truth)"))
            else:
                for g in self.gyros(cfg):
                    if g not in sp["gyros"]:
                        out.append(sdoc.problem(("sim", "platform", "gyros"),
                                                f"no truth for gyro {g!r}"))
        return out

    def _check_timing(self, cfg: Config) -> list[Problem]:
        pdoc, sdoc = cfg.procedure_doc, cfg.stand_doc
        plat = cfg.stand["platform"]
        t = Timing.of(cfg)
        out = []
        where = ("digitizer",)
        if not _near_int(t.tc_s / t.interval_s):
            out.append(pdoc.problem(("pulse", "duration_s"), f"Tc = {t.tc_s:g} s is not a whole "
                                    f"number of DMM intervals ({t.interval_s:g} s): the pulse "
                                    f"edges must fall on samples (docs/method.md B)"))
        if not _near_int(t.tc_s / t.interval_s / t.points):
            out.append(pdoc.problem(("pulse", "points"), f"{t.points} points per pulse: the "
                                    f"generator's step ({1 / t.awg_rate_hz:g} s) must be a whole "
                                    f"number of DMM intervals ({t.interval_s:g} s)"))
        awg = AWG_PROFILES[plat["awg"]["model"]]
        lo, hi = awg.sample_rate_range_hz
        if not lo <= t.awg_rate_hz <= hi or 2 * t.points + 2 > awg.max_points:
            out.append(pdoc.problem(("pulse", "points"), f"{t.points} points in {t.tc_s:g} s do "
                                    f"not fit the {awg.model} ({awg.max_points} points, "
                                    f"{lo:g} .. {hi:g} Sa/s)"))
        amps = {"amplitude_v": cfg.procedure["pulse"]["amplitude_v"]}
        if setting(cfg, "timing_cycles"):
            amps["timing_amplitude_v"] = self.timing_amplitude(cfg)
        shape = dp.pulse_shape(cfg.procedure["pulse"]["shape"])
        for g in self.gyros(cfg):
            spec = plat["gyros"].get(g)
            if spec is None:
                continue
            dmm = DMM_PROFILES[spec["dmm"]["model"]]
            if not any(math.isclose(t.range_v, r) for r in dmm.ranges_v):
                out.append(pdoc.problem(where + ("range_v",), f"the {dmm.model} has ranges "
                                        f"{', '.join(f'{r:g}' for r in dmm.ranges_v)} V"))
            if t.interval_s < max(dmm.min_interval_s, t.aperture_s + dmm.interval_overhead_s):
                out.append(pdoc.problem(where, f"the aperture {t.aperture_s:g} s does not fit "
                                        f"the interval {t.interval_s:g} s on the {dmm.model}"))
            if t.count > dmm.max_readings:
                out.append(pdoc.problem(("pulse", "duration_s"), f"{t.count} samples a cycle "
                                        f"exceed the {dmm.model}'s {dmm.max_readings} readings"))
            for key, amp in amps.items():
                excursion = (spec["k_as_v_per_deg"] * spec["precession_dps_per_v"] * amp
                             * t.tc_s * shape.angle_end)
                if excursion > 0.8 * t.range_v:
                    out.append(pdoc.problem(("pulse", key) if key == "amplitude_v" else (key,),
                               f"gyro {g}: the pulse pair swings the angle sensor by "
                               f"{excursion:.3g} V (k_as x precession x amplitude x Tc), over "
                               f"0.8 of the DMM's {t.range_v:g} V range "
                               f"({sdoc.path}:{sdoc.line(('platform', 'gyros', g))})"))
        return out

    def _check_positions(self, cfg: Config) -> list[Problem]:
        pos = [float(p) for p in setting(cfg, "positions_deg")]
        theta = np.radians(pos)
        a = np.column_stack([np.ones_like(theta), np.cos(theta)]
                            + ([-np.sin(theta)] if np.any(np.abs(np.sin(theta)) > 1e-9) else []))
        if np.linalg.matrix_rank(a) < a.shape[1] or len({round(p % 360, 6) for p in pos}) < 2:
            return [cfg.procedure_doc.problem(("positions_deg",), "the positions must separate "
                                              "own and apparent drift: include two 180 deg "
                                              "apart (e.g. [0, 180])")]
        return []

    def timing_amplitude(self, cfg: Config) -> float:
        return float(cfg.procedure.get("timing_amplitude_v",
                                        TIMING_GAIN * cfg.procedure["pulse"]["amplitude_v"]))

    # -- plan -----------------------------------------------------------------------------
    def table(self, cfg: Config) -> str:
        return cfg.stand["platform"]["table_axis"]

    def turn(self, cfg: Config) -> tuple[float, float]:
        drive = cfg.stand["axes"][self.table(cfg)]["drive"]
        t = cfg.procedure.get("turn", {})
        return (float(t.get("rate_dps", drive["max_rate_dps"])),
                float(t.get("accel_dps2", drive["max_accel_dps2"])))

    def build_plan(self, cfg: Config) -> Plan:
        t = Timing.of(cfg)
        table = self.table(cfg)
        gyros = self.gyros(cfg)
        gap = float(setting(cfg, "gap_s"))
        cycle_s = t.record_s + gap + CYCLE_OVERHEAD_S
        rate, accel = self.turn(cfg)
        shape = cfg.procedure["pulse"]["shape"]
        steps: list[Step] = []
        if setting(cfg, "prompts"):
            steps.append(Step("prompt", None, "Level the platform; switch the gyros' torque "
                              "sensors to the pulse generator (correction loops open); connect "
                              "each angle sensor to its DMM and the generator's trigger output "
                              "to every DMM's Ext Trig input"))
        steps.append(Step("setup", None, f"{shape} pairs of 2 x {t.tc_s:g} s on gyros "
                          f"{', '.join(gyros)}; DMMs: {t.count} samples at "
                          f"{1 / t.interval_s:g} Sa/s, aperture {t.aperture_s * 1e3:g} ms",
                          2.0, None, {}))
        at = None
        for k, pos in enumerate(float(p) for p in setting(cfg, "positions_deg")):
            turn_s = (abs(pos - at) / rate + rate / accel) if at is not None else \
                abs(pos) / rate + rate / accel
            steps.append(Step("turn", table, f"platform to {pos:g} deg (profile position)",
                              turn_s, None, {"position_deg": pos, "rate_dps": rate,
                                             "accel_dps2": accel}))
            settle = float(setting(cfg, "settle_s"))
            if settle:
                steps.append(Step("settle", table, f"{settle:g} s for the platform to settle",
                                  settle, None, {"duration_s": settle}))
            at = pos
            timing = int(setting(cfg, "timing_cycles")) if k == 0 else 0
            for i in range(timing):
                steps.append(Step("cycle", table, f"timing cycle {i + 1}/{timing} at {pos:g} "
                                  f"deg ({self.timing_amplitude(cfg):g} V)", cycle_s,
                                  f"timing/{i + 1}",
                                  {"position_deg": pos, "timing": True, "index": i + 1}))
            n = int(setting(cfg, "cycles"))
            for i in range(n):
                steps.append(Step("cycle", table, f"cycle {i + 1}/{n} at {pos:g} deg", cycle_s,
                                  f"{pos:g}deg/{i + 1}",
                                  {"position_deg": pos, "timing": False, "index": i + 1}))
        steps.append(Step("stop", table, "pulse outputs off; turntable to rest, disabled", 2.0))
        return Plan(cfg.procedure.get("title", cfg.procedure_path.stem), tuple(steps))

    # -- bench ----------------------------------------------------------------------------
    def start_sim(self, cfg: Config) -> tuple[SimBench, StandSettings]:
        sim = SimBench(cfg.stand_settings, [self.table(cfg)])
        return sim, sim.start(extra=[gyro_rig_factory(cfg.stand, self.gyros(cfg))])

    def open_bench(self, cfg: Config, stand: StandSettings, clock: Clock,
                   run: RunDir | None) -> Bench:
        bench = Bench()
        plat = cfg.stand["platform"]

        def raw(name: str) -> Any:
            return raw_text_logger(bench.log(run.raw_path(name)), clock) if run else None

        try:
            table = plat["table_axis"]
            open_axis(bench, stand.axes[table], clock, run, counter=False, fog=False)
            awg = WaveformGenerator.open(
                stand.address("platform.awg.resource", plat["awg"]["resource"]),
                plat["awg"]["model"], clock, raw=raw("awg.jsonl"))
            bench.enter(awg)
            bench.extra["awg"] = awg
            bench.extra["dmms"] = {}
            for g in self.gyros(cfg):
                d = plat["gyros"][g]["dmm"]
                dmm = Digitizer.open(
                    stand.address(f"platform.gyros.{g}.dmm.resource", d["resource"]),
                    d["model"], clock, raw=raw(f"{g}-dmm.jsonl"))
                bench.enter(dmm)
                bench.extra["dmms"][g] = dmm
            bench.axes[table].identities["awg"] = with_readback(
                awg.identify(), {}, manual_note(awg.profile.manual))
            for g, dmm in bench.extra["dmms"].items():
                bench.axes[table].identities[f"{g}-dmm"] = with_readback(
                    dmm.identify(), {}, manual_note(dmm.profile.manual))
        except BaseException as e:
            bench.abandon(e)
            raise
        return bench

    # -- steps (each action is a `_do_<action>` method) -----------------------------------
    def _do_setup(self, step: Step, ctx: RunContext) -> None:
        t = Timing.of(ctx.cfg)
        for g, dmm in ctx.bench.extra["dmms"].items():
            setup = dmm.configure(t.range_v, t.aperture_s, t.interval_s, t.count,
                                  trigger_delay_s=t.trigger_delay_s)
            ctx.run.event("dmm_setup", gyro=g, **setup.__dict__)
        ctx.state["fetches"] = {g: 0 for g in ctx.bench.extra["dmms"]}
        ctx.state["loaded_v"] = None

    def _load(self, ctx: RunContext, amplitude_v: float) -> None:
        """(Re)load the pair on every gyro's channel at this amplitude."""
        if ctx.state.get("loaded_v") == amplitude_v:
            return
        cfg = ctx.cfg
        t = Timing.of(cfg)
        pair = dp.pulse_shape(cfg.procedure["pulse"]["shape"]).pair_points(t.points)
        awg = ctx.bench.extra["awg"]
        first = True
        for g in ctx.bench.extra["dmms"]:
            ch = cfg.stand["platform"]["gyros"][g]["awg_channel"]
            loaded = awg.load_pair(ch, pair, t.awg_rate_hz, amplitude_v,
                                   lead_points=t.lead_points, trigger_out=first)
            first = False
            ctx.run.event("awg_loaded", gyro=g, channel=ch, amplitude_v=amplitude_v,
                          sample_rate_hz=loaded.sample_rate_hz, points=loaded.points,
                          lead_s=loaded.lead_s)
        ctx.state["loaded_v"] = amplitude_v

    def _do_turn(self, step: Step, ctx: RunContext) -> None:
        drive = ctx.bench.axes[step.axis].drive
        p = step.params
        tol = ctx.cfg.stand["axes"][step.axis]["drive"].get("position_tolerance_deg",
                                                           DEFAULT_POSITION_TOLERANCE_DEG)
        final = drive.move_to(p["position_deg"], p["rate_dps"], p["accel_dps2"],
                              tolerance_deg=tol)
        ctx.run.event("turned", axis=step.axis, position_deg=p["position_deg"],
                      actual_deg=final)
        ctx.progress.line(f"  platform at {final:.4f} deg (target {p['position_deg']:g})")

    def _do_settle(self, step: Step, ctx: RunContext) -> None:
        self._wait(ctx, step.on_axis, step.params["duration_s"])

    def _wait(self, ctx: RunContext, axis: str, duration_s: float) -> None:
        drive = ctx.bench.axes[axis].drive
        end = ctx.clock.now() + duration_s
        while (left := end - ctx.clock.now()) > 0:
            drive.check()
            ctx.progress.advance(duration_s - left, duration_s,
                                 f"{axis}: {duration_s - left:.1f} of {duration_s:g} s waited")
            ctx.clock.sleep(min(left, 1.0))
        drive.check()

    def _do_cycle(self, step: Step, ctx: RunContext) -> None:
        cfg, p = ctx.cfg, step.params
        t = Timing.of(cfg)
        amplitude = self.timing_amplitude(cfg) if p["timing"] else \
            float(cfg.procedure["pulse"]["amplitude_v"])
        self._load(ctx, amplitude)
        drive = ctx.bench.axes[step.axis].drive
        dmms = ctx.bench.extra["dmms"]
        drive.check()
        for dmm in dmms.values():
            dmm.arm()
        t0 = ctx.bench.extra["awg"].trigger()
        data = {}
        for g, dmm in dmms.items():
            data[g] = dmm.fetch()
            ctx.state["fetches"][g] += 1
        drive.check()
        ctx.run.event("cycle", unit=step.unit, position_deg=p["position_deg"],
                      actual_deg=drive.position_deg, timing=p["timing"], amplitude_v=amplitude,
                      t_trigger_s=t0, fetch=dict(ctx.state["fetches"]), samples=t.count,
                      interval_s=t.interval_s, first_sample_s=t.first_sample_s, tc_s=t.tc_s)
        shape = dp.pulse_shape(cfg.procedure["pulse"]["shape"])
        quick = []
        for g, u in data.items():
            spec = cfg.stand["platform"]["gyros"][g]
            k_as = spec["k_as_v_per_deg"]
            rec = dp.CycleRecord(u, t.interval_s, t.first_sample_s, t.tc_s)
            a = dp.fit_offset(rec, shape).amplitude_v_per_dps / k_as
            nominal = spec["precession_dps_per_v"] * amplitude
            if not dp.MIN_AMPLITUDE_REL * nominal <= abs(a) <= nominal / dp.MIN_AMPLITUDE_REL:
                raise Abort(f"gyro {g}: the angle sensor shows a precession of {a:.3g} deg/s "
                            f"where the pulse should give {nominal:.3g} deg/s "
                            f"(precession_dps_per_v x {amplitude:g} V): check the torque "
                            f"sensor's current path from generator channel "
                            f"{spec['awg_channel']} and the angle sensor's wiring to its DMM")
            w, _ = dp.cycle_drift_dph(rec, shape, k_as, 0.0, a)
            # 5 significant digits, as the certificate prints the drift of each cycle
            quick.append(Figure(g, w, unit="°/h", signed=True, digits=5))
        kind = "timing cycle" if p["timing"] else "cycle"
        where = f"{kind} {p['index']} at {p['position_deg']:g}°"
        ctx.progress.reading("drift", where, *quick)
        ctx.progress.result(f"{where}, drift at nominal edges", *quick)
        self._wait(ctx, step.on_axis, float(setting(cfg, "gap_s")))

    def _do_stop(self, step: Step, ctx: RunContext) -> None:
        ctx.bench.extra["awg"].outputs_off()
        drive = ctx.bench.axes[step.axis].drive
        drive.stop()
        drive.disable()

    # -- analysis -------------------------------------------------------------------------
    def analyze(self, run: RunDir, cfg: Config) -> dict[str, Any]:
        from procedures.drift_pulse.budgets import add_budgets

        return add_budgets(analyze_run(run, cfg, self))


KIND = DriftPulse()


def dmm_replies(run: RunDir, session: int, gyro: str, model: str) -> list[str]:
    """The DMM's replies to FETC?, in order, from its raw SCPI journal of a session."""
    path = run.path / "raw" / f"s{session}" / f"{gyro}-dmm.jsonl"
    out, waiting = [], False
    fetch = DMM_PROFILES[model].words.fetch.text().upper()
    for r in read_jsonl(path):
        if r.get("dir") == "tx":
            waiting = r["data"].strip().upper() == fetch
        elif r.get("dir") == "rx" and waiting:
            out.append(r["data"])
            waiting = False
    return out


def analyze_run(run: RunDir, cfg: Config, kind: DriftPulse = KIND) -> dict[str, Any]:
    events = run.events()
    plan_units = set(kind.build_plan(cfg).units())
    done = {e["unit"]: e["session"] for e in events if e.get("event") == "unit_done"}
    cycles = [e for e in events if e.get("event") == "cycle" and done.get(e["unit"]) ==
              e["session"]]
    gyros = kind.gyros(cfg)
    plat = cfg.stand["platform"]["gyros"]
    replies: dict[tuple[int, str], list[str]] = {}
    records: dict[str, list[dp.CycleRecord]] = {g: [] for g in gyros}
    for e in cycles:
        for g in gyros:
            key = (e["session"], g)
            if key not in replies:
                replies[key] = dmm_replies(run, *key, plat[g]["dmm"]["model"])
            n = e["fetch"][g]
            u = parse_numbers(replies[key][n - 1])
            if u.size != e["samples"]:
                raise ValueError(f"{run.path}: cycle {e['unit']}: the DMM of gyro {g} "
                                 f"returned {u.size} readings, the event says {e['samples']}")
            records[g].append(dp.CycleRecord(u, e["interval_s"], e["first_sample_s"],
                                             e["tc_s"], e["t_trigger_s"], e["position_deg"],
                                             timing_only=e["timing"]))
    shape = dp.pulse_shape(cfg.procedure["pulse"]["shape"])
    turn_tol = cfg.stand["axes"][kind.table(cfg)]["drive"].get("position_tolerance_deg",
                                                               DEFAULT_POSITION_TOLERANCE_DEG)
    stated = {g: dp.StatedErrors(k_as_u_rel=plat[g].get("k_as_u_rel", 0.0),
                                 pulse_mismatch_max_rel=plat[g].get("pulse_mismatch_max_rel", 0.0),
                                 drift_random_walk_dph_per_rth=plat[g].get(
                                     "drift_random_walk_dph_per_rth", 0.0),
                                 turn_tolerance_deg=turn_tol) for g in gyros}
    rule = setting(cfg, "decision_rule")
    complete = plan_units <= set(done)
    drift: dict[str, Any]
    checks: list[dict[str, Any]] = []
    try:
        result = dp.analyze(records, shape, {g: plat[g]["k_as_v_per_deg"] for g in gyros},
                            cfg.procedure["site"]["latitude_deg"], stated)
        drift = result.to_dict()["drift"]
        checks = _checks(cfg, result, rule)
    except ValueError as e:
        drift = {"axes": {}, "not_computed": str(e)}
        complete = False
    t = Timing.of(cfg)
    method = {"method": "docs/method.md B: alternating-sign controlled precession",
              "pulse": cfg.procedure["pulse"], "timing_cycles": setting(cfg, "timing_cycles"),
              "cycles_per_position": setting(cfg, "cycles"),
              "positions_deg": setting(cfg, "positions_deg"),
              "sample_rate_hz": 1.0 / t.interval_s, "aperture_s": t.aperture_s,
              "site": cfg.procedure["site"], "tolerance": cfg.procedure.get("tolerance", {})}
    return result_document(run, cfg, events, complete=complete, checks=checks, rule=rule,
                           method=method, drift=drift)


def _checks(cfg: Config, result: dp.DriftResult, rule: str) -> list[dict[str, Any]]:
    """Own drift against the tolerance; the Earth-rate consistency (k_as, levelling)."""
    out = []
    tol = cfg.procedure.get("tolerance", {}).get("own_drift_dph")
    for g, ax in result.axes.items():
        if tol is None:
            continue
        c = judge(g, 0.0, "own_drift", ax.own_dph, ax.own_u_dph, float(tol), rule).to_dict()
        out.append({"axis": g, "quantity": "own_drift", "unit": "deg/h",
                    "value_dph": ax.own_dph, "u_dph": ax.own_u_dph, "tolerance_dph": float(tol),
                    **{k: c[k] for k in ("rule", "verdict", "reason", "capability_ratio",
                                         "capability_ok")}})
    if result.earth_consistent is not None and result.earth_horizontal_dph is not None:
        diff = result.earth_horizontal_dph - result.earth_horizontal_expected_dph
        out.append({"axis": "x,y", "quantity": "earth_horizontal_rate", "unit": "deg/h",
                    "value_dph": result.earth_horizontal_dph,
                    "u_dph": result.earth_horizontal_u_dph,
                    "expected_dph": result.earth_horizontal_expected_dph, "rule": "consistency",
                    "verdict": "pass" if result.earth_consistent else "fail",
                    "reason": f"|measured - 15.041 cos(latitude)| = {abs(diff):.2g} deg/h "
                              f"{'<=' if result.earth_consistent else '>'} U = "
                              f"{result.earth_horizontal_u_dph:.2g} deg/h"})
    return out
