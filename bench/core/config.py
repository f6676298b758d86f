"""Procedure and stand files: load, validate, cross-check (CONTRACT §2).

The schemas of the keys every procedure kind shares, and `Config`, what the loader
(bench/core/loader.py) returns once both files have passed.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from bench.core.canbus import bus_problems
from bench.core.schema import Any_, Bool, Check, Date, Key, ListOf, Map, MapOf, Num, OneOf, Str
from bench.core.yamlfile import Problem, YamlDoc
from drivers.counter_profiles import get_profile

# -- what is physically plausible for a rate table (wider than any real bench) ----------
#: a rate table's fastest axes turn some 10 000 deg/s; its slowest useful rate is around
#: 0.001 deg/s (one turn in 100 h): anything outside is a typing slip, not a bench
RATE_MIN_DPS, RATE_MAX_DPS = 1e-3, 20_000.0
ACCEL_MAX_DPS2 = 100_000.0
#: the counter's input range (a 10x probe on +/-5 V)
LEVEL_MAX_V = 50.0
#: one step of a plan longer than this (bench time) is refused: nobody runs it
STEP_MAX_S = 7 * 86_400.0

# -- stand file ---------------------------------------------------------------------

CALIBRATION = Map({
    "certificate": Key(Str(), True, "the calibration certificate's number"),
    "issuer": Key(Str(), True, "the laboratory that issued it"),
    "due": Key(Date(), True, "calibration due date, YYYY-MM-DD"),
    "traces": Key(Str(), False, "the quantity it traces to SI, e.g. 'time interval to the "
                                "SI second'"),
})
TRACEABLE = Map({   # a reference the bench does not drive (a 10 MHz source, a sensor)
    "item": Key(Str(), True, "what it is, e.g. 'GPS-disciplined 10 MHz reference'"),
    "serial": Key(Str(), False, "its serial number"),
    "certificate": Key(Str(), True, "its calibration certificate's number"),
    "issuer": Key(Str(), True, "the laboratory that issued it"),
    "due": Key(Date(), True, "calibration due date, YYYY-MM-DD"),
    "traces": Key(Str(), False, "the quantity it traces to SI"),
})
DRIVE = Map({
    "interface": Key(Str(), True, "python-can interface: socketcan, pcan, kvaser, virtual..."),
    "channel": Key(Str(), True, "python-can channel, e.g. can0"),
    "node_id": Key(Num(min=1, max=127, integer=True), True, "the drive's CANopen node id"),
    "controller_node_id": Key(Num(min=1, max=127, integer=True), False,
                              "this axis's controller node on the bus, whose heartbeat "
                              "the drive watches (default: highest id free on the bus)"),
    "bitrate": Key(Num(min=10_000, max=1_000_000, integer=True, unit="bit/s"), False,
                   "CAN bit rate, where the interface needs it (socketcan takes the link's)"),
    "max_rate_dps": Key(Num(min=RATE_MIN_DPS, max=RATE_MAX_DPS, unit="deg/s"), True,
                        "the axis's rate limit: a command above it is refused, never clipped"),
    "max_accel_dps2": Key(Num(min=0, exclusive_min=True, max=ACCEL_MAX_DPS2,
                              unit="deg/s^2"), True, "the axis's acceleration limit (and the "
                          "ramps' default)"),
    "counts_per_rev": Key(Num(min=1, integer=True), False, "encoder counts per revolution "
                          "(position and velocity units of the drive)"),
    "heartbeat_ms": Key(Num(min=10, max=10_000, integer=True), False,
                        "controller heartbeat period; the drive watches it"),
    "watchdog_ms": Key(Num(min=20, max=65_535, integer=True), False,
                       "drive stops the axis when the controller is silent this long"),
    "settle_tolerance_dps": Key(Num(min=0, exclusive_min=True, unit="deg/s"), False,
                                "the drive's own velocity window (CiA 402 0x606D)"),
    "position_tolerance_deg": Key(Num(min=0, exclusive_min=True, unit="deg"), False,
                                  "how close a position move must land (profile position)"),
    "eds": Key(Str(), False, "the drive's EDS file, for canopen's object dictionary"),
    "serial": Key(Str(), False, "the instrument's serial number: the key of its "
                                "check values (bench control)"),
    "calibration": Key(CALIBRATION, False, "the encoder's calibration certificate, if any"),
    "unit_factors": Key(Any_(), False,
                        "'read' (the drive's factor group 0x608F/0x6091/0x60A9/0x60AA is "
                        "read at connect) or {velocity: rpm|inc/s|0.001 inc/s|..., "
                        "acceleration: rpm/s|inc/s2|...} written at connect and read back; "
                        "a stand without a sim: block must state it"),
    "pdo": Key(Str(("set", "verify")), False,
               "TPDO transmission type / event timer: verify (default) or set at connect"),
})
COUNTER = Map({
    "resource": Key(Str(), True, "VISA resource string"),
    "model": Key(Str(), True, "counter profile"),
    "serial": Key(Str(), False, "the instrument's serial number: the key of its "
                                "check values (bench control)"),
    "channel": Key(Num(min=1, max=4, integer=True), False, "input channel of the zero-mark "
                   "pulse"),
    "level_v": Key(Num(min=-LEVEL_MAX_V, max=LEVEL_MAX_V, unit="V"), False,
                   "absolute trigger level; required on a real stand (a twin defaults it)"),
    "slope": Key(Str(("POS", "NEG")), False, "the pulse edge timed"),
    "coupling": Key(Str(("DC", "AC")), False, "input coupling"),
    "impedance_ohm": Key(Num(min=0, exclusive_min=True, unit="ohm"), False,
                         "input impedance (50 or 1e6)"),
    "trigger_jitter_s": Key(Num(min=0, unit="s"), False, "slot sensor edge jitter, std"),
    "timebase_limit_rel": Key(Num(min=0), False, "timebase error limit (external reference)"),
    "reference": Key(Str(("external", "internal")), False,
                     "timebase: set at connect and read back (53230A SENS:ROSC:SOUR); a "
                     "timebase_limit_rel below the model's needs 'external'"),
    "timeout_margin_s": Key(Num(min=0, exclusive_min=True, max=3600, unit="s"), False,
                            "extra time allowed beyond a half's expected turns before "
                            "the counter counts as silent"),
    "calibration": Key(CALIBRATION, False, "the counter's calibration certificate"),
    "time_tie": Key(Map({
        "source": Key(Str(("fog-sync", "host-clock")), True,
                      "how the counter's start event is placed on the FOG's time axis: "
                      "fog-sync (external trigger from the FOG's sync output) or host-clock"),
        "sync_period_s": Key(Num(min=0, exclusive_min=True, unit="s"), False,
                             "FOG time between sync pulses (pulse k at k * period)"),
        "latency_s": Key(Num(min=0, unit="s"), False, "sync pulse to counter trigger, "
                         "calibrated"),
        "latency_u_s": Key(Num(min=0, unit="s"), False, "its standard uncertainty (with "
                           "jitter)"),
        "host_window_s": Key(Num(min=0, unit="s"), False, "how well the host knows the "
                             "FOG's time axis"),
    }), False, "how the counter's start is tied to the FOG's time axis (docs/"
               "configuration.md); a stand without a sim: block must state it"),
})
#: the FOG keys' defaults, used by the schema's reference and by `FogSettings` (one place)
FOG_DEFAULTS: dict[str, Any] = {"baudrate": 921600, "format": "kvh-a", "axis": "z",
                                "configure": "declare"}
FOG = Map({
    "port": Key(Str(), True, "serial port, e.g. /dev/ttyUSB0"),
    "baudrate": Key(Num(min=1200, max=16_000_000, integer=True), False, "serial line rate",
                     FOG_DEFAULTS["baudrate"]),
    "format": Key(Str(), False, "frame format, e.g. kvh-a", FOG_DEFAULTS["format"]),
    "axis": Key(Str(("x", "y", "z")), False, "the FOG axis along the table axis",
                 FOG_DEFAULTS["axis"]),
    "rate_hz": Key(Num(min=1, max=100_000, unit="Hz"), True, "the FOG's output (frame) rate"),
    "range_dps": Key(Num(min=0, exclusive_min=True, max=100_000, unit="deg/s"), False,
                     "the FOG's measuring range: a rate above it is refused"),
    "units": Key(Str(("deg/s", "rad/s", "deg", "rad")), True,
                  "what the rotational fields carry; KVH's power-on default is delta "
                  "radians, 'rad' (1775 IMU Technical Manual, Table 5-10)"),
    "configure": Key(Str(("set", "verify", "declare")), False,
                     "set: configure the FOG at connect and read back; verify: read back "
                     "only; declare: trust fog.units", FOG_DEFAULTS["configure"]),
    "serial": Key(Str(), False, "the FOG's serial number (it answers no identity query, "
                  "so the certificate prints it as the stand file states it; the key of its "
                  "check values, bench control)"),
    "model": Key(Str(), False, "maker and model, for the certificate"),
    "sign": Key(Num(min=-1, max=1, integer=True), False, "-1 when the FOG is mounted with "
                "its sensitive axis against the table's positive sense"),
    "calibration": Key(CALIBRATION, False, "the FOG's calibration certificate, if any"),
})
STAND_AXIS_KEYS: dict[str, Key] = {
    "drive": Key(DRIVE, True, "the axis's servo drive (CANopen CiA 402)"),
    "counter": Key(COUNTER, False, "the counter timing the zero-mark pulse, once per turn"),
    "fog": Key(FOG, False, "the reference gyro (FOG) mounted on the axis"),
}
HARMONIC = Map({
    "order": Key(Num(min=1, integer=True), True, "h: cycles per turn"),
    "amplitude_rel": Key(Num(min=0), True, "a, relative to the set rate"),
    "phase_deg": Key(Num(unit="deg"), False, "p, at the zero mark"),
})
SIM_FOG = Map({**{k: Key(Num(unit=u), False, doc) for k, u, doc in (
                   ("scale", "", "scale factor"), ("bias_dps", "deg/s", "bias w0"),
                   ("misalignment_deg", "deg", "sensitive axis to table axis"),
                   ("noise_dps", "deg/s", "white noise std per sample"),
                   ("bias_drift_dps_per_h", "deg/s/h", "linear bias drift from the start"))},
               # a FOG that drifts across runs (bench/core/simdrift.py, bench control)
               "scale_step": Key(Map({"from_run": Key(Num(min=1, integer=True), True,
                                                      "the first run with the step"),
                                      "rel": Key(Num(), True, "the step, a fraction of the "
                                                 "scale")}), False,
                                 "scale x (1 + rel) from run from_run on"),
               "scale_ramp": Key(Map({"from_run": Key(Num(min=1, integer=True), True,
                                                      "the first run of the ramp"),
                                      "rel_per_run": Key(Num(), True, "the change per run, "
                                                         "a fraction of the scale")}), False,
                                 "scale x (1 + rel_per_run per run) from run from_run on"),
               "units": Key(Str(("deg/s", "rad/s", "deg", "rad")), False,
                            "what the twin carries before the bench configures it "
                            "(default: delta radians, or the declared fog.units)")})
SIM_AXIS = Map({
    "rate_bias_rel": Key(Num(), False, "mean table rate = set x (1 + this)"),
    "harmonics": Key(ListOf(HARMONIC), False, "w_true - w_set = w_set x sum a cos(h phi + p)"),
    "mains": Key(Map({"frequency_hz": Key(Num(min=0, exclusive_min=True, unit="Hz"), False,
                                          "the ripple's frequency"),
                      "amplitude_dps": Key(Num(min=0, unit="deg/s"), False, "its amplitude"),
                      "phase_deg": Key(Num(unit="deg"), False, "its phase at t = 0")}),
                 False,
                 "a mains-frequency rate ripple"),
    "rate_noise_dps": Key(Num(min=0, unit="deg/s"), False, "white table rate noise while "
                          "turning, std per FOG sample"),
    "turn_jitter_s": Key(Num(min=0, unit="s"), False, "zero-mark edge timing std"),
    "fog": Key(SIM_FOG, False, "the FOG's truth: k = scale cos(misalignment), w0 = bias"),
    "counter_external_reference": Key(Bool(), False, "a valid 10 MHz is wired to the "
                                      "counter's Ext Ref In (default true)"),
    "counter_first_value": Key(Str(("from-start", "edge-to-edge")), False,
                               "how the 53230A twin reads its first timestamp value: from "
                               "the trigger (default) or edge to edge (the Programmer's "
                               "Reference's SENSe:TSTamp:RATE example)"),
    "time_tie": Key(Map({"latency_s": Key(Num(min=0, unit="s"), False, "true latency"),
                         "jitter_s": Key(Num(min=0, unit="s"), False, "its jitter, std")}),
                    False, "the FOG sync to counter trigger link: true latency and jitter"),
    "serials": Key(Map({"counter": Key(Str(), False, "the counter twin's *IDN? serial"),
                        "drive": Key(Num(min=0, max=2**32 - 1, integer=True), False,
                                     "the drive twin's serial number, 0x1018:4")}), False,
                   "the serial each twin reports: the counter's *IDN? serial field, the "
                   "drive's identity object 0x1018:4"),
    "drive": Key(Map({"velocity_unit": Key(Str(), False, "e.g. rpm, inc/s"),
                      "acceleration_unit": Key(Str(), False, "e.g. rpm/s, inc/s2"),
                      "tpdo_event_timer_ms": Key(Num(min=0, integer=True, unit="ms"), False,
                                                 "0: TPDOs on change only")}), False,
                 "the drive twin's factor group (e.g. rpm, rpm/s) and TPDO event timer"),
})
SIM_KEYS: dict[str, Key] = {
    "seed": Key(Num(min=0, integer=True), False, "the twins' random seed: a run's numbers "
                "depend on it and the files alone"),
    "clock_speed": Key(OneOf(Num(min=0, exclusive_min=True), Str(("max",))), False,
                       "virtual seconds per real one, or max: as fast as every twin keeps up"),
    "axes": Key(MapOf(SIM_AXIS), False, "each axis's truth, by stand axis name"),
    "run_number": Key(Num(min=1, integer=True), False,
                      "this run's number for a drifting twin (default: 1 + the runs of "
                      "this table in the records)"),
}


def _absolute_path(value: Any) -> str | None:
    """A key or certificate is named by its path, never pasted in (the stand file is
    copied into every run directory); relative paths would depend on the cwd."""
    if isinstance(value, str) and "-----BEGIN" in value:
        return "expected the path of a PEM file, not the key or certificate itself"
    if isinstance(value, str) and not Path(os.path.expanduser(value)).is_absolute():
        return f"expected an absolute path (or ~/...), got {value!r}"
    return None


ABSOLUTE_PATH = Check(Str(), _absolute_path)
SIGNING = Map({    # the DCC's signing key (bench/app/dcc/settings.py, docs/dcc.md)
    "key": Key(ABSOLUTE_PATH, True, "PEM private key (PKCS#8 or traditional), absolute path"),
    "certificate": Key(ABSOLUTE_PATH, True, "PEM X.509 certificate of that key, chain after"),
    "password_env": Key(Str(), False, "environment variable holding the key's password"),
})
STAND_DCC = Map({
    "lab": Key(ABSOLUTE_PATH, False, "lab settings file (YAML), absolute path"),
    "signing": Key(SIGNING, False, "the DCC's signing key and certificate (docs/dcc.md)"),
})
IDENTITY = Map({"maker": Key(Str(), True, "the table's maker"),
                "model": Key(Str(), True, "its model"),
                "serial": Key(Str(), True, "its serial number (text; the records key)"),
                "location": Key(Str(), False, "where it stands"),
                "recertification_interval_days": Key(
                    Num(min=1, integer=True, unit="d"), False,
                    "the table's recertification interval (lab settings may override)")})


def stand_schema(extra_top: dict[str, Key] | None = None,
                 extra_axis: dict[str, Key] | None = None,
                 extra_sim: dict[str, Key] | None = None) -> Map:
    """The stand file's schema; a procedure kind may add instruments of its own."""
    return Map({
        "stand": Key(IDENTITY, True, "the rate table under test"),
        "axes": Key(Check(MapOf(Map({**STAND_AXIS_KEYS, **(extra_axis or {})})),
                          bus_problems), True, "the table's axes, by the names procedures "
                    "use"),
        "sim": Key(Map({**SIM_KEYS, **(extra_sim or {})}), False, "the twins' truth: "
                   "present, the stand runs on simulated twins; absent, on hardware"),
        "traceability": Key(ListOf(TRACEABLE), False, "references and sensors the bench "
                            "does not drive, with their calibration certificates"),
        "dcc": Key(STAND_DCC, False, "DCC: lab settings file, signing key (paths only)"),
        "mains_hz": Key(Num(min=1, max=1000, unit="Hz"), False,
                        "the lab's mains frequency (50 or 60); without it the analysis "
                        "finds the mains tone from the data"),
        **(extra_top or {}),
    })


