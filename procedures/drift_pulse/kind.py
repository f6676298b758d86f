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

from collections.abc import Callable, Collection, Mapping
from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING

from bench.core import rundir_layout as layout
from bench.core.config import (
    Config,
    StandSettings,
    stand_schema,
)
from bench.core.plan import Duration, Plan, Step, check_actions
from bench.core.progress import Figure
from bench.core.schema import Key, Map
from bench.core.yamlfile import Problem
from drivers.clock import Clock
from procedures.base import prompt, result_head, resume_whole
from procedures.drift_pulse.settings import (  # noqa: F401 - the kind's names
    CYCLE_OVERHEAD_S,
    NAME,
    PLATFORM,
    PROCEDURE,
    SIM_AWG,
    SIM_DMM,
    SIM_PLATFORM,
    DriftSettings,
    PlatformSettings,
    Timing,
    drift_problems,
)

# the instruments, the twins, the analysis (numpy), the certificate and the records are
# imported where the kind uses them: `bench validate` and `bench schema` load this module
# for its files alone
if TYPE_CHECKING:
    from bench.core.engine import RunContext
    from bench.core.instruments import Bench
    from bench.core.journal import RunDir
    from bench.core.registry import KindPlan, StepHandler
    from bench.core.simbench import SimBench, TwinFactory
    from bench.kind import Kind
    from bench.report.codec import KindResult
    from bench.report.station import StationParts
    from drivers.awg import WaveformGenerator
    from drivers.dmm import Digitizer
    from procedures.drift_pulse import analysis as dp
    from procedures.drift_pulse.certificate import DriftCertificate
    from procedures.drift_pulse.dcc import DriftDcc
    from procedures.drift_pulse.instruments import DriftBench
    from procedures.drift_pulse.records import DriftRecords
    from procedures.drift_pulse.result import DriftBody


# -- each action's parameters, made once where the plan is built (the settle's:
# bench.core.plan.Duration) ---------------------------------------------------------------

@dataclass(frozen=True, slots=True)
class TurnParams:
    """The platform to an absolute position (profile position mode)."""
    position_deg: float
    rate_dps: float
    accel_dps2: float


@dataclass(frozen=True, slots=True)
class CycleParams:
    """One pulse cycle at a position: a timing cycle (locates the pulses) or a measuring
    one; `index` counts from 1 within its kind and position."""
    position_deg: float
    timing: bool
    index: int


class DriftFiles:
    """The drift procedure's files (the kind's `settings` part)."""

    def procedure_schema(self) -> Map:
        return PROCEDURE

    def stand_schema(self) -> Map:
        return stand_schema(extra_top={"platform": Key(PLATFORM, True)},
                            extra_sim={"platform": Key(SIM_PLATFORM), "awg": Key(SIM_AWG),
                                       "dmm": Key(SIM_DMM)})

    # -- checks that need both files --------------------------------------------------
    def cross_check(self, cfg: Config) -> list[Problem]:
        return drift_problems(cfg)

    def parse(self, cfg: Config) -> DriftSettings:
        """The validated files as the kind's frozen settings (bench/core/registry.py)."""
        return DriftSettings.parse(cfg)

    def notes(self, cfg: Config) -> list[str]:
        """Nothing to advise beside 'valid' (bench/core/registry.py `KindSettings`)."""
        return []


