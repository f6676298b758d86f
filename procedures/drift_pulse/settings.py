"""The drift-pulse procedure's files: their keys, defaults (each in its key), the rules
that need both files, and the settings the kind runs on, parsed once (`DriftSettings`).

The procedure, the stand's `platform:` block and its `sim.platform` truth are read here
and nowhere else (tests/test_architecture.py).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Annotated, Any

from bench.core.config import CALIBRATION, COMMON_PROCEDURE_KEYS, IDENTITY, Config
from bench.core.schema import (
    Key,
    ListOf,
    Map,
    MapOf,
    Num,
    Setting,
    Str,
    declared_map,
    parse_declared,
)
from bench.core.yamlfile import Problem
from drivers.awg import PROFILES as AWG_PROFILES
from drivers.dmm import PROFILES as DMM_PROFILES
from procedures.drift_pulse.shapes import SHAPES, pulse_shape
from sims.truth import GyroTruth, PlatformTruth

#: the keys of a stand file's `sim.platform.gyros.<gyro>` truth (the gyro twin's fields)
SIM_GYRO_KEYS: tuple[str, ...] = tuple(GyroTruth.__dataclass_fields__)

NAME = "drift-pulse"
GYRO_NAMES = ("x", "y", "z")

TIMING_GAIN = 8.0
#: real-bench seconds a cycle costs beyond its record: arming, transfer, SCPI checks
CYCLE_OVERHEAD_S = 0.5



# -- files ------------------------------------------------------------------------------

# Each key of the procedure file is declared once, on the frozen dataclass that holds it
# as the file states it (`DriftFile`): the field's type and default, its Setting's node
# (bounds, unit) and meaning. PROCEDURE is derived from them (bench/core/schema.py).


@dataclass(frozen=True, kw_only=True)
class Site:
    latitude_deg: Annotated[float, Setting(Num(min=-90, max=90, unit="deg"))]
    name: Annotated[str | None, Setting(Str())] = None


@dataclass(frozen=True, kw_only=True)
class Pulse:
    shape: Annotated[str, Setting(Str(tuple(SHAPES)),
                                  "rectangular, triangular (or sawtooth)")]
    duration_s: Annotated[float, Setting(Num(min=0, exclusive_min=True, unit="s"),
                                         "Tc, each pulse")]
    amplitude_v: Annotated[float, Setting(
        Num(min=0, exclusive_min=True, unit="V"),
        "peak voltage into the torque-sensor current amplifier")]
    points: Annotated[int, Setting(Num(min=4, max=500_000, integer=True),
                                   "waveform points per pulse")] = 1000


@dataclass(frozen=True, kw_only=True)
class Turn:
    rate_dps: Annotated[float, Setting(Num(min=0, exclusive_min=True, unit="deg/s"))]
    accel_dps2: Annotated[float, Setting(Num(min=0, exclusive_min=True, unit="deg/s^2"))]


@dataclass(frozen=True, kw_only=True)
class Digitizer:
    sample_rate_hz: Annotated[float, Setting(Num(min=0, exclusive_min=True, unit="Hz"),
                                             "the DMMs' sample rate")] = 2000.0
    #: None: 0.8 of the interval
    aperture_s: Annotated[float | None, Setting(Num(min=0, exclusive_min=True, unit="s"),
                                                "default 0.8 of the interval")] = None
    range_v: Annotated[float, Setting(Num(min=0, exclusive_min=True, unit="V"),
                                      "the DMMs' range")] = 10.0
    margin_s: Annotated[float, Setting(Num(min=0, unit="s"),
                                       "recorded after the pair")] = 0.05


@dataclass(frozen=True, kw_only=True)
class DriftTolerance:
    own_drift_dph: Annotated[float | None, Setting(
        Num(min=0, exclusive_min=True, unit="deg/h"))] = None


@dataclass(frozen=True, kw_only=True)
class DriftFile:
    """The drift-pulse procedure file's own keys as it states them, defaults filled in."""

    site: Annotated[Site, Setting()]
    pulse: Annotated[Pulse, Setting()]
    cycles: Annotated[int, Setting(Num(min=4, max=10_000, integer=True), "measuring cycles "
                                   "per position (4 at least for the scatter)")] = 10
    timing_cycles: Annotated[int, Setting(Num(min=0, max=1000, integer=True),
                                          "large-amplitude cycles that locate the pulses")] = 4
    timing_amplitude_v: Annotated[float | None, Setting(
        Num(min=0, exclusive_min=True, unit="V"),
        "default 8 x the pulse amplitude, within the DMM range")] = None
    positions_deg: Annotated[tuple[float, ...], Setting(
        ListOf(Num(min=-360, max=360, unit="deg"), min_len=2),
        "turntable positions")] = (0.0, 180.0)
    gap_s: Annotated[float, Setting(Num(min=0, unit="s"), "pause between cycles")] = 0.5
    settle_s: Annotated[float, Setting(Num(min=0, unit="s"), "pause after a turn")] = 5.0
    turn: Annotated[Turn | None, Setting(
        doc="default: the drive's max rate and acceleration")] = None
    digitizer: Annotated[Digitizer, Setting()] = Digitizer()
    gyros: Annotated[tuple[str, ...] | None, Setting(
        ListOf(Str(GYRO_NAMES), min_len=1),
        "which of the platform's gyros (default: all)")] = None
    tolerance: Annotated[DriftTolerance, Setting()] = DriftTolerance()