# -- procedure file: the keys every procedure kind shares ------------------------------

COMMON_PROCEDURE_KEYS: dict[str, Key] = {
    "procedure": Key(Str(), True, "the procedure kind (bench schema procedure KIND)"),
    "title": Key(Str(), False, "printed on the plan and the certificate (default: the file "
                               "name)"),
    "stand": Key(Str(), True, "stand file, relative to this file"),
    "conditions": Key(MapOf(Any_()), False, "recorded conditions, printed on the certificate"),
    "certificate": Key(MapOf(Any_()), False, "customer, laboratory, ... for the certificate"),
    "decision_rule": Key(Str(("simple", "guard-band")), False, "how a verdict is decided "
                         "against the tolerance (ILAC-G8); default simple acceptance"),
    "prompts": Key(Bool(), False, "ask the operator before each axis (mount the FOG...); "
                                  "default true, --yes answers"),
    "calibration_state": Key(Str(("as-found", "as-left")), False,
                             "as-found before an adjustment, as-left after (the records "
                             "pair them; --as-found/--as-left win)"),
    "adjustment_note": Key(Str(), False, "what was adjusted since the as-found run"),
    "operator": Key(Str(), False, "who runs the procedure (default: the login name)"),
    "specification": Key(Map({
        "source": Key(Str(), True, "the document the tolerances come from: maker, title, "
                                   "revision, date"),
        "definitions": Key(MapOf(Str()), False, "how the document defines each figure, by "
                                                "tolerance key"),
    }), False, "where the tolerances come from; printed with the statement of conformity"),
}


