"""Procedure and stand files: load, validate, cross-check (CONTRACT §2).

The schemas of the keys every procedure kind shares, and `Config`, what the loader
(bench/core/loader.py) returns once both files have passed.
"""

from __future__ import annotations

import datetime as dt
import functools
import os
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, Literal, TypeAlias

import msgspec
from msgspec import Meta, Struct

from bench.core.canbus import AxisBus, bus_problems
from bench.core.schema import (
    Key,
    Map,
    SettingsRefused,
    parse_date,
    struct_at,
    struct_map,
)
from bench.core.yamlfile import KeyPath, Problem, YamlDoc, YamlValue
from drivers.calibration import Calibration
from drivers.counter_profiles import get_profile
from drivers.counter_settings import CounterSettings
from drivers.drive_settings import DriveSettings
from drivers.fog_settings import FogSettings
from sims.drive_truth import DriveTruth
from sims.truth import AxisTruth, FogTruth

if TYPE_CHECKING:
    from _typeshed import DataclassInstance

#: a procedure as its kind parsed it: its frozen settings (a Struct or a dataclass)
KindParsed: TypeAlias = "msgspec.Struct | DataclassInstance"

# -- what is physically plausible for a rate table (wider than any real bench) ----------
#: the rate and acceleration bounds are the drive's (drivers/drive_settings.py)
#: one step of a plan longer than this (bench time) is refused: nobody runs it
STEP_MAX_S = 7 * 86_400.0

# -- stand file ---------------------------------------------------------------------

# Each stand block is declared once, as the msgspec Struct the bench reads (the drive's,
# counter's and FOG's in drivers/, the twins' truth in sims/truth.py, the rest
# here): each field's type, default, bounds and unit (msgspec.Meta) and meaning. The
# block's schema (`bench validate`, `bench schema`, JSON Schema) is `struct_map` of the
# Struct, its parse `struct_at` (bench/core/schema.py); what a Struct's own rules refuse
# is placed at its file, line and key by `struct_problems`. The procedure keys every kind
# shares (`CommonSettings`) are declared the same way.

CALIBRATION = struct_map(Calibration)