PROCEDURE = Map({**COMMON_PROCEDURE_KEYS, **declared_map(DriftFile).keys})

GYRO = Map({
    "model": Key(Str(), False, "the gyro's model (printed as part of the item calibrated)"),
    "serial": Key(Str(), False, "the gyro's serial number (printed as part of the item)"),
    "awg_channel": Key(Num(min=1, max=4, integer=True), True),
    "dmm": Key(Map({"resource": Key(Str(), True, "VISA resource string"),
                    "model": Key(Str(tuple(DMM_PROFILES)), True),
                    "serial": Key(Str(), False, "the DMM's serial: the lab register's item "
                                  "(its runs are found by it: bench impact)"),
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
                    "serial": Key(Str(), False, "the generator's serial: the lab register's "
                                  "item (its runs are found by it: bench impact)"),
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
               "serial": Key(Str(), False, "the serial the twin reports (*IDN? field 3)"),
               "amplitude_error_rel": Key(
                   Num(min=-0.5, max=0.5), False, "the generator's true amplitude error a, "
                   "unknown to the lab: every output voltage x (1 + a) (issue 58)", 0.0)})
SIM_DMM = Map({"trigger_latency_s": Key(Num(min=0)),
               "serials": Key(MapOf(Str()), False, "gyro: the serial its DMM twin reports"),
               "gain_error_rel": Key(
                   MapOf(Num(min=-0.5, max=0.5)), False, "gyro: its DMM's true gain error g, "
                   "unknown to the lab: every reading the twin returns x (1 + g) (default 0; "
                   "issue 58)"),
               "offset_error_v": Key(
                   MapOf(Num(unit="V")), False, "gyro: its DMM's true offset o, unknown to "
                   "the lab: every reading + o, after the gain (default 0; issue 58)")})
#: the DMM twins' own errors, by gyro (`sim.dmm`; each a keyword of sims/dmm_twin.DmmTwin)
DMM_ERROR_KEYS = ("gain_error_rel", "offset_error_v")

def drift_file(cfg: Config) -> DriftFile:
    """The procedure file's own keys, parsed (validated: the loader's cross-checks run
    on files the schema passed)."""
    return parse_declared(DriftFile, cfg.procedure)


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
        d = parse_declared(Digitizer, cfg.procedure.get("digitizer") or {})
        tc = float(p["duration_s"])
        points = int(p.get("points", Pulse.points))
        interval = 1.0 / d.sample_rate_hz
        aperture = d.aperture_s if d.aperture_s is not None else 0.8 * interval
        lead_s = 1.0 / (points / tc)
        count = int(math.ceil((2 * tc + lead_s + d.margin_s) / interval)) + 1
        return cls(tc, points, points / tc, interval, aperture, d.range_v, count,
                   max(interval - 0.5 * aperture, 0.0))


def _near_int(x: float) -> bool:
    return abs(x - round(x)) < 1e-6 * max(1.0, abs(x))


def drift_problems(cfg: Config) -> list[Problem]:
    """The checks that need both files: the platform's wiring, the pulse timing
    against the instruments, the positions, the turn against the drive."""
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
    out += _check_timing(cfg)
    out += _check_positions(cfg)
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
            for g in gyros_of(cfg):
                if g not in sp["gyros"]:
                    out.append(sdoc.problem(("sim", "platform", "gyros"),
                                            f"no truth for gyro {g!r}"))
    return out

def _check_timing(cfg: Config) -> list[Problem]:
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
    if cfg.procedure.get("timing_cycles", DriftFile.timing_cycles):
        amps["timing_amplitude_v"] = timing_amplitude(cfg)
    shape = pulse_shape(cfg.procedure["pulse"]["shape"])
    for g in gyros_of(cfg):
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

def _rank(columns: list[list[float]]) -> int:
    """The number of independent columns (numpy's `matrix_rank` of the column stack, by
    Gram-Schmidt with its tolerance: the largest column norm x rows x machine epsilon),
    in plain Python: `bench validate` checks the positions without numpy."""
    rows = len(columns[0]) if columns else 0
    tol = max((math.hypot(*c) for c in columns), default=0.0) * max(rows, len(columns)) \
        * 2.220446049250313e-16
    basis: list[list[float]] = []
    for c in columns:
        r = list(c)
        for b in basis:     # twice: classical Gram-Schmidt, re-orthogonalised
            for _ in range(2):
                dot = math.fsum(x * y for x, y in zip(r, b, strict=True))
                r = [x - dot * y for x, y in zip(r, b, strict=True)]
        norm = math.hypot(*r)
        if norm > tol:
            basis.append([x / norm for x in r])
    return len(basis)


def _check_positions(cfg: Config) -> list[Problem]:
    pos = [float(p) for p in cfg.procedure.get("positions_deg", DriftFile.positions_deg)]
    theta = [math.radians(p) for p in pos]
    columns = [[1.0] * len(theta), [math.cos(t) for t in theta]]
    if any(abs(math.sin(t)) > 1e-9 for t in theta):
        columns.append([-math.sin(t) for t in theta])
    if _rank(columns) < len(columns) or len({round(p % 360, 6) for p in pos}) < 2:
        return [cfg.procedure_doc.problem(("positions_deg",), "the positions must separate "
                                          "own and apparent drift: include two 180 deg "
                                          "apart (e.g. [0, 180])")]
    return []

def timing_amplitude(cfg: Config) -> float:
    return float(cfg.procedure.get("timing_amplitude_v",
                                    TIMING_GAIN * cfg.procedure["pulse"]["amplitude_v"]))


def gyros_of(cfg: Config) -> list[str]:
    return list(cfg.procedure.get("gyros") or cfg.stand["platform"]["gyros"])


@dataclass(frozen=True)
class GyroSpec:
    """One gyro of the platform as the stand states it."""

    awg_channel: int
    dmm_resource: str
    dmm_model: str
    k_as_v_per_deg: float
    precession_dps_per_v: float
    k_as_u_rel: float = 0.0
    pulse_mismatch_max_rel: float = 0.0
    drift_random_walk_dph_per_rth: float = 0.0


@dataclass(frozen=True)
class PlatformSettings:
    """The stand's gyro platform and the gyros the procedure uses (all, on a stand
    alone: `bench devices`), with the twins' truth; parsed once."""

    gyros: tuple[str, ...]
    table_axis: str
    awg_resource: str
    awg_model: str
    platform: Mapping[str, GyroSpec]     # every gyro of the platform, by name
    #: the twins' truth (the stand's `sim.platform`, `sim.awg`, `sim.dmm`); None on hardware
    sim_platform: PlatformTruth | None
    awg_twin: Mapping[str, Any]
    awg_serial: str | None
    dmm_twin: Mapping[str, Any]
    dmm_serials: Mapping[str, str]
    #: gyro: its DMM twin's own errors (`sim.dmm.gain_error_rel`, `offset_error_v`; issue 58)
    dmm_errors: Mapping[str, Mapping[str, float]]

    @classmethod
    def of(cls, cfg: Config) -> PlatformSettings:
        parsed = cfg.settings
        return parsed if isinstance(parsed, PlatformSettings) else cls.parse_platform(cfg)

    @classmethod
    def parse_platform(cls, cfg: Config) -> PlatformSettings:
        return PlatformSettings(**_platform_fields(cfg))


def _platform_fields(cfg: Config) -> dict[str, Any]:
    plat = cfg.stand["platform"]
    table = str(plat["table_axis"])
    gyros = {g: GyroSpec(int(s["awg_channel"]), str(s["dmm"]["resource"]),
                         str(s["dmm"]["model"]), float(s["k_as_v_per_deg"]),
                         float(s["precession_dps_per_v"]),
                         float(s.get("k_as_u_rel", 0.0)),
                         float(s.get("pulse_mismatch_max_rel", 0.0)),
                         float(s.get("drift_random_walk_dph_per_rth", 0.0)))
             for g, s in plat["gyros"].items()}
    sim = cfg.stand.get("sim") or {}
    sp = sim.get("platform")
    sim_settings = cfg.stand_settings.sim
    truth = None if sp is None else PlatformTruth(
        latitude_deg=float(sp["latitude_deg"]), azimuth_deg=float(sp["azimuth_deg"]),
        gyros={g: GyroTruth(**{k: float(v) for k, v in (sp["gyros"].get(g) or {}).items()})
               for g in gyros_of(cfg) if g in sp["gyros"]},
        table_axis=table,   # the platform's drift walk is its truth, seeded as the stand
        seed=sim_settings.seed if sim_settings else 0)
    awg_twin = dict(sim.get("awg") or {})
    dmm_twin = dict(sim.get("dmm") or {})
    awg_serial, dmm_serials = awg_twin.pop("serial", None), dmm_twin.pop("serials", {})
    dmm_errors: dict[str, dict[str, float]] = {}
    for key in DMM_ERROR_KEYS:
        for g, v in (dmm_twin.pop(key, None) or {}).items():
            dmm_errors.setdefault(str(g), {})[key] = float(v)
    return dict(gyros=tuple(gyros_of(cfg)), table_axis=table,
                awg_resource=str(plat["awg"]["resource"]), awg_model=str(plat["awg"]["model"]),
                platform=gyros, sim_platform=truth, awg_twin=awg_twin,
                awg_serial=str(awg_serial) if awg_serial else None, dmm_twin=dmm_twin,
                dmm_serials={str(k): str(v) for k, v in dmm_serials.items()},
                dmm_errors=dmm_errors)


@dataclass(frozen=True)
class DriftSettings(PlatformSettings):
    """The validated procedure and the stand's platform, parsed once."""

    title: str
    pulse_shape: str
    amplitude_v: float
    timing_amplitude_v: float
    latitude_deg: float
    turn_rate_dps: float
    turn_accel_dps2: float
    position_tolerance_deg: float
    cycles: int
    timing_cycles: int
    positions_deg: tuple[float, ...]
    gap_s: float
    settle_s: float
    decision_rule: str
    prompts: bool
    own_drift_tolerance_dph: float | None
    timing: Timing
    #: as the procedure file states them (result.json's `method`)
    pulse_doc: Mapping[str, Any]
    site_doc: Mapping[str, Any]
    tolerance_doc: Mapping[str, Any]

    @classmethod
    def from_config(cls, cfg: Config) -> DriftSettings:
        parsed = cfg.settings
        return parsed if isinstance(parsed, DriftSettings) else cls.parse(cfg)

    @classmethod
    def parse(cls, cfg: Config) -> DriftSettings:
        p = cfg.procedure
        f = drift_file(cfg)
        fields = _platform_fields(cfg)
        drive = cfg.stand_settings.axes[fields["table_axis"]].drive
        return cls(
            **fields, title=cfg.common.title, pulse_shape=f.pulse.shape,
            amplitude_v=f.pulse.amplitude_v, timing_amplitude_v=timing_amplitude(cfg),
            latitude_deg=f.site.latitude_deg,
            turn_rate_dps=f.turn.rate_dps if f.turn else drive.max_rate_dps,
            turn_accel_dps2=f.turn.accel_dps2 if f.turn else drive.max_accel_dps2,
            position_tolerance_deg=drive.position_tolerance_deg,
            cycles=f.cycles, timing_cycles=f.timing_cycles, positions_deg=f.positions_deg,
            gap_s=f.gap_s, settle_s=f.settle_s, decision_rule=cfg.common.decision_rule,
            prompts=cfg.common.prompts,
            own_drift_tolerance_dph=f.tolerance.own_drift_dph,
            timing=Timing.of(cfg), pulse_doc=dict(p["pulse"]), site_doc=dict(p["site"]),
            tolerance_doc=dict(p.get("tolerance") or {}))