class DriftPlan:
    """The drift procedure's steps (the kind's `plan` part): every cycle a unit, resumed
    whole; checked against the actions its steps handle."""

    resume_plan = staticmethod(resume_whole)

    def __init__(self, actions: Collection[str]) -> None:
        self._actions = actions

    def build_plan(self, cfg: Config) -> Plan:
        d = DriftSettings.from_config(cfg)
        t = d.timing
        table = d.table_axis
        gyros = d.gyros
        gap = d.gap_s
        cycle_s = t.record_s + gap + CYCLE_OVERHEAD_S
        rate, accel = d.turn_rate_dps, d.turn_accel_dps2
        shape = d.pulse_shape
        steps: list[Step] = []
        if d.prompts:
            steps.append(Step("prompt", None, "Level the platform; switch the gyros' torque "
                              "sensors to the pulse generator (correction loops open); connect "
                              "each angle sensor to its DMM and the generator's trigger output "
                              "to every DMM's Ext Trig input"))
        steps.append(Step("setup", None, f"{shape} pairs of 2 x {t.tc_s:g} s on gyros "
                          f"{', '.join(gyros)}; DMMs: {t.count} samples at "
                          f"{1 / t.interval_s:g} Sa/s, aperture {t.aperture_s * 1e3:g} ms",
                          2.0, None))
        at = None
        for k, pos in enumerate(d.positions_deg):
            turn_s = (abs(pos - at) / rate + rate / accel) if at is not None else \
                abs(pos) / rate + rate / accel
            steps.append(Step("turn", table, f"platform to {pos:g} deg (profile position)",
                              turn_s, None, TurnParams(pos, rate, accel)))
            settle = d.settle_s
            if settle:
                steps.append(Step("settle", table, f"{settle:g} s for the platform to settle",
                                  settle, None, Duration(settle)))
            at = pos
            timing = d.timing_cycles if k == 0 else 0
            for i in range(timing):
                steps.append(Step("cycle", table, f"timing cycle {i + 1}/{timing} at {pos:g} "
                                  f"deg ({d.timing_amplitude_v:g} V)", cycle_s,
                                  f"timing/{i + 1}",
                                  CycleParams(pos, True, i + 1)))
            n = d.cycles
            for i in range(n):
                steps.append(Step("cycle", table, f"cycle {i + 1}/{n} at {pos:g} deg", cycle_s,
                                  f"{pos:g}deg/{i + 1}",
                                  CycleParams(pos, False, i + 1)))
        steps.append(Step("stop", table, "pulse outputs off; turntable to rest, disabled", 2.0))
        return check_actions(Plan(d.title, tuple(steps)), self._actions)


