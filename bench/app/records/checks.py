"""A run directory -> the check values it yields about the bench's own instruments.

ISO/IEC 17025 7.7.1 asks a lab to show its results stay valid between calibrations of its
equipment. Every run already measures the equipment it runs on; this module keeps those
figures, per instrument serial, with their U (k = 2), so the control charts
(`control.py`) can tell a FOG whose scale factor jumped from one that is stable
(docs/method.md C1 says what each value is and where its U comes from):

    counter  zero-mark timing jitter (second differences of the edges of each half);
             the reference read back (1 = external reference, 0 = internal)
    drive    settle time beyond the ramp, and the rate ripple it reports while timed
    others   what the run's procedure kind says of the instruments it measures
             (`bench.kind.ChecksInstruments`: the FOGs' scale and bias, a gyro
             platform's own drift per gyro)

Everything is read from the run directory's own files, so `bench records import` keeps
the same values as the end of the run did.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from pathlib import Path

from bench.analysis.finite import finite_number as _num
from bench.core import rundir_layout as layout
from bench.core.events import Event, StepStarted, TimedHalf
from bench.core.journal_codec import DriveLine, read_drive_log, read_events
from bench.core.registry import procedure_names
from bench.core.yamlfile import YamlValue
from bench.kind import ChecksInstruments, installed_records
from bench.report.figures import InstrumentCheck
from bench.report.result_frame import ResultFrame, as_object
from drivers.json_types import JsonObject, JsonValue

#: the stand instruments' check quantities, their unit and what the chart calls them (one
#: place); a kind adds those of its own instruments (`ChecksInstruments.check_quantities`)
QUANTITIES: dict[str, tuple[str, str]] = {
    "zero_mark_jitter_s": ("s", "zero-mark timing jitter, edge std"),
    "reference_external": ("1", "counter reference read back (1 external, 0 internal)"),
    "settle_time_s": ("s", "drive settle time beyond the ramp"),
    "ripple_rel": ("1", "drive-reported rate ripple while timed, rms / |rate|"),
}
#: quantities that are attributes (a change from the baseline is the signal, not a spread)
ATTRIBUTES = ("reference_external",)


def quantities() -> dict[str, tuple[str, str]]:
    """Every check quantity: the stand instruments', then each installed kind's own."""
    out = dict(QUANTITIES)
    for name in procedure_names():
        kind = installed_records(name)
        if isinstance(kind, ChecksInstruments):
            out.update({q: v for q, v in kind.check_quantities.items() if q not in out})
    return out


#: one check value of one instrument in one run (the type a kind's own checks come in)
CheckRecord = InstrumentCheck


def _serial_of(stated: str | None, reported: str | None, unique: bool, fallback: str) -> str:
    """The serial the instrument reported, if no other instrument of the run reports the
    same: the instrument actually connected (issue 41: a swapped counter must not land on
    the stated one's control chart); else the stand file's `serial:` (a FOG answers no
    identity query); else the instrument's place on the stand (STAND-SERIAL/axis/role)."""
    if reported and unique and not re.fullmatch(r"[A-Za-z]*0*", reported):
        return reported       # (all zeros: a twin's or an unset serial, no identity)
    return stated or fallback


def _idn_serial(text: JsonValue) -> str | None:
    """*IDN? -> its third field (IEEE 488.2: maker, model, serial, firmware)."""
    if not isinstance(text, str) or not text:
        return None
    parts = text.split(";", 1)[0].split(",")
    return parts[2].strip() or None if len(parts) >= 4 else None


def _drive_serial(text: JsonValue) -> str | None:
    """The drive identity (0x1018 sub 4) as the bench prints it: '..., serial N'."""
    m = re.search(r"serial (\S+?)(?:[;,]|$)", text if isinstance(text, str) else "")
    return m.group(1) if m else None


def _fog_serial(text: JsonValue) -> str | None:
    """A FOG's answer to ?IS as its identity carries it ('..., serial N (?IS); ...')."""
    m = re.search(r"serial (\S+) \(\?IS\)", text if isinstance(text, str) else "")
    return m.group(1) if m else None


def _std_u(std: float, dof: int) -> float | None:
    """U (k = 2) of a standard deviation from `dof` degrees of freedom (chi-square, normal
    data: ustd(s) = s / sqrt(2 dof)), docs/method.md C1."""
    return 2.0 * std / math.sqrt(2.0 * dof) if dof > 0 else None


def _jitter(axis: str, events: Sequence[Event], serial: str,
            model: str | None) -> list[CheckRecord]:
    """Zero-mark edge jitter from the second differences of each half's edges: for white
    edge jitter s, d = e[i+1] - 2 e[i] + e[i-1] has variance 6 s^2 (docs/method.md C1)."""
    sq, n = 0.0, 0
    for e in events:
        if not isinstance(e, TimedHalf) or e.axis != axis:
            continue
        edges = e.edges_s
        for i in range(1, len(edges) - 1):
            d = edges[i + 1] - 2.0 * edges[i] + edges[i - 1]
            sq += d * d
            n += 1
    if n == 0:
        return []
    s = math.sqrt(sq / (6.0 * n))
    return [CheckRecord(serial, "counter", model, axis, "zero_mark_jitter_s", None, s,
                        _std_u(s, n), "s")]


def _drive(axis: str, raw: Path, events: Sequence[Event], serial: str,
           model: str | None) -> list[CheckRecord]:
    """Settle time beyond the commanded ramp, and the ripple the drive reports while the
    counter times turns (docs/method.md C1), from the drive's raw journal."""
    files = sorted(raw.glob(f"{layout.SESSION_GLOB}/{layout.drive_log(axis)}"))
    if not files:
        return []
    settle: list[tuple[float, float]] = []      # (settle time, feedback interval)
    windows = []
    starts: dict[tuple[int, str | None], float | None] = {}
    for e in events:
        # the step that timed a half is the last one its unit started on this axis before
        # the half's event (a kind's step names are its own; bench/ names none of them)
        if isinstance(e, StepStarted) and e.axis == axis:
            starts[(e.session, e.unit)] = e.t_s
        if isinstance(e, TimedHalf) and e.axis == axis:
            t0 = starts.get((e.session, e.unit))
            rate, t1 = e.set_rate_dps, e.t_s
            if t0 is not None and t1 is not None and rate:
                windows.append((str(e.session), t0, t1, rate))
    ripple_sq, ripple_n = 0.0, 0
    for f in files:
        session = f.parent.name.removeprefix("s")
        command: DriveLine | None = None
        last_w = 0.0
        for rec in read_drive_log(f):
            t = _num(rec.t_s)
            if t is None:
                continue
            if rec.kind == "command":
                if command is not None:
                    last_w = _num(command.sent_dps) or last_w
                command = rec
            elif rec.kind == "settled" and command is not None:
                accel = _num(command.accel_dps2) or 0.0
                target = _num(rec.target_dps) or 0.0
                ramp = abs(target - last_w) / accel if accel > 0 else 0.0
                hold = _num(rec.hold_s) or 0.0
                samples = int(_num(rec.samples) or 1)
                value = t - hold - (_num(command.t_s) or 0.0) - ramp
                settle.append((max(value, 0.0), hold / max(samples - 1, 1)))
                last_w = target
            elif rec.kind == "feedback":
                v = _num(rec.velocity_dps)
                for s, a, b, rate in windows:
                    if s == session and a <= t <= b and v is not None:
                        ripple_sq += ((v - rate) / rate) ** 2
                        ripple_n += 1
    out = []
    if settle:
        mean = sum(v for v, _ in settle) / len(settle)
        # each settle moment is known to one feedback interval (rectangular), and the
        # mean of n of them to that over sqrt(n): U = 2 * dt / sqrt(3 n)
        dt = max(d for _, d in settle)
        out.append(CheckRecord(serial, "drive", model, axis, "settle_time_s", None, mean,
                               2.0 * dt / math.sqrt(3.0 * len(settle)), "s"))
    if ripple_n:
        rms = math.sqrt(ripple_sq / ripple_n)
        out.append(CheckRecord(serial, "drive", model, axis, "ripple_rel", None, rms,
                               _std_u(rms, ripple_n), "1"))
    return out


def checks_of(run_path: Path, result: ResultFrame | Mapping[str, JsonValue],
              stand: Mapping[str, JsonValue], kind_name: str | None = None
              ) -> list[CheckRecord]:
    """Every check value of one run, per instrument serial, from its result's frame (as
    the analysis gave it, or result.json's)."""
    events = read_events(run_path / layout.EVENTS) \
        if (run_path / layout.EVENTS).is_file() else []
    frame = result if isinstance(result, ResultFrame) else ResultFrame.conform(result)[0]
    kind_of_run = kind_name or frame.procedure or ""
    ident = as_object(stand.get("stand")) or {}
    ident.update({k: v for k, v in frame.stand.items() if v is not None})
    stand_serial = str(ident.get("serial") or "stand")
    ids: Mapping[str, JsonObject] = frame.instruments
    stand_axes = as_object(stand.get("axes")) or {}
    reported: dict[str, list[str | None]] = {"counter": [], "drive": [], "fog": []}
    for a in stand_axes:
        got = entry if isinstance(entry := ids.get(a), Mapping) else {}
        reported["counter"].append(_idn_serial(got.get("counter")))
        reported["drive"].append(_drive_serial(got.get("drive")))
        reported["fog"].append(_fog_serial(got.get("fog")))

    def serial(axis: str, role: str, conf: Mapping[str, YamlValue]) -> str:
        got = entry if isinstance(entry := ids.get(axis), Mapping) else {}
        rep = (_idn_serial(got.get("counter")) if role == "counter" else
               _drive_serial(got.get("drive")) if role == "drive" else
               _fog_serial(got.get("fog")) if role == "fog" else None)
        unique = rep is not None and reported.get(role, []).count(rep) == 1
        stated = conf.get("serial")
        return _serial_of(None if stated in (None, "") else str(stated), rep, unique,
                          f"{stand_serial}/{axis}/{role}")

    # the instruments the run's procedure kind measures (the FOGs' scale and bias, a gyro
    # platform's gyros): listed with their axis, before the stand's instruments there
    kind = installed_records(kind_of_run)
    measured: list[CheckRecord] = kind.instrument_checks(frame, stand, serial) \
        if isinstance(kind, ChecksInstruments) else []
    # the counters that timed turns in this run (an axis the run did not time has no
    # check value of its counter)
    timed = {e.axis for e in events if isinstance(e, TimedHalf)}
    out: list[CheckRecord] = []
    for axis, conf in stand_axes.items():
        if not isinstance(conf, Mapping):
            continue
        out += [c for c in measured if c.axis == axis]
        counter = conf.get("counter")
        if isinstance(counter, Mapping) and axis in timed:
            sn, model = serial(axis, "counter", counter), _opt(counter.get("model"))
            out += _jitter(axis, events, sn, model)
            ref = (as_object(ids.get(axis)) or {}).get("counter_reference")
            if ref:
                out.append(CheckRecord(sn, "counter", model, axis, "reference_external",
                                       None, 1.0 if "external" in str(ref).lower() else 0.0,
                                       None, "1"))
        drive = conf.get("drive")
        if isinstance(drive, Mapping) and events:
            out += _drive(axis, layout.raw_root(run_path), events, serial(axis, "drive", drive),
                          _opt(drive.get("model")))
    placed = {a for a, conf in stand_axes.items() if isinstance(conf, Mapping)}
    return out + [c for c in measured if c.axis not in placed]


def _opt(x: JsonValue) -> str | None:
    return None if x in (None, "") else str(x)
