"""The rate ladder's procedure file: its keys, their defaults, and the rules that read them."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Annotated, Any, Literal

import msgspec
from msgspec import Meta, Struct

from bench.core.config import (
    COMMON_PROCEDURE_KEYS,
    STEP_MAX_S,
    Config,
    check_axis_names,
)
from bench.core.plan import format_duration
from bench.core.schema import Map, struct_at, struct_map
from bench.core.yamlfile import Problem, YamlDoc
from drivers.counter_profiles import PROFILES as COUNTER_PROFILES
from drivers.drive_settings import ACCEL_MAX_DPS2, RATE_MAX_DPS, RATE_MIN_DPS
from drivers.fog_settings import DEFAULT_RANGE_DPS

NAME = "rate-ladder"

# Each key of the ladder's procedure file is declared once, on the msgspec Struct the plan,
# the analysis and the certificate read: its type, default, bounds (`Meta(ge=..)`), unit
# (`Meta.extra["unit"]`) and meaning (`Meta.description`). PROCEDURE is `struct_map` of
# them, the parse `struct_at` (bench/core/schema.py); a field the parse resolves from
# other keys is `Meta.extra["given"]`, one the file never states `Meta.extra["file"]`.

#: not a key of the file: set by the parse
_SET = Meta(extra={"file": False})


class Band(Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    """One tolerance band: `rel` applies to rates below `below_dps` (None: the rest)."""

    below_dps: Annotated[float, Meta(
        gt=0, le=RATE_MAX_DPS, extra={"unit": "deg/s"},
        description="the band applies to rates below this; omit on the last band")] \
        | None = None
    rel: Annotated[float, Meta(gt=0, le=1, description="tolerance, a fraction (1e-6 = "
                                                       "1 ppm)")]


class Settle(Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    """When a rate counts as reached (the procedure's `settle:`)."""

    tolerance_dps: Annotated[float, Meta(
        gt=0, le=100, extra={"unit": "deg/s"},
        description="settled when within the larger of this and tolerance_rel x "
                    "rate")] = 0.005
    tolerance_rel: Annotated[float, Meta(
        gt=0, le=1, description="settling tolerance relative to the rate")] = 1e-3
    hold_s: Annotated[float, Meta(
        ge=0, le=86_400, extra={"unit": "s"},
        description="how long the rate must stay within tolerance")] = 2.0
    timeout_s: Annotated[float, Meta(
        gt=0, le=STEP_MAX_S, extra={"unit": "s"},
        description="a rate that has not settled by then aborts the run")] = 60.0

    def tolerance_at(self, rate_dps: float) -> float:
        return max(self.tolerance_dps, self.tolerance_rel * abs(rate_dps))


#: turns per rate and direction when the file gives none
DEFAULT_TURNS = 5
Turns = Annotated[int, Meta(ge=1, le=10_000)]
Rate = Annotated[float, Meta(ge=RATE_MIN_DPS, le=RATE_MAX_DPS, extra={"unit": "deg/s"})]


class AxisSettings(Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    """One axis of the ladder as it runs: its own `turns` where it gives one, its ramp
    acceleration (the procedure's `accel_dps2`, never above the drive's limit)."""

    name: Annotated[str, _SET]
    rates_dps: Annotated[tuple[Rate, ...], Meta(
        min_length=1, description="rate magnitudes; each runs +w then -w")]
    #: resolved by the parse: the axis's own, else the file's
    turns: Annotated[Turns, Meta(description="turns per rate and direction on this axis "
                                             "(default: the file's turns)",
                                 extra={"given": True})]
    prompt: Annotated[str, Meta(description="what the operator must do before this "
                                            "axis")] | None = None
    accel_dps2: Annotated[float, _SET] = 0.0


Bands = Annotated[tuple[Band, ...], Meta(min_length=1)]


class Tolerance(Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    """What the table's maker claims, by rate band (the procedure's `tolerance:`); a key
    left out: reported, not judged."""

    rate_error: Annotated[Bands, Meta(description="|mean - set| / |set| (eq. 1)")] = ()
    rate_instability: Annotated[Bands, Meta(
        description="per-turn rate std / rate (eq. 2)")] = ()
    intra_turn_instability: Annotated[Bands, Meta(
        description="std of the random part within a turn / rate")] = ()

    def get(self, key: str) -> tuple[Band, ...] | None:
        """The bands of tolerance key `key` (rate_error, ...); None: the file states none."""
        bands: tuple[Band, ...] = getattr(self, key)
        return bands or None

    def items(self) -> list[tuple[str, tuple[Band, ...]]]:
        """The keys the file states, with their bands, in TOLERANCE_KEYS' order."""
        return [(k, b) for k in TOLERANCE_KEYS if (b := getattr(self, k))]


TOLERANCE_KEYS = ("rate_error", "rate_instability", "intra_turn_instability")


class LadderSettings(Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    """The validated procedure file, parsed once; each key declared here, once.

    The plan, the analysis and the certificate's Method table all read these, so a
    per-axis `turns` is what each of them says (issue 12)."""

    #: the file's top-level default, per rate and direction
    turns: Annotated[Turns, Meta(description="turns per rate and direction; an odd count "
                                             "with sequence +-+ splits the + half "
                                             "unevenly")] = DEFAULT_TURNS
    sequence: Annotated[Literal["+-", "+-+"], Meta(
        description="order of the halves of a pair (+-+ cancels a linear FOG bias "
                    "drift)")] = "+-+"
    accel_dps2: Annotated[float, Meta(
        gt=0, le=ACCEL_MAX_DPS2, extra={"unit": "deg/s^2"},
        description="ramp acceleration (default and limit: the drive's "
                    "max_accel_dps2)")] | None = None
    settle: Annotated[Settle, Meta(description="when a rate counts as reached")] = Settle()
    static_record_s: Annotated[float, Meta(
        ge=0, le=86_400, extra={"unit": "s"},
        description="FOG at rest per axis (noise floor)")] = 60.0
    harmonics: Annotated[int, Meta(ge=1, le=20,
                                   description="orders 1..H fitted in angle")] = 4
    #: resolved by the parse (`mains_of`); None: found from the data (MAINS_CANDIDATES_HZ)
    mains_hz: Annotated[float, Meta(
        ge=1, le=1000, extra={"unit": "Hz"},
        description="mains frequency of the lab's grid; overrides the stand's `mains_hz` "
                    "(without either, found from the data: 50 and 60 Hz are "
                    "tried)")] | None = None
    axes: Annotated[dict[str, AxisSettings], Meta(
        min_length=1, description="the axes to certify, by their stand names",
        extra={"required": True})] = msgspec.field(default_factory=dict)
    tolerance: Annotated[Tolerance, Meta(
        description="what the table's maker claims, by rate band; a figure without a band "
                    "is reported, not judged")] = Tolerance()
    mains_source: Annotated[str, _SET] = ""
    decision_rule: Annotated[str, _SET] = "simple"
    prompts: Annotated[bool, _SET] = True
    title: Annotated[str, _SET] = ""

    @classmethod
    def from_config(cls, cfg: Config) -> LadderSettings:
        parsed = cfg.settings
        return parsed if isinstance(parsed, LadderSettings) else cls.parse(cfg)

    @classmethod
    def parse(cls, cfg: Config) -> LadderSettings:
        """The validated file as the ladder runs it: each axis's turns (its own, else the
        file's) and ramp acceleration (the file's, never above the drive's limit)."""
        p = cfg.procedure
        own = {k: v for k, v in p.items() if k in _LADDER_KEYS and v is not None}
        turns = int(own.get("turns", DEFAULT_TURNS))
        mains_hz, mains_source = mains_of(cfg)
        stand = cfg.stand_settings
        accel = own.get("accel_dps2")
        axes = {}
        for name, spec in (own.pop("axes", None) or {}).items():
            limit = stand.axes[name].drive.max_accel_dps2 if name in stand.axes else 0.0
            axes[name] = struct_at(
                AxisSettings, {k: v for k, v in spec.items() if v is not None},
                ("axes", name), name=name, turns=int(spec.get("turns", turns)),
                accel_dps2=min(float(accel), limit) if accel is not None else limit)
        parsed = struct_at(cls, own, mains_hz=mains_hz, mains_source=mains_source,
                           decision_rule=cfg.common.decision_rule,
                           prompts=cfg.common.prompts, title=cfg.common.title)
        # the axes set after: a procedure a command makes up names none (`bench devices`)
        return msgspec.structs.replace(parsed, axes=axes)

    def tolerance_doc(self) -> dict[str, list[dict[str, float]]]:
        """The tolerance as the procedure file states it (result.json's `method`)."""
        return {k: [{**({"below_dps": b.below_dps} if b.below_dps is not None else {}),
                     "rel": b.rel} for b in bands] for k, bands in self.tolerance.items()}

    def method(self) -> dict[str, Any]:
        """The settings result.json records under `method` (the certificate's Method
        table): `turns` is one number when every axis ran it, else per axis in words."""
        per_axis = {a.name: a.turns for a in self.axes.values()}
        turns: int | str = (next(iter(per_axis.values())) if len(set(per_axis.values())) == 1
                            else ", ".join(f"{k} {v}" for k, v in per_axis.items()))
        return {"turns": turns, "turns_per_axis": per_axis, "sequence": self.sequence,
                "static_record_s": self.static_record_s, "harmonics": self.harmonics,
                "mains_hz": self.mains_hz, "mains_source": self.mains_source,
                "decision_rule": self.decision_rule}


PROCEDURE = Map({**COMMON_PROCEDURE_KEYS, **struct_map(LadderSettings).keys})
#: the procedure file's keys the ladder reads itself
_LADDER_KEYS = frozenset(struct_map(LadderSettings).keys)


#: the grids a mains tone is looked for at when neither file states the lab's
MAINS_CANDIDATES_HZ = (50.0, 60.0)
MAINS_FOUND = "found from the data (50 and 60 Hz tried; the larger significant tone)"


def mains_of(cfg: Config) -> tuple[float | None, str]:
    """The mains frequency and where it comes from: the procedure's `mains_hz`, else the
    stand's top-level `mains_hz` (the lab's grid, CONTRACT §2), else None: the analysis
    finds it from the data (never a silent 50)."""
    if cfg.procedure.get("mains_hz") is not None:
        return float(cfg.procedure["mains_hz"]), "procedure file (mains_hz)"
    if cfg.stand.get("mains_hz") is not None:
        return float(cfg.stand["mains_hz"]), "stand file (mains_hz, the lab's grid)"
    return None, MAINS_FOUND


def validation_notes(cfg: Config) -> list[str]:
    """What `bench validate` says beside 'valid' for a rate ladder."""
    if mains_of(cfg)[0] is None:
        return [f"{cfg.stand_path}: key mains_hz not set (neither in the stand nor in "
                f"{cfg.procedure_path.name}): the mains tone will be found from the data "
                "(50 and 60 Hz tried); set mains_hz: 50 or 60 at the stand file's top "
                "level to state the lab's grid"]
    return []


def tolerance_for(bands: tuple[Band, ...] | None, rate_dps: float) -> float | None:
    """The first band whose `below_dps` exceeds |rate|, else the band without one."""
    if not bands:
        return None
    for band in bands:
        if band.below_dps is not None and abs(rate_dps) < band.below_dps:
            return band.rel
    for band in bands:
        if band.below_dps is None:
            return band.rel
    return None


def halves(turns: int, sequence: str) -> list[tuple[int, int]]:
    """(sign, turns) per half. '+-+' splits the + turns around the - half."""
    if sequence == "+-+" and turns >= 2:
        return [(+1, (turns + 1) // 2), (-1, turns), (+1, turns // 2)]
    return [(+1, turns), (-1, turns)]


def counter_capability_problems(sdoc: YamlDoc, axis: str, counter: Any) -> list[Problem]:
    """What the ladder needs of an axis's counter, from its model's profile, before
    anything starts: time stamps of the zero mark (consecutive turns, docs/method.md
    A1), a reference-source command where the stand states `reference`, an external
    start where its time tie is `fog-sync` (drivers/counter_profiles.py
    `missing_capabilities`)."""
    if not isinstance(counter, Mapping) or counter.get("model") not in COUNTER_PROFILES:
        return []    # an unknown model: the schema names the choices at its line
    profile = COUNTER_PROFILES[counter["model"]]
    tie = counter.get("time_tie")
    missing = profile.missing_capabilities(
        timestamps=True, reference=counter.get("reference"),
        time_tie=tie.get("source") if isinstance(tie, Mapping) else None)
    out: list[Problem] = []
    for key, sentence in missing:
        path = ("axes", axis, "counter", key) + (("source",) if key == "time_tie" else ())
        if key == "model":
            sentence += (f"; models that have time stamps: "
                         f"{', '.join(_timestamping_models())}")
        out.append(sdoc.problem(path, sentence))
    return out


def _timestamping_models() -> list[str]:
    return sorted(m for m, p in COUNTER_PROFILES.items() if p.supports_timestamps)


def ladder_problems(cfg: Config) -> list[Problem]:
    """The ladder's checks that need both files: axes exist, rates within the drive's
    limits and the FOG's range, the last tolerance band open."""
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
        out += counter_capability_problems(sdoc, axis, counter)
        if counter and "level_v" not in counter and not cfg.has_sim:
            # the counter refuses to arm without it; say so before anything moves
            out.append(sdoc.problem(("axes", axis, "counter"), "missing level_v: a real "
                                    "stand needs an absolute trigger level in volts (a "
                                    "once-per-rev pulse is too slow for auto-level)"))
        fog_range = (fog or {}).get("range_dps", DEFAULT_RANGE_DPS)
        # from the files alone: one broken stand key must not hide the other checks
        turns = int(spec.get("turns", cfg.procedure.get("turns", DEFAULT_TURNS)))
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
            stated, source = mains_of(cfg)
            if mains and stated is not None and mains.get("frequency_hz") != stated:
                doc = pdoc if source.startswith("procedure") else sdoc
                out.append(doc.problem(("mains_hz",), f"mains_hz {stated:g} Hz, but the "
                           f"stand's sim truth of axis {axis!r} has its mains tone at "
                           f"{mains.get('frequency_hz'):g} Hz: set mains_hz to the "
                           "lab's grid"))
    for name in ("rate_error", "rate_instability", "intra_turn_instability"):
        bands = cfg.procedure.get("tolerance", {}).get(name)
        if bands and "below_dps" in bands[-1]:
            out.append(pdoc.problem(("tolerance", name, len(bands) - 1),
                                    "the last band must have no below_dps (it covers "
                                    "every rate above the others)"))
    return out