class DriftSteps:
    """The drift procedure on the bench (the kind's `steps` part): twins, instruments,
    and one handler per action of its plan."""

    def __init__(self) -> None:
        self.handlers: Mapping[str, StepHandler] = {
            "prompt": prompt, "setup": self._do_setup, "turn": self._do_turn,
            "settle": self._do_settle, "cycle": self._do_cycle, "stop": self._do_stop}

    def execute(self, step: Step, ctx: RunContext) -> None:
        self.handlers[step.action](step, ctx)

    # -- bench ----------------------------------------------------------------------------
    def start_sim(self, cfg: Config) -> tuple[SimBench, StandSettings]:
        from bench.core.simbench import SimBench
        sim = SimBench(cfg.stand_settings, [PlatformSettings.of(cfg).table_axis])
        return sim, sim.start(extra=[gyro_rig_factory(PlatformSettings.of(cfg))])

    def open_bench(self, cfg: Config, stand: StandSettings, clock: Clock,
                   run: RunDir | None) -> Bench:
        from bench.core.instruments import (
            manual_note,
            open_axis,
            raw_text_logger,
            with_readback,
        )
        from drivers.awg import WaveformGenerator
        from drivers.dmm import Digitizer
        from procedures.drift_pulse.instruments import DriftBench
        bench = DriftBench()
        d = PlatformSettings.of(cfg)

        def raw(name: str) -> Callable[[str, bytes], None] | None:
            return raw_text_logger(bench.log(run.raw_path(name)), clock) if run else None

        try:
            table = d.table_axis
            open_axis(bench, stand.axes[table], clock, run, counter=False, fog=False)
            awg = WaveformGenerator.open(
                stand.address("platform.awg.resource", d.awg_resource),
                d.awg_model, clock, raw=raw(layout.AWG_LOG))
            bench.enter(awg)
            bench.awg = awg
            for g in d.gyros:
                spec = d.platform[g]
                dmm = Digitizer.open(
                    stand.address(f"platform.gyros.{g}.dmm.resource", spec.dmm_resource),
                    spec.dmm_model, clock, raw=raw(layout.dmm_log(g)))
                bench.enter(dmm)
                bench.dmms[g] = dmm
            bench.axes[table].identities["awg"] = with_readback(
                awg.identify(), {}, manual_note(awg.profile.manual))
            for g, dmm in bench.dmms.items():
                bench.axes[table].identities[f"{g}-dmm"] = with_readback(
                    dmm.identify(), {}, manual_note(dmm.profile.manual))
        except BaseException as e:
            bench.abandon(e)
            raise
        return bench

    # -- steps (each action's handler: `handlers`) -----------------------------------------
    def _do_setup(self, step: Step, ctx: RunContext) -> None:
        from procedures.drift_pulse.events import DmmSetup
        t = DriftSettings.from_config(ctx.cfg).timing
        for g, dmm in dmms_of(ctx.bench).items():
            setup = dmm.configure(t.range_v, t.aperture_s, t.interval_s, t.count,
                                  trigger_delay_s=t.trigger_delay_s)
            ctx.run.write(DmmSetup(gyro=g, setup=setup))
        plat = platform_of(ctx.bench)
        plat.fetches = {g: 0 for g in plat.dmms}
        plat.loaded_v = None

    def _load(self, ctx: RunContext, amplitude_v: float) -> None:
        """(Re)load the pair on every gyro's channel at this amplitude."""
        from procedures.drift_pulse import analysis as dp
        from procedures.drift_pulse.events import AwgLoaded
        if platform_of(ctx.bench).loaded_v == amplitude_v:
            return
        d = DriftSettings.from_config(ctx.cfg)
        t = d.timing
        pair = dp.pulse_shape(d.pulse_shape).pair_points(t.points)
        awg = awg_of(ctx.bench)
        first = True
        for g in dmms_of(ctx.bench):
            ch = d.platform[g].awg_channel
            loaded = awg.load_pair(ch, pair, t.awg_rate_hz, amplitude_v,
                                   lead_points=t.lead_points, trigger_out=first)
            first = False
            ctx.run.write(AwgLoaded(gyro=g, channel=ch, amplitude_v=amplitude_v,
                                    sample_rate_hz=loaded.sample_rate_hz, points=loaded.points,
                                    lead_s=loaded.lead_s))
        platform_of(ctx.bench).loaded_v = amplitude_v

    def _do_turn(self, step: Step, ctx: RunContext) -> None:
        from procedures.drift_pulse.events import Turned
        drive = ctx.bench.axes[step.on_axis].drive
        p = step.params_as(TurnParams)
        tol = DriftSettings.from_config(ctx.cfg).position_tolerance_deg
        final = drive.move_to(p.position_deg, p.rate_dps, p.accel_dps2,
                              tolerance_deg=tol)
        ctx.run.write(Turned(axis=step.on_axis, position_deg=p.position_deg,
                             actual_deg=final))
        ctx.progress.line(f"  platform at {final:.4f} deg (target {p.position_deg:g})")

    def _do_settle(self, step: Step, ctx: RunContext) -> None:
        self._wait(ctx, step.on_axis, step.params_as(Duration).duration_s)

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
        from bench.core.engine import Abort
        from procedures.drift_pulse import analysis as dp
        from procedures.drift_pulse.events import Cycle
        p = step.params_as(CycleParams)
        d = DriftSettings.from_config(ctx.cfg)
        t = d.timing
        amplitude = d.timing_amplitude_v if p.timing else d.amplitude_v
        self._load(ctx, amplitude)
        drive = ctx.bench.axes[step.on_axis].drive
        dmms = dmms_of(ctx.bench)
        drive.check()
        for dmm in dmms.values():
            dmm.arm()
        t0 = awg_of(ctx.bench).trigger()
        data = {}
        for g, dmm in dmms.items():
            data[g] = dmm.fetch()
            platform_of(ctx.bench).fetches[g] += 1
        drive.check()
        ctx.run.write(Cycle(unit=step.in_unit, position_deg=p.position_deg,
                            actual_deg=drive.position_deg, timing=p.timing, amplitude_v=amplitude,
                            t_trigger_s=t0, fetch=dict(platform_of(ctx.bench).fetches),
                            samples=t.count, interval_s=t.interval_s,
                            first_sample_s=t.first_sample_s, tc_s=t.tc_s))
        shape = dp.pulse_shape(d.pulse_shape)
        quick = []
        for g, u in data.items():
            spec = d.platform[g]
            k_as = spec.k_as_v_per_deg
            rec = dp.CycleRecord(u, t.interval_s, t.first_sample_s, t.tc_s)
            a = dp.fit_offset(rec, shape).amplitude_v_per_dps / k_as
            nominal = spec.precession_dps_per_v * amplitude
            if not dp.MIN_AMPLITUDE_REL * nominal <= abs(a) <= nominal / dp.MIN_AMPLITUDE_REL:
                raise Abort(f"gyro {g}: the angle sensor shows a precession of {a:.3g} deg/s "
                            f"where the pulse should give {nominal:.3g} deg/s "
                            f"(precession_dps_per_v x {amplitude:g} V): check the torque "
                            f"sensor's current path from generator channel "
                            f"{spec.awg_channel} and the angle sensor's wiring to its DMM")
            w, _ = dp.cycle_drift_dph(rec, shape, k_as, 0.0, a)
            # 5 significant digits, as the certificate prints the drift of each cycle
            quick.append(Figure(g, w, unit="°/h", signed=True, digits=5))
        kind = "timing cycle" if p.timing else "cycle"
        where = f"{kind} {p.index} at {p.position_deg:g}°"
        ctx.progress.reading("drift", where, *quick)
        ctx.progress.result(f"{where}, drift at nominal edges", *quick)
        self._wait(ctx, step.on_axis, d.gap_s)

    def _do_stop(self, step: Step, ctx: RunContext) -> None:
        awg_of(ctx.bench).outputs_off()
        ctx.bench.rest(step.on_axis)