@dataclass(frozen=True)
class FogSettings:
    """A stand's `fog:` block, parsed once, every default here (the schema above says
    which keys are required): the live driver, the twin, the analysis reading the raw
    capture, the disk-space estimate and the station view all take it from here."""

    port: str
    rate_hz: float
    units: str
    baudrate: int = FOG_DEFAULTS["baudrate"]
    format: str = FOG_DEFAULTS["format"]
    axis: str = FOG_DEFAULTS["axis"]
    configure: str = FOG_DEFAULTS["configure"]
    model: str | None = None

    @classmethod
    def of(cls, fog: dict[str, Any]) -> FogSettings:
        fields = {k: fog[k] for k in ("baudrate", "format", "axis", "configure", "model")
                  if k in fog}
        return cls(port=str(fog["port"]), rate_hz=float(fog["rate_hz"]),
                   units=str(fog["units"]), **fields)

    @classmethod
    def of_axis(cls, stand: dict[str, Any], axis: str) -> FogSettings | None:
        """The FOG of `axis`, or None when the axis has none (or the stand is damaged:
        the station view reads run directories it did not write)."""
        f = ((stand.get("axes") or {}).get(axis) or {}).get("fog")
        if not isinstance(f, dict) or not all(k in f for k in ("port", "rate_hz", "units")):
            return None
        return cls.of(f)


@dataclass(frozen=True)
class Config:
    """A validated procedure with its stand."""

    procedure_path: Path
    stand_path: Path
    procedure: dict[str, Any]
    stand: dict[str, Any]
    procedure_doc: YamlDoc
    stand_doc: YamlDoc

    @property
    def kind(self) -> str:
        return self.procedure["procedure"]

    @property
    def has_sim(self) -> bool:
        return "sim" in self.stand

    def stand_axis(self, name: str) -> dict[str, Any]:
        return self.stand["axes"][name]

    def fog(self, axis: str) -> FogSettings:
        """The axis's FOG settings (validated: a procedure that needs a FOG has one)."""
        return FogSettings.of(self.stand["axes"][axis]["fog"])


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