class Traceable(Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    """An entry of the stand's `traceability:` list: a reference the bench does not drive
    (a 10 MHz source, a sensor), with its calibration."""

    item: Annotated[str, Meta(description="what it is, e.g. 'GPS-disciplined 10 MHz "
                                          "reference'")]
    serial: Annotated[str, Meta(description="its serial number")] | None = None
    certificate: Annotated[str, Meta(description="its calibration certificate's number")]
    issuer: Annotated[str, Meta(description="the laboratory that issued it")]
    due: Annotated[dt.date, Meta(description="calibration due date, YYYY-MM-DD")]
    traces: Annotated[str, Meta(description="the quantity it traces to SI")] | None = None

    @property
    def calibration(self) -> Calibration:
        return Calibration(self.certificate, self.issuer, self.due, self.traces)


TRACEABLE = struct_map(Traceable)


DRIVE = struct_map(DriveSettings)
COUNTER = struct_map(CounterSettings)


FOG = struct_map(FogSettings)


class StandAxisFile(Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    """One axis of the stand file (`axes.<axis>`), as `parse_stand` reads it into a
    `StandAxis`."""

    drive: Annotated[DriveSettings, Meta(description="the axis's servo drive (CANopen CiA "
                                                     "402)")]
    counter: Annotated[CounterSettings, Meta(description="the counter timing the zero-mark "
                                                         "pulse, once per turn")] | None = None
    fog: Annotated[FogSettings, Meta(description="the reference gyro (FOG) mounted on the "
                                                 "axis")] | None = None


def _absolute_path(value: str) -> str | None:
    """A key or certificate is named by its path, never pasted in (the stand file is
    copied into every run directory); relative paths would depend on the cwd."""
    if "-----BEGIN" in value:
        return "expected the path of a PEM file, not the key or certificate itself"
    if not Path(os.path.expanduser(value)).is_absolute():
        return f"expected an absolute path (or ~/...), got {value!r}"
    return None


#: a path key: text, an absolute path (the rule `_absolute_path`)
PathKey = Annotated[str, Meta(extra={"check": _absolute_path})]


class SigningFile(Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    """The DCC's signing key (bench/app/dcc/settings.py, docs/dcc.md): paths only."""

    key: Annotated[PathKey, Meta(description="PEM private key (PKCS#8 or traditional), "
                                             "absolute path")]
    certificate: Annotated[PathKey, Meta(description="PEM X.509 certificate of that key, "
                                                     "chain after")]
    password_env: Annotated[str, Meta(description="environment variable holding the "
                                                  "key's password")] | None = None


class StandDccFile(Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    """The stand's `dcc:` block."""

    lab: Annotated[PathKey, Meta(description="lab settings file (YAML), absolute "
                                             "path")] | None = None
    signing: Annotated[SigningFile, Meta(description="the DCC's signing key and certificate "
                                                     "(docs/dcc.md)")] | None = None


SIGNING = struct_map(SigningFile)
STAND_DCC = struct_map(StandDccFile)


class Identity(Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    """The table under test (the stand's `stand:` block)."""

    maker: Annotated[str, Meta(description="the table's maker")]
    model: Annotated[str, Meta(description="its model")]
    serial: Annotated[str, Meta(description="its serial number (text; the records key)")]
    location: Annotated[str, Meta(description="where it stands")] | None = None
    recertification_interval_days: Annotated[int, Meta(
        ge=1, extra={"unit": "d"},
        description="the table's recertification interval (lab settings may "
                    "override)")] | None = None


IDENTITY = struct_map(Identity)


class BenchName(Struct, frozen=True, forbid_unknown_fields=True):
    """The stand's `bench:` block: this bench among the lab's."""

    name: Annotated[str, Meta(description="the bench's name on the lab server, unique in "
                                          "the lab (default: this machine's host "
                                          "name)")] | None = None


BENCH = struct_map(BenchName)


def _bus_rule(axes: dict[str, Any]) -> list[tuple[KeyPath, str]]:
    """The buses' check, on the axes the schema accepted (each drive's bus and ids)."""
    return bus_problems(msgspec.convert(axes, dict[str, AxisBus]))


class StandFile(Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    """The stand file's top-level keys (CONTRACT §2), each block its own Struct; a
    procedure kind adds its own instruments (`stand_schema`)."""

    stand: Annotated[Identity, Meta(description="the rate table under test")]
    axes: Annotated[dict[str, StandAxisFile], Meta(
        description="the table's axes, by the names procedures use",
        extra={"check": _bus_rule})]
    sim: Annotated[SimSettings, Meta(
        description="the twins' truth: present, the stand runs on simulated twins; absent, "
                    "on hardware")] | None = None
    traceability: Annotated[tuple[Traceable, ...], Meta(
        description="references and sensors the bench does not drive, with their "
                    "calibration certificates")] = ()
    dcc: Annotated[StandDccFile, Meta(
        description="DCC: lab settings file, signing key (paths only)")] | None = None
    bench: Annotated[BenchName, Meta(
        description="this bench among the lab's benches (the lab server's station shows "
                    "each by its name; docs/station.md)")] | None = None
    mains_hz: Annotated[float, Meta(
        ge=1, le=1000, extra={"unit": "Hz"},
        description="the lab's mains frequency (50 or 60); without it the analysis finds "
                    "the mains tone from the data")] | None = None


def stand_schema(extra_top: dict[str, Key] | None = None,
                 extra_sim: dict[str, Key] | None = None) -> Map:
    """The stand file's schema; a procedure kind may add instruments of its own, at the
    top and in the `sim:` block (their twins' truth)."""
    keys = dict(struct_map(StandFile).keys)
    sim = keys["sim"]
    keys["sim"] = Key(Map({**SIM_KEYS, **(extra_sim or {})}), sim.required, sim.doc)
    return Map({**keys, **(extra_top or {})})


# -- procedure file: the keys every procedure kind shares ------------------------------

# The procedure's `item:`, `decision_rule_agreement:` and `specification:` blocks: the
# certificate reads them as the file states them (bench/app/certificate/item.py), so
# CommonSettings keeps them as mappings; their keys are declared here.

class ItemFile(Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    """The procedure's `item:` block: the item as received and as left."""

    received: Annotated[dt.date, Meta(description="the date the item was received "
                                                  "(ISO/IEC 17025 7.8.2.1 g)")] | None = None
    condition: Annotated[str, Meta(description="its condition on receipt "
                                               "(7.4.3)")] | None = None
    as_found_run: Annotated[str, Meta(
        description="the as-found run this as-left run repeats after an adjustment: its "
                    "run id (run directory name)")] | None = None
    adjustments: Annotated[tuple[str, ...], Meta(
        description="adjustments made to the item before this run (7.8.4.1 b)")] \
        | None = None


class AgreementFile(Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    """The procedure's `decision_rule_agreement:` block (ISO/IEC 17025 7.1.3)."""

    agreed_with: Annotated[str, Meta(description="who agreed to the decision rule for the "
                                                 "customer")]
    agreed_on: Annotated[dt.date, Meta(description="when, YYYY-MM-DD")]
    reference: Annotated[str, Meta(description="where it is recorded (order, contract "
                                               "review)")] | None = None


class SpecificationFile(Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    """The procedure's `specification:` block: where the tolerances come from."""

    source: Annotated[str, Meta(description="the document the tolerances come from: maker, "
                                            "title, revision, date")]
    definitions: Annotated[dict[str, str], Meta(
        description="how the document defines each figure, by tolerance key")] | None = None


class CommonSettings(Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    """The procedure keys every kind shares, declared once and parsed once."""

    #: required in a file; "" in the procedure a command makes up (`bench devices`)
    procedure: Annotated[str, Meta(description="the procedure kind (bench schema procedure "
                                               "KIND)", extra={"required": True})] = ""
    #: resolved by the parse: the file's, else the file name
    title: Annotated[str, Meta(description="printed on the plan and the certificate "
                                           "(default: the file name)",
                               extra={"given": True})]
    stand: Annotated[str, Meta(description="stand file, relative to this file",
                               extra={"required": True})] = ""
    conditions: Annotated[dict[str, Any], Meta(
        description="recorded conditions, printed on the certificate")] \
        = msgspec.field(default_factory=dict)
    certificate: Annotated[dict[str, Any], Meta(
        description="customer, laboratory, ... for the certificate")] \
        = msgspec.field(default_factory=dict)
    decision_rule: Annotated[Literal["simple", "guard-band"], Meta(
        description="how a verdict is decided against the tolerance (ILAC-G8): simple "
                    "acceptance or a guard band")] = "simple"
    prompts: Annotated[bool, Meta(description="ask the operator before each axis (mount the "
                                              "FOG...); --yes answers")] = True
    calibration_state: Annotated[Literal["as-found", "as-left"], Meta(
        description="as-found before an adjustment, as-left after (the records pair them; "
                    "--as-found/--as-left win)")] | None = None
    adjustment_note: Annotated[str, Meta(
        description="what was adjusted since the as-found run")] | None = None
    # the certificate reads these three as the file writes them: mappings, their keys
    # declared by the blocks' Structs
    item: Annotated[dict[str, Any], Meta(
        description="the item as received and as left; each part left out is printed 'not "
                    "stated' (docs/certificate.md)", extra={"written": ItemFile})] | None = None
    decision_rule_agreement: Annotated[dict[str, Any], Meta(
        description="the customer's agreement to decision_rule (ISO/IEC 17025 7.1.3); "
                    "without it the certificate says 'not stated'",
        extra={"written": AgreementFile})] | None = None
    operator: Annotated[str, Meta(
        description="who runs the procedure (default: the login name)")] | None = None
    specification: Annotated[dict[str, Any], Meta(
        description="where the tolerances come from; printed with the statement of "
                    "conformity", extra={"written": SpecificationFile})] | None = None


COMMON_PROCEDURE_KEYS: dict[str, Key] = dict(struct_map(CommonSettings).keys)


def _opt(spec: dict[str, Any], key: str, cast: Any) -> Any:
    """A validated optional key, cast, or None when the file leaves it out."""
    return cast(spec[key]) if spec.get(key) is not None else None


@dataclass(frozen=True)
class Traced:
    """One calibrated item of the stand (bench/core/traceability.py)."""

    where: str                 # key path in the stand file, e.g. axes.outer.counter
    item: str
    certificate: str | None
    issuer: str | None
    due: dt.date | None
    traces: str | None
    #: the serial the stand file states for an item the bench does not read (a reference)
    stated_serial: str | None = None
    #: the serial the stand file states for the item, instrument or reference (the key the
    #: lab register's inventory is looked up by)
    serial: str | None = None

    def overdue(self, on: dt.date) -> bool:
        return self.due is not None and on > self.due

    @property
    def stated(self) -> bool:
        return self.certificate is not None


def _traced_name(path: tuple[str, ...], spec: Mapping[str, YamlValue]) -> str:
    role = path[-1]
    where = " ".join(p for p in path[1:-1] if p not in ("axes", "gyros"))
    model = spec.get("model")
    return f"{role}{' ' + str(model) if model else ''}{f' ({where})' if where else ''}"


def _instruments(node: YamlValue, path: tuple[str, ...]
                 ) -> Iterator[tuple[tuple[str, ...], Mapping[str, YamlValue]]]:
    """Every block of the stand that is an instrument (it has an address or a
    calibration), whichever kind's block holds it (a gyro platform's DMMs too)."""
    if not isinstance(node, dict):
        return
    for key, value in node.items():
        if key == "sim" and not path:
            continue  # the twins' truth, not the bench
        if isinstance(value, dict):
            sub = (*path, str(key))
            if "resource" in value or "port" in value or "interface" in value \
                    or "calibration" in value:
                yield sub, value
            yield from _instruments(value, sub)


def _str(value: YamlValue) -> str | None:
    """A stated text (a serial or certificate may be written as a number), None when
    the file leaves it out or empty."""
    return str(value) if value else None


def stated_traceability(stand: Mapping[str, YamlValue]) -> tuple[Traced, ...]:
    """Every instrument of a stand mapping (with or without a stated calibration) and
    every entry of its `traceability:` list."""
    out = []
    for path, spec in _instruments(dict(stand), ()):
        cal = got if isinstance(got := spec.get("calibration"), dict) else {}
        traces = cal.get("traces")
        out.append(Traced(".".join(path), _traced_name(path, spec),
                          _str(cal.get("certificate")), _str(cal.get("issuer")),
                          parse_date(cal.get("due")),
                          traces if isinstance(traces, str) else None,
                          serial=_str(spec.get("serial"))))
    listed = stand.get("traceability")
    for i, t in enumerate(listed if isinstance(listed, list) else []):
        if isinstance(t, dict):
            traces = t.get("traces")
            out.append(Traced(f"traceability[{i}]", str(t.get("item", "")),
                              str(t.get("certificate")), str(t.get("issuer")),
                              parse_date(t.get("due")),
                              traces if isinstance(traces, str) else None,
                              _str(t.get("serial")), _str(t.get("serial"))))
    return tuple(out)


@dataclass(frozen=True)
class StandAxis:
    """One axis of the stand: its drive, and the counter and FOG that watch it."""

    name: str
    drive: DriveSettings
    counter: CounterSettings | None = None
    fog: FogSettings | None = None


@dataclass(frozen=True)
class SimAxis:
    """The twins' truth for one axis (the stand's `sim.axes.<axis>`)."""

    #: the axis's truth, which the twins read whole (each its own parts)
    truth: AxisTruth
    scale_step: tuple[int, float] | None = None      # (from_run, rel)
    scale_ramp: tuple[int, float] | None = None      # (from_run, rel_per_run)
    tie_latency_s: float | None = None      # None: exactly the latency the stand declares
    tie_jitter_s: float = 0.0
    #: the drive twin's power-on configuration (its serial from `serials.drive`)
    drive: DriveTruth = DriveTruth()


#: truth used by `--sim` for an axis the stand file's `sim:` block does not describe
DEFAULT_SIM_AXIS = SimAxis(AxisTruth(fog=FogTruth(noise_dps=0.01), turn_jitter_s=27e-9))


class SimSettings(Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    """The stand's `sim:` block: the twins' truth (absent on a real bench)."""

    seed: Annotated[int, Meta(ge=0, description="the twins' random seed: a run's numbers "
                                                "depend on it and the files alone")] = 0
    clock_speed: Annotated[float, Meta(gt=0, description=(
        "virtual seconds per real one, or max: as fast as every twin keeps up"))] \
        | Literal["max"] | None = None
    #: written as sims/truth.py AxisTruth, parsed by `_sim_axis` (each truth's default is its
    #: dataclass field's)
    axes: Annotated[dict[str, SimAxis], Meta(
        description="each axis's truth, by stand axis name",
        extra={"written": dict[str, AxisTruth]})] = msgspec.field(default_factory=dict)
    run_number: Annotated[int, Meta(ge=1, description="this run's number for a drifting twin "
                                    "(default: 1 + the runs of this table in the "
                                    "records)")] | None = None
    #: `bench sim`: "socketcand", served to other processes
    can_bus: Annotated[str, Meta(extra={"file": False})] = "virtual"
    #: set for a --resume: the session these twins serve
    session: Annotated[int, Meta(extra={"file": False})] = 1

    def axis(self, name: str) -> SimAxis:
        return self.axes.get(name, DEFAULT_SIM_AXIS)

    @property
    def has_drift(self) -> bool:
        return any(a.scale_step or a.scale_ramp for a in self.axes.values())


SIM_KEYS: dict[str, Key] = dict(struct_map(SimSettings).keys)


@dataclass(frozen=True)
class DccRefs:
    """The stand's `dcc:` block: paths only (the lab file, the signing key)."""

    lab: str | None = None
    signing_key: str | None = None
    signing_certificate: str | None = None
    password_env: str | None = None


@dataclass(frozen=True)
class StandSettings:
    """The validated stand file, parsed once: what every reader below the loader uses."""

    identity: Identity
    axes: Mapping[str, StandAxis]
    sim: SimSettings | None = None
    traceability: tuple[Traceable, ...] = ()
    dcc: DccRefs = DccRefs()
    mains_hz: float | None = None
    #: the stand file's `bench.name`: how the lab server knows this bench (None: unnamed,
    #: bench/app/fleet names it by the host)
    bench_name: str | None = None
    #: every instrument and reference with its calibration as stated (traceability)
    traced: tuple[Traced, ...] = ()
    #: addresses of a kind's own instruments rewritten to their twins' (SimBench), by
    #: the key path of the address in the stand file ("platform.awg.resource")
    addresses: Mapping[str, str] = field(default_factory=dict)

    @property
    def simulated(self) -> bool:
        return self.sim is not None

    def address(self, where: str, stated: str) -> str:
        """The address of a kind's instrument: its twin's on a simulated bench."""
        return self.addresses.get(where, stated)


def _sim_axis(d: dict[str, Any], at: KeyPath) -> SimAxis:
    """A `sim.axes.<axis>` block, read into its one declaration (sims/truth.py AxisTruth;
    a key left out takes its default there)."""
    t = struct_at(AxisTruth, d, at)
    tie, step, ramp = t.time_tie, t.fog.scale_step, t.fog.scale_ramp
    drive = (t.drive if t.serials.drive is None
             else msgspec.structs.replace(t.drive, serial_number=t.serials.drive))
    return SimAxis(
        t, scale_step=(step.from_run, step.rel) if step else None,
        scale_ramp=(ramp.from_run, ramp.rel_per_run) if ramp else None,
        tie_latency_s=tie.latency_s, tie_jitter_s=tie.jitter_s, drive=drive)


def dcc_refs(stand: Mapping[str, Any] | None) -> DccRefs:
    """The `dcc:` block of a stand mapping (also a run directory's copy, read back)."""
    dcc = (stand or {}).get("dcc") or {}
    signing = dcc.get("signing") or {}
    return DccRefs(_opt(dcc, "lab", str), _opt(signing, "key", str),
                   _opt(signing, "certificate", str), _opt(signing, "password_env", str))


def parse_stand(stand: dict[str, Any]) -> StandSettings:
    """A validated stand mapping as frozen settings (the kinds' own stand blocks, such as
    a gyro platform's, are parsed by the kind)."""
    from bench.core.canbus import controller_node_ids

    # a kind's stand schema may leave out the axes (a plug-in kind without a table)
    ident = stand.get("stand") or {}
    stand_axes = stand.get("axes") or {}
    controllers = controller_node_ids(msgspec.convert(stand_axes, dict[str, AxisBus]))
    axes: dict[str, StandAxis] = {}
    for name, a in stand_axes.items():
        c, f = a.get("counter"), a.get("fog")
        axes[name] = StandAxis(
            name, struct_at(DriveSettings, a["drive"], ("axes", name, "drive"),
                      controller_node_id=controllers[name]),
            struct_at(CounterSettings, c, ("axes", name, "counter")) if c else None,
            struct_at(FogSettings, f, ("axes", name, "fog")) if f else None)
    sim = None
    if "sim" in stand:
        s = stand["sim"] or {}   # a kind's own keys beside (a platform's truth): its parse
        sim = struct_at(SimSettings, {k: v for k, v in s.items()
                                      if k in SIM_KEYS and k != "axes" and v is not None},
                        ("sim",), axes={n: _sim_axis(v or {}, ("sim", "axes", n))
                                        for n, v in (s.get("axes") or {}).items()})
    trace = tuple(struct_at(Traceable, t, ("traceability", i))
                  for i, t in enumerate(stand.get("traceability") or []))
    return StandSettings(
        identity=(struct_at(Identity, ident, ("stand",)) if ident
                  else Identity(maker="", model="", serial="")),
        axes=axes, sim=sim, traceability=trace,
        dcc=dcc_refs(stand), traced=stated_traceability(stand),
        mains_hz=_opt(stand, "mains_hz", float),
        bench_name=struct_at(BenchName, stand.get("bench") or {}, ("bench",)).name)


def parse_common(procedure: Mapping[str, YamlValue], path: Path) -> CommonSettings:
    """The shared keys of a validated procedure (a kind's own keys are its parse's; a key
    written null takes its default)."""
    return struct_at(CommonSettings, {k: v for k, v in procedure.items()
                                      if k in COMMON_PROCEDURE_KEYS and v is not None},
                     title=str(procedure.get("title", path.stem)))


@dataclass(frozen=True)
class Config:
    """A validated procedure with its stand."""

    procedure_path: Path
    stand_path: Path
    procedure: dict[str, Any]
    stand: dict[str, Any]
    procedure_doc: YamlDoc
    stand_doc: YamlDoc
    #: the procedure as its kind parsed it (`ProcedureKind.parse`; set by the loader)
    settings: KindParsed | None = None

    @functools.cached_property
    def common(self) -> CommonSettings:
        """The procedure keys every kind shares, parsed once."""
        return parse_common(self.procedure, self.procedure_path)

    @functools.cached_property
    def stand_settings(self) -> StandSettings:
        """The stand, parsed once: what the engine, the kinds and the twins read."""
        return parse_stand(self.stand)

    @property
    def kind(self) -> str:
        name: str = self.procedure["procedure"]
        return name

    @property
    def has_sim(self) -> bool:
        return "sim" in self.stand

    def stand_axis(self, name: str) -> StandAxis:
        return self.stand_settings.axes[name]

    def fog(self, axis: str) -> FogSettings:
        """The axis's FOG settings (validated: a procedure that needs a FOG has one)."""
        fog = self.stand_settings.axes[axis].fog
        if fog is None:
            raise KeyError(f"axis {axis} has no fog")
        return fog


class ConfigError(Exception):
    """Every problem found in a procedure and its stand file."""

    def __init__(self, problems: list[Problem]) -> None:
        self.problems = problems
        super().__init__("\n".join(str(p) for p in problems))


def real_stand_problems(sdoc: YamlDoc) -> list[Problem]:
    """What a real stand (no `sim:` block) must state because no driver can guess it.

    The FOG's units are required by the schema for every stand; here, the time tie: on
    twins one clock ties the counter to the FOG, on hardware only a physical link does
    (drivers/time_tie.py), so a real stand with a counter and a FOG must say how.
    """
    data = sdoc.data if isinstance(sdoc.data, dict) else {}
    axes = got if isinstance(got := data.get("axes"), dict) else {}
    out = reference_problems(sdoc, axes)
    if "sim" in data:
        return out
    for name, axis in axes.items():
        if not isinstance(axis, dict):
            continue
        drive = axis.get("drive")
        if isinstance(drive, dict) and "unit_factors" not in drive:
            out.append(sdoc.problem(
                ("axes", name, "drive"),
                "a real stand must state drive.unit_factors: 'read' (the drive's factor "
                "group is read at connect) or {velocity: ..., acceleration: ...} to set "
                "(common drives default to rpm or inc/s; see docs/configuration.md, "
                "axes.<name>.drive.unit_factors)"))
        counter, fog = axis.get("counter"), axis.get("fog")
        if isinstance(counter, dict) and fog and "time_tie" not in counter:
            out.append(sdoc.problem(
                ("axes", name, "counter"),
                "a real stand must state counter.time_tie (how the counter's start event "
                "is placed on the FOG's time axis: source fog-sync with sync_period_s, "
                "latency_s and latency_u_s, or host-clock); see docs/configuration.md, "
                "axes.<name>.counter.time_tie"))
        tie = counter.get("time_tie") if isinstance(counter, dict) else None
        if isinstance(tie, dict) and tie.get("source") == "fog-sync":
            missing = [k for k in ("sync_period_s", "latency_s", "latency_u_s")
                       if k not in tie]
            if missing:   # else the tie's uncertainty would silently be 0 in the budget
                out.append(sdoc.problem(
                    ("axes", name, "counter", "time_tie"),
                    f"a fog-sync time tie on a real stand must state {', '.join(missing)} "
                    "(the link's calibrated latency and its standard uncertainty enter "
                    "the counter's budget); see docs/configuration.md, "
                    "axes.<name>.counter.time_tie"))
    return out


def struct_problems(sdoc: YamlDoc, refused: list[Problem]) -> list[Problem]:
    """What the stand's Struct-declared blocks refuse beyond the schema's nodes (the rules
    of a block, e.g. a drive's watchdog against its heartbeat, a FOG's sign), each at its
    file, line and key: each block the nodes accepted is built as the run will build it."""
    data = sdoc.data if isinstance(sdoc.data, dict) else {}
    axes = got if isinstance(got := data.get("axes"), dict) else {}
    out = []
    for name, axis in axes.items():
        for key, cls in (("drive", DriveSettings), ("counter", CounterSettings),
                         ("fog", FogSettings)):
            block = axis.get(key) if isinstance(axis, dict) else None
            if not isinstance(block, dict) or any(
                    p.key == f"axes.{name}.{key}" or p.key.startswith(f"axes.{name}.{key}.")
                    for p in refused):
                continue
            try:
                struct_at(cls, block, ("axes", name, key))
            except SettingsRefused as e:
                out.append(sdoc.problem(e.path, e.message))
    return out


def reference_problems(sdoc: YamlDoc, axes: dict[Any, Any]) -> list[Problem]:
    """The counter's timebase as the stand states it, against its budget.

    The budget takes the timebase limit from `timebase_limit_rel`, else from the
    counter model's internal oscillator; the counter is set to `reference` and read back
    (drivers/counter.py refuses a different read-back). A stand saying `external` without
    the external reference's limit would put the internal oscillator's limit in the
    budget of a counter running on another clock; one saying `internal` with a limit
    below the oscillator's claims what it does not have. A real stand must say which.
    """
    out = []
    real = "sim" not in (sdoc.data if isinstance(sdoc.data, dict) else {})
    for name, axis in axes.items():
        counter = axis.get("counter") if isinstance(axis, dict) else None
        if not isinstance(counter, dict):
            continue
        where = ("axes", name, "counter")
        ref, limit = counter.get("reference"), counter.get("timebase_limit_rel")
        if ref is None:
            # twins too: a twin's counter runs on its external reference by default, and a
            # budget taking the internal oscillator's limit would contradict its read-back
            out.append(sdoc.problem(where, f"{'a real stand' if real else 'the stand'} must "
                                    "state counter.reference: external (a 10 MHz reference "
                                    "at Ext Ref In, with its timebase_limit_rel) or internal; "
                                    "the counter is set to it and read back, and the budget "
                                    "takes its limit (docs/configuration.md)"))
        elif ref == "external" and limit is None:
            out.append(sdoc.problem((*where, "reference"), "reference: external needs the "
                                    "external reference's timebase_limit_rel (from its "
                                    "certificate); without it the budget would assume the "
                                    "counter's internal oscillator"))
        elif ref == "internal" and isinstance(limit, int | float):
            try:
                own = get_profile(str(counter.get("model"))).timebase_limit_rel
            except (KeyError, ValueError):
                continue
            if limit < own:
                out.append(sdoc.problem((*where, "timebase_limit_rel"),
                                        f"{limit:g} is below the {counter.get('model')}'s "
                                        f"internal oscillator limit {own:g}, but reference is "
                                        "internal: state reference: external (and connect "
                                        "Ext Ref In) or the oscillator's limit"))
    return out


def check_axis_names(cfg: Config, axes_key: str = "axes") -> list[Problem]:
    """Every axis a procedure names must exist in its stand file."""
    out = []
    for axis in cfg.procedure.get(axes_key, {}):
        if axis not in cfg.stand["axes"]:
            out.append(cfg.procedure_doc.problem(
                (axes_key, axis), f"the stand file {cfg.stand_path} has no axis {axis!r} "
                f"(it has {', '.join(cfg.stand['axes'])})"))
    return out