class DriftAnalysis:
    """result.json of a drift run (the kind's `analysis` part)."""

    def __init__(self, plan: DriftPlan) -> None:
        self._plan = plan

    def analyze(self, run: RunDir, cfg: Config) -> KindResult[DriftBody]:
        return analyze_run(run, cfg, self._plan)


class DriftPulse:
    """The drift procedure as a kind (bench/kind.py `Kind`): its parts, the heavy ones
    (numpy, the certificate, the records) imported when first used."""

    name = NAME
    settings = DriftFiles()
    steps = DriftSteps()
    plan = DriftPlan(steps.handlers)
    analysis = DriftAnalysis(plan)

    @cached_property
    def certificate(self) -> DriftCertificate:
        from procedures.drift_pulse.certificate import DriftCertificate
        return DriftCertificate()

    @cached_property
    def dcc(self) -> DriftDcc:
        from procedures.drift_pulse.dcc import DriftDcc
        return DriftDcc()

    @cached_property
    def records(self) -> DriftRecords:
        from procedures.drift_pulse.records import DriftRecords
        return DriftRecords()

    @cached_property
    def station(self) -> StationParts:
        """Nothing of its own on the station's pages: they list its declared figures."""
        from bench.report.station import StationParts
        return StationParts()


KIND: Kind = DriftPulse()


def awg_of(bench: Bench) -> WaveformGenerator:
    """The platform's waveform generator, as `DriftSteps.open_bench` keeps it."""
    awg = platform_of(bench).awg
    if awg is None:
        raise TypeError("the bench's platform waveform generator is not open")
    return awg


def dmms_of(bench: Bench) -> dict[str, Digitizer]:
    """Gyro -> its digitizing DMM, as `DriftSteps.open_bench` keeps them."""
    return platform_of(bench).dmms


def platform_of(bench: Bench) -> DriftBench:
    """The bench as `DriftSteps.open_bench` made it: with the platform's instruments."""
    from procedures.drift_pulse.instruments import DriftBench
    if not isinstance(bench, DriftBench):
        raise TypeError(f"the bench is a {type(bench).__name__}, not a DriftBench")
    return bench


def gyro_rig_factory(d: PlatformSettings) -> TwinFactory:
    """The twins of a gyro platform on the stand's turntable (the stand file's `platform:`
    and `sim.platform` blocks): the platform, its waveform generator and one DMM per gyro
    of the procedure, each address rewritten to its twin's (`SimBench.addresses`)."""

    def add_platform(sb: SimBench) -> None:
        from sims.gyro_rig import start_gyro_rig
        if d.sim_platform is None:
            raise ValueError("a simulated drift-pulse bench needs sim.platform")
        gyros = list(d.gyros)
        rig = start_gyro_rig(sb.stand, d.sim_platform,
                             {g: d.platform[g].awg_channel for g in gyros},
                             awg_model=d.awg_model, dmm_model=d.platform[gyros[0]].dmm_model,
                             awg_options=d.awg_twin, dmm_options=d.dmm_twin,
                             dmm_errors=d.dmm_errors)
        sb.add("gyro-rig", rig, rig.stop)
        # the stand's serials in *IDN? field 3 (each twin reads its idn at every query)
        for twin, serial in ((rig.awg, d.awg_serial),
                             *((rig.dmms[g], d.dmm_serials.get(g)) for g in gyros)):
            if serial:
                idn = twin.idn.split(",")
                twin.idn = ",".join([*idn[:2], serial, *idn[3:]])
        sb.addresses["platform.awg.resource"] = rig.awg.resource
        for g in gyros:
            sb.addresses[f"platform.gyros.{g}.dmm.resource"] = rig.dmms[g].resource

    return add_platform


