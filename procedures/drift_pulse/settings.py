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

import msgspec
from msgspec import Meta, Struct

from bench.core.config import COMMON_PROCEDURE_KEYS, Config, Identity
from bench.core.schema import Map, struct_at, struct_map
from bench.core.yamlfile import Problem
from drivers.awg import PROFILES as AWG_PROFILES
from drivers.calibration import Calibration
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

# Each key of the drift kind's files is declared once, on the msgspec Struct that holds it
# as the file states it: its type, default, bounds (`Meta(ge=..)`), unit
# (`Meta.extra["unit"]`) and meaning (`Meta.description`). The schemas `bench validate`,
# `bench schema` and docs/configuration.md read are `struct_map` of them, and the kind's
# settings are built from them with `struct_at` (bench/core/schema.py).

def _u(unit: str, description: str | None = None, *, gt: float | None = None,
       ge: float | None = None, le: float | None = None) -> Meta:
    """A number's Meta: its unit, meaning and bounds."""
    bounds: dict[str, Any] = {k: v for k, v in (("gt", gt), ("ge", ge), ("le", le))
                              if v is not None}
    return Meta(description=description, extra={"unit": unit}, **bounds)


class Site(Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    latitude_deg: Annotated[float, _u("deg", ge=-90, le=90)]
    name: str | None = None


class Pulse(Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    shape: Annotated[str, Meta(extra={"choices": tuple(SHAPES)},
                               description="rectangular, triangular (or sawtooth)")]
    duration_s: Annotated[float, _u("s", "Tc, each pulse", gt=0)]
    amplitude_v: Annotated[float, _u("V", "peak voltage into the torque-sensor current "
                                          "amplifier", gt=0)]
    points: Annotated[int, Meta(ge=4, le=500_000,
                                description="waveform points per pulse")] = 1000


class Turn(Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    rate_dps: Annotated[float, _u("deg/s", gt=0)]
    accel_dps2: Annotated[float, _u("deg/s^2", gt=0)]


class Digitizer(Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    sample_rate_hz: Annotated[float, _u("Hz", "the DMMs' sample rate", gt=0)] = 2000.0
    #: None: 0.8 of the interval
    aperture_s: Annotated[float, _u("s", "default 0.8 of the interval", gt=0)] | None = None
    range_v: Annotated[float, _u("V", "the DMMs' range", gt=0)] = 10.0
    margin_s: Annotated[float, _u("s", "recorded after the pair", ge=0)] = 0.05


class DriftTolerance(Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    own_drift_dph: Annotated[float, _u("deg/h", gt=0)] | None = None


Position = Annotated[float, _u("deg", ge=-360, le=360)]
GyroName = Annotated[str, Meta(extra={"choices": GYRO_NAMES})]


class DriftFile(Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    """The drift-pulse procedure file's own keys as it states them, defaults filled in."""

    site: Site
    pulse: Pulse
    cycles: Annotated[int, Meta(ge=4, le=10_000, description="measuring cycles per "
                                "position (4 at least for the scatter)")] = 10
    timing_cycles: Annotated[int, Meta(ge=0, le=1000, description="large-amplitude cycles "
                                       "that locate the pulses")] = 4
    timing_amplitude_v: Annotated[float, _u(
        "V", "default 8 x the pulse amplitude, within the DMM range", gt=0)] | None = None
    positions_deg: Annotated[tuple[Position, ...], Meta(
        min_length=2, description="turntable positions")] = (0.0, 180.0)
    gap_s: Annotated[float, _u("s", "pause between cycles", ge=0)] = 0.5
    settle_s: Annotated[float, _u("s", "pause after a turn", ge=0)] = 5.0
    turn: Annotated[Turn, Meta(
        description="default: the drive's max rate and acceleration")] | None = None
    digitizer: Digitizer = Digitizer()
    gyros: Annotated[tuple[GyroName, ...], Meta(
        min_length=1, description="which of the platform's gyros (default: all)")] | None = None
    tolerance: DriftTolerance = DriftTolerance()


PROCEDURE = Map({**COMMON_PROCEDURE_KEYS, **struct_map(DriftFile).keys})
_DRIFT_KEYS = frozenset(f.encode_name for f in msgspec.structs.fields(DriftFile))


class GyroDmm(Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    resource: Annotated[str, Meta(description="VISA resource string")]
    model: Annotated[str, Meta(extra={"choices": tuple(DMM_PROFILES)})]
    serial: Annotated[str, Meta(description="the DMM's serial: the lab register's item "
                                            "(its runs are found by it: bench "
                                            "impact)")] | None = None
    calibration: Annotated[Calibration, Meta(
        description="the DMM's certificate")] | None = None


class GyroSpec(Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    """One gyro of the platform as the stand states it (`platform.gyros.<gyro>`)."""

    model: Annotated[str, Meta(description="the gyro's model (printed as part of the item "
                                           "calibrated)")] | None = None
    serial: Annotated[str, Meta(description="the gyro's serial number (printed as part of "
                                            "the item)")] | None = None
    awg_channel: Annotated[int, Meta(ge=1, le=4)]
    dmm: GyroDmm
    k_as_v_per_deg: Annotated[float, _u("V/deg", "the command angle sensor's transfer "
                                                 "coefficient", gt=0)]
    k_as_u_rel: Annotated[float, Meta(ge=0, description="its standard uncertainty, "
                                                        "relative")] = 0.0
    precession_dps_per_v: Annotated[float, _u("deg/s per V", "nominal k_ts * gain / H "
                                                             "(range checks only)", gt=0)]
    pulse_mismatch_max_rel: Annotated[float, Meta(
        ge=0, description="bound of the +/- amplitude mismatch")] = 0.0
    drift_random_walk_dph_per_rth: Annotated[float, Meta(
        ge=0, description="the gyro's spec")] = 0.0

    @property
    def dmm_resource(self) -> str:
        return self.dmm.resource

    @property
    def dmm_model(self) -> str:
        return self.dmm.model


class PlatformAwg(Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    resource: str
    model: Annotated[str, Meta(extra={"choices": tuple(AWG_PROFILES)})]
    serial: Annotated[str, Meta(description="the generator's serial: the lab register's "
                                            "item (its runs are found by it: bench "
                                            "impact)")] | None = None
    calibration: Annotated[Calibration, Meta(
        description="the generator's certificate")] | None = None


class PlatformFile(Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    """The stand's `platform:` block: the gyro platform under test and its wiring."""

    identity: Annotated[Identity, Meta(description="the platform under test")] | None = None
    table_axis: Annotated[str, Meta(description="the stand axis the platform sits on")]
    awg: PlatformAwg
    gyros: Annotated[dict[str, GyroSpec], Meta(min_length=1)]


class SimGyro(Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    """A gyro's truth (`sim.platform.gyros.<gyro>`): sims/truth.py `GyroTruth`'s fields
    (SIM_GYRO_KEYS, tests/test_drift_procedure.py), each left out taking its default."""

    own_drift_dph: float | None = None
    precession_dps_per_v: float | None = None
    k_as_v_per_deg: float | None = None
    angle_offset_deg: float | None = None
    angle_noise_arcsec: float | None = None
    pulse_mismatch_rel: float | None = None
    pulse_jitter_s: float | None = None
    drift_random_walk_dph_per_rth: float | None = None


class SimPlatform(Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    latitude_deg: Annotated[float, Meta(ge=-90, le=90)]
    azimuth_deg: Annotated[float, Meta(description="the X input axis at turntable 0, "
                                                   "from north")]
    gyros: dict[str, SimGyro]


class SimAwg(Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    """The generator twin's truth (`sim.awg`; each a keyword of sims/awg_twin.AwgTwin)."""

    output_latency_s: Annotated[float, Meta(ge=0)] | None = None
    trigger_out_skew_s: float | None = None
    trigger_out_width_s: Annotated[float, Meta(ge=0)] | None = None
    load_ohm: Annotated[float, Meta(ge=1)] | None = None
    serial: Annotated[str, Meta(description="the serial the twin reports (*IDN? field "
                                            "3)")] | None = None
    amplitude_error_rel: Annotated[float, Meta(
        ge=-0.5, le=0.5, description="the generator's true amplitude error a, unknown to "
        "the lab: every output voltage x (1 + a) (issue 58)")] = 0.0


class SimDmm(Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    """The DMM twins' truth (`sim.dmm`; each a keyword of sims/dmm_twin.DmmTwin)."""

    trigger_latency_s: Annotated[float, Meta(ge=0)] | None = None
    serials: Annotated[dict[str, str], Meta(
        description="gyro: the serial its DMM twin reports")] | None = None
    gain_error_rel: Annotated[dict[str, Annotated[float, Meta(ge=-0.5, le=0.5)]], Meta(
        description="gyro: its DMM's true gain error g, unknown to the lab: every reading "
        "the twin returns x (1 + g) (default 0; issue 58)")] | None = None
    offset_error_v: Annotated[dict[str, Annotated[float, _u("V")]], Meta(
        description="gyro: its DMM's true offset o, unknown to the lab: every reading + o, "
        "after the gain (default 0; issue 58)")] | None = None


PLATFORM = struct_map(PlatformFile)
SIM_PLATFORM = struct_map(SimPlatform)
SIM_AWG = struct_map(SimAwg)
SIM_DMM = struct_map(SimDmm)


def drift_file(cfg: Config) -> DriftFile:
    """The procedure file's own keys, parsed (validated: the loader's cross-checks run
    on files the schema passed; a key written null takes its default)."""
    return struct_at(DriftFile, {k: v for k, v in cfg.procedure.items()
                                 if k in _DRIFT_KEYS and v is not None})


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
    def of(cls, f: DriftFile) -> Timing:
        """The timing of the procedure's pulse and digitizer (docs/method.md B)."""
        d = f.digitizer
        tc, points = f.pulse.duration_s, f.pulse.points
        interval = 1.0 / d.sample_rate_hz
        aperture = d.aperture_s if d.aperture_s is not None else 0.8 * interval
        lead_s = 1.0 / (points / tc)
        count = int(math.ceil((2 * tc + lead_s + d.margin_s) / interval)) + 1
        return cls(tc, points, points / tc, interval, aperture, d.range_v, count,
                   max(interval - 0.5 * aperture, 0.0))


def _near_int(x: float) -> bool:
    return abs(x - round(x)) < 1e-6 * max(1.0, abs(x))


def platform_file(cfg: Config) -> PlatformFile:
    """The stand's `platform:` block, parsed (validated, as `drift_file`'s)."""
    return struct_at(PlatformFile, cfg.stand["platform"], ("platform",))


def drift_problems(cfg: Config) -> list[Problem]:
    """The checks that need both files: the platform's wiring, the pulse timing
    against the instruments, the positions, the turn against the drive."""
    pdoc, sdoc = cfg.procedure_doc, cfg.stand_doc
    f, plat = drift_file(cfg), platform_file(cfg)
    axes = cfg.stand_settings.axes
    out: list[Problem] = []
    table = plat.table_axis
    if table not in axes:
        out.append(sdoc.problem(("platform", "table_axis"), f"the stand has no axis "
                                f"{table!r} (it has {', '.join(axes)})"))
    for g in plat.gyros:
        if g not in GYRO_NAMES:
            out.append(sdoc.problem(("platform", "gyros", g), "a gyro is x, y "
                                    "(horizontal) or z (vertical)"))
    for i, g in enumerate(f.gyros or ()):
        if g not in plat.gyros:
            out.append(pdoc.problem(("gyros", i), f"the stand's platform has no gyro {g!r}"))
    awg = AWG_PROFILES[plat.awg.model]
    channels: dict[int, str] = {}
    for g, spec in plat.gyros.items():
        ch = spec.awg_channel
        if ch not in awg.channels:
            out.append(sdoc.problem(("platform", "gyros", g, "awg_channel"),
                                    f"the {awg.model} has channels {awg.channels}"))
        if ch in channels:
            out.append(sdoc.problem(("platform", "gyros", g, "awg_channel"),
                                    f"channel {ch} already drives gyro {channels[ch]}"))
        channels[ch] = g
    gyros = _gyros(f, plat)
    out += _check_timing(cfg, f, plat, gyros)
    out += _check_positions(cfg, f)
    if abs(f.site.latitude_deg) > 84.0:
        out.append(pdoc.problem(("site", "latitude_deg"), "within 6 deg of a pole the "
                                "Earth's horizontal rate is too small for an azimuth"))
    if table in axes and f.turn is not None:
        drive = axes[table].drive
        for key, value, limit, most in (
                ("rate_dps", f.turn.rate_dps, "max_rate_dps", drive.max_rate_dps),
                ("accel_dps2", f.turn.accel_dps2, "max_accel_dps2", drive.max_accel_dps2)):
            if value > most:
                out.append(pdoc.problem(("turn", key), f"{value:g} exceeds the drive's "
                                        f"{limit} {most:g}"))
    sim = cfg.stand.get("sim")
    if sim is not None:
        sp = sim.get("platform")
        if sp is None:
            out.append(sdoc.problem(("sim",), "a simulated drift-pulse bench needs "
                                    "sim.platform (the platform's truth)"))
        else:
            for g in gyros:
                if g not in sp["gyros"]:
                    out.append(sdoc.problem(("sim", "platform", "gyros"),
                                            f"no truth for gyro {g!r}"))
    return out

def _check_timing(cfg: Config, f: DriftFile, plat: PlatformFile,
                  gyros: list[str]) -> list[Problem]:
    pdoc, sdoc = cfg.procedure_doc, cfg.stand_doc
    t = Timing.of(f)
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
    awg = AWG_PROFILES[plat.awg.model]
    lo, hi = awg.sample_rate_range_hz
    if not lo <= t.awg_rate_hz <= hi or 2 * t.points + 2 > awg.max_points:
        out.append(pdoc.problem(("pulse", "points"), f"{t.points} points in {t.tc_s:g} s do "
                                f"not fit the {awg.model} ({awg.max_points} points, "
                                f"{lo:g} .. {hi:g} Sa/s)"))
    amps = {"amplitude_v": f.pulse.amplitude_v}
    if f.timing_cycles:
        amps["timing_amplitude_v"] = _timing_amplitude(f)
    shape = pulse_shape(f.pulse.shape)
    for g in gyros:
        spec = plat.gyros.get(g)
        if spec is None:
            continue
        dmm = DMM_PROFILES[spec.dmm.model]
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
            excursion = (spec.k_as_v_per_deg * spec.precession_dps_per_v * amp
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


def _check_positions(cfg: Config, f: DriftFile) -> list[Problem]:
    pos = list(f.positions_deg)
    theta = [math.radians(p) for p in pos]
    columns = [[1.0] * len(theta), [math.cos(t) for t in theta]]
    if any(abs(math.sin(t)) > 1e-9 for t in theta):
        columns.append([-math.sin(t) for t in theta])
    if _rank(columns) < len(columns) or len({round(p % 360, 6) for p in pos}) < 2:
        return [cfg.procedure_doc.problem(("positions_deg",), "the positions must separate "
                                          "own and apparent drift: include two 180 deg "
                                          "apart (e.g. [0, 180])")]
    return []

def _timing_amplitude(f: DriftFile) -> float:
    """The timing cycles' amplitude: as written, else TIMING_GAIN x the pulse's."""
    return (f.timing_amplitude_v if f.timing_amplitude_v is not None
            else TIMING_GAIN * f.pulse.amplitude_v)


def _gyros(f: DriftFile, plat: PlatformFile) -> list[str]:
    """The gyros the procedure uses: as it names them, else all the platform's."""
    return list(f.gyros or plat.gyros)


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
        named = cfg.procedure.get("gyros")   # a stand alone (`bench devices`): all
        return PlatformSettings(**_platform_fields(cfg, list(named) if named else None))


def _platform_fields(cfg: Config, gyros: list[str] | None = None) -> dict[str, Any]:
    """PlatformSettings' fields from the stand's typed `platform:` and `sim` blocks."""
    plat = platform_file(cfg)
    used = list(plat.gyros) if gyros is None else gyros
    sim = cfg.stand.get("sim") or {}
    sp = sim.get("platform")
    sim_settings = cfg.stand_settings.sim
    truth = None
    if sp is not None:
        st = struct_at(SimPlatform, sp, ("sim", "platform"))
        truth = PlatformTruth(
            latitude_deg=st.latitude_deg, azimuth_deg=st.azimuth_deg,
            gyros={g: GyroTruth(**{k: v for k, v in msgspec.structs.asdict(st.gyros[g]).items()
                                   if v is not None})
                   for g in used if g in st.gyros},
            table_axis=plat.table_axis,   # the platform's drift walk is its truth, seeded
            seed=sim_settings.seed if sim_settings else 0)   # as the stand
    awg = struct_at(SimAwg, sim.get("awg") or {}, ("sim", "awg"))
    dmm = struct_at(SimDmm, sim.get("dmm") or {}, ("sim", "dmm"))
    written = set(sim.get("awg") or {})
    awg_twin = {k: v for k, v in msgspec.structs.asdict(awg).items()
                if k != "serial" and k in written}
    dmm_twin = {} if dmm.trigger_latency_s is None \
        else {"trigger_latency_s": dmm.trigger_latency_s}
    dmm_errors: dict[str, dict[str, float]] = {}
    for key, by_gyro in (("gain_error_rel", dmm.gain_error_rel),
                         ("offset_error_v", dmm.offset_error_v)):
        for g, v in (by_gyro or {}).items():
            dmm_errors.setdefault(g, {})[key] = v
    return dict(gyros=tuple(used), table_axis=plat.table_axis,
                awg_resource=plat.awg.resource, awg_model=plat.awg.model,
                platform=plat.gyros, sim_platform=truth, awg_twin=awg_twin,
                awg_serial=awg.serial or None, dmm_twin=dmm_twin,
                dmm_serials=dict(dmm.serials or {}), dmm_errors=dmm_errors)


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
        fields = _platform_fields(cfg, _gyros(f, platform_file(cfg)))
        drive = cfg.stand_settings.axes[fields["table_axis"]].drive
        return cls(
            **fields, title=cfg.common.title, pulse_shape=f.pulse.shape,
            amplitude_v=f.pulse.amplitude_v, timing_amplitude_v=_timing_amplitude(f),
            latitude_deg=f.site.latitude_deg,
            turn_rate_dps=f.turn.rate_dps if f.turn else drive.max_rate_dps,
            turn_accel_dps2=f.turn.accel_dps2 if f.turn else drive.max_accel_dps2,
            position_tolerance_deg=drive.position_tolerance_deg,
            cycles=f.cycles, timing_cycles=f.timing_cycles, positions_deg=f.positions_deg,
            gap_s=f.gap_s, settle_s=f.settle_s, decision_rule=cfg.common.decision_rule,
            prompts=cfg.common.prompts,
            own_drift_tolerance_dph=f.tolerance.own_drift_dph,
            timing=Timing.of(f), pulse_doc=dict(p["pulse"]), site_doc=dict(p["site"]),
            tolerance_doc=dict(p.get("tolerance") or {}))
