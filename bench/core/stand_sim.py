"""The stand file's `sim.axes.<axis>:` block, declared once: the twins' truth as the
file writes it, with each key's unit and meaning (msgspec Structs, read by
bench/core/schema.py for `bench validate`, `bench schema` and docs/configuration.md).

A key left out is None here and takes the truth's own default (sims/truth.py's
dataclasses, sims/drive_truth.py): each default is declared once, there.
bench/core/config.py turns the block into the `SimAxis` the twins read.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from msgspec import Meta, Struct

from sims.drive_truth import DriveTruth


def _m(description: str, unit: str = "", **bounds: float) -> Meta:
    """A key's meaning, unit and bounds (ge, gt, le)."""
    kw: dict[str, Any] = {"description": description, **bounds}
    if unit:
        kw["extra"] = {"unit": unit}
    return Meta(**kw)


class HarmonicFile(Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    order: Annotated[int, _m("h: cycles per turn", ge=1)]
    amplitude_rel: Annotated[float, _m("a, relative to the set rate", ge=0)]
    phase_deg: Annotated[float, _m("p, at the zero mark", "deg")] | None = None


class MainsFile(Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    frequency_hz: Annotated[float, _m("the ripple's frequency", "Hz", gt=0)] | None = None
    amplitude_dps: Annotated[float, _m("its amplitude", "deg/s", ge=0)] | None = None
    phase_deg: Annotated[float, _m("its phase at t = 0", "deg")] | None = None


class ScaleStepFile(Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    from_run: Annotated[int, _m("the first run with the step", ge=1)]
    rel: Annotated[float, _m("the step, a fraction of the scale")]


class ScaleRampFile(Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    from_run: Annotated[int, _m("the first run of the ramp", ge=1)]
    rel_per_run: Annotated[float, _m("the change per run, a fraction of the scale")]


class SimFogFile(Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    scale: Annotated[float, _m("scale factor")] | None = None
    bias_dps: Annotated[float, _m("bias w0", "deg/s")] | None = None
    misalignment_deg: Annotated[float, _m("sensitive axis to table axis", "deg")] | None = None
    noise_dps: Annotated[float, _m("white noise std per sample", "deg/s")] | None = None
    bias_drift_dps_per_h: Annotated[float, _m("linear bias drift from the start",
                                              "deg/s/h")] | None = None
    # a FOG that drifts across runs (bench/core/simdrift.py, bench control)
    scale_step: Annotated[ScaleStepFile, _m("scale x (1 + rel) from run from_run "
                                            "on")] | None = None
    scale_ramp: Annotated[ScaleRampFile, _m("scale x (1 + rel_per_run per run) from run "
                                            "from_run on")] | None = None
    units: Annotated[Literal["deg/s", "rad/s", "deg", "rad"], _m(
        "what the twin carries before the bench configures it (default: delta radians, or "
        "the declared fog.units)")] | None = None


class SimCounterFile(Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    timebase_offset_rel: Annotated[float, _m(
        "the counter's true time-base offset e, unknown to the lab: every period the twin "
        "times is scaled by 1 + e (default 0; issue 58)")] | None = None


class TieTruthFile(Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    latency_s: Annotated[float, _m("true latency", "s", ge=0)] | None = None
    jitter_s: Annotated[float, _m("its jitter, std", "s", ge=0)] | None = None


class SerialsFile(Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    counter: Annotated[str, _m("the counter twin's *IDN? serial")] | None = None
    drive: Annotated[int, _m("the drive twin's serial number, 0x1018:4",
                             ge=0, le=2**32 - 1)] | None = None


class SimAxisFile(Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    """One axis's truth, as the stand's `sim.axes.<axis>:` writes it."""

    rate_bias_rel: Annotated[float, _m("mean table rate = set x (1 + this)")] | None = None
    harmonics: Annotated[tuple[HarmonicFile, ...], _m(
        "w_true - w_set = w_set x sum a cos(h phi + p)")] | None = None
    mains: Annotated[MainsFile, _m("a mains-frequency rate ripple")] | None = None
    rate_noise_dps: Annotated[float, _m("white table rate noise while turning, std per FOG "
                                        "sample", "deg/s", ge=0)] | None = None
    turn_jitter_s: Annotated[float, _m("zero-mark edge timing std", "s", ge=0)] | None = None
    fog: Annotated[SimFogFile, _m("the FOG's truth: k = scale cos(misalignment), w0 = "
                                  "bias")] | None = None
    counter_external_reference: Annotated[bool, _m(
        "a valid 10 MHz is wired to the counter's Ext Ref In (default true)")] | None = None
    counter: Annotated[SimCounterFile, _m("the counter twin's own errors")] | None = None
    counter_first_value: Annotated[Literal["from-start", "edge-to-edge"], _m(
        "how the 53230A twin reads its first timestamp value: from the trigger (default) "
        "or edge to edge (the Programmer's Reference's SENSe:TSTamp:RATE "
        "example)")] | None = None
    time_tie: Annotated[TieTruthFile, _m("the FOG sync to counter trigger link: true "
                                         "latency and jitter")] | None = None
    serials: Annotated[SerialsFile, _m(
        "the serial each twin reports: the counter's *IDN? serial field, the drive's "
        "identity object 0x1018:4")] | None = None
    drive: Annotated[DriveTruth, _m(
        "the drive twin's own configuration: its factor group (e.g. rpm, rpm/s), TPDO event "
        "timer, limits and windows (sims/drive_truth.py)")] | None = None