def analyze_run(run: RunDir, cfg: Config, plan: KindPlan = KIND.plan
                ) -> KindResult[DriftBody]:
    from msgspec import UNSET

    from bench.core.journal import units_done
    from bench.report.codec import KindResult
    from drivers.scpi import parse_numbers
    from procedures.drift_pulse import analysis as dp
    from procedures.drift_pulse.budgets import CorrectionInput
    from procedures.drift_pulse.codec import dmm_replies
    from procedures.drift_pulse.corrections import read_corrections
    from procedures.drift_pulse.events import Cycle
    from procedures.drift_pulse.result import DriftBody, DriftCheck, DriftFigures, DriftMethod

    events = run.events()
    plan_units = set(plan.build_plan(cfg).units())
    done = units_done(events)
    cycles = [e for e in events if isinstance(e, Cycle) and done.get(e.unit) == e.session]
    d = DriftSettings.from_config(cfg)
    gyros = list(d.gyros)
    plat = d.platform
    replies: dict[tuple[int, str], list[str]] = {}
    records: dict[str, list[dp.CycleRecord]] = {g: [] for g in gyros}
    # the run folder's instrument corrections (issue 58): none, the readings as measured
    corr = read_corrections(run.path)
    for e in cycles:
        session, samples = e.session, e.samples
        for g in gyros:
            key = (session, g)
            if key not in replies:
                replies[key] = dmm_replies(run, *key, plat[g].dmm_model)
            n = e.fetch[g]
            u = corr.readings(g, parse_numbers(replies[key][n - 1]))
            if u.size != samples:
                raise ValueError(f"{run.path}: cycle {e.unit}: the DMM of gyro {g} "
                                 f"returned {u.size} readings, the event says {samples}")
            records[g].append(dp.CycleRecord(
                u, e.interval_s, e.first_sample_s, e.tc_s, e.t_trigger_s, e.position_deg,
                timing_only=e.timing))
    shape = dp.pulse_shape(d.pulse_shape)
    stated = {g: dp.StatedErrors(k_as_u_rel=plat[g].k_as_u_rel,
                                 pulse_mismatch_max_rel=plat[g].pulse_mismatch_max_rel,
                                 drift_random_walk_dph_per_rth=plat[g].drift_random_walk_dph_per_rth,
                                 turn_tolerance_deg=d.position_tolerance_deg,
                                 corrections=tuple(CorrectionInput(c.where, c.quantity,
                                                                   c.value, c.ustd)
                                                   for c in corr.of_gyro(g)))
              for g in gyros}
    rule = d.decision_rule
    complete = plan_units <= set(done)
    checks: list[DriftCheck] = []
    try:
        result = dp.analyze(records, shape, {g: plat[g].k_as_v_per_deg for g in gyros},
                            d.latitude_deg, stated)
        drift = result.figures()
        checks = result.checks(d.own_drift_tolerance_dph, rule)
    except ValueError as e:
        drift = DriftFigures.failed(str(e))
        complete = False
    t = d.timing
    method = DriftMethod(pulse=dict(d.pulse_doc), timing_cycles=d.timing_cycles,
                         cycles_per_position=d.cycles, positions_deg=d.positions_deg,
                         sample_rate_hz=1.0 / t.interval_s, aperture_s=t.aperture_s,
                         site=dict(d.site_doc), tolerance=dict(d.tolerance_doc))
    head = result_head(run, cfg, events, complete=complete, checks=checks, rule=rule,
                       method=method)
    # the body after the frame: its uncertainty twins are fields of the model (result.py;
    # the rule they follow is bench/report/uncertainty_names.py's); the corrections
    # applied, stated (issue 58; none: the document as before)
    return KindResult(head, DriftBody(drift=drift,
                                      corrections=list(corr.stated) if corr else UNSET))

