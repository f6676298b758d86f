"""result.json for a rate-ladder run, from the run directory's raw data alone.

The engine calls `analyze_run` at the end of a run and `bench analyze` calls it on a
finished (or aborted) run directory: both read the same files, so they agree to the
last digit. The FOG samples come from re-decoding the raw capture (the same decoder the
live driver used); the zero-mark edges from re-parsing the counter's raw replies; the
event log says only which samples and which replies belong to which half.
"""

from __future__ import annotations

import dataclasses
import math
import tempfile
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any

import msgspec
import numpy as np

from bench.analysis.allan import allan_deviation
from bench.analysis.coverage import chi2_ppf
from bench.analysis.disk import DiskArray
from bench.analysis.pair import analyze_pair_mains
from bench.analysis.random_part import std_interval_u_rel
from bench.analysis.results import PairAnalysis, RateResult
from bench.analysis.turns import CounterBudget
from bench.analysis.window import HalfRecord
from bench.core import rundir_layout as layout
from bench.core.config import Config, CounterSettings
from bench.core.events import Event
from bench.core.journal import RunDir, fog_capture_starts, units_done
from bench.core.journal_codec import float_field
from bench.report.codec import KindResult
from bench.report.conformity import CAPABILITY_LIMIT, judge, judge_limit
from drivers.counter_profiles import get_profile
from drivers.fog import CaptureCursor, FogCheckpoint
from drivers.scpi import parse_numbers
from procedures.base import RawHashes, result_head
from procedures.rate_ladder import result as result_model
from procedures.rate_ladder.budgets import with_budgets
from procedures.rate_ladder.codec import CounterReply, counter_replies, read_corrections
from procedures.rate_ladder.conditions import TemperatureSpan, memo_key
from procedures.rate_ladder.events import (
    HalfAcquired,
    PairDirection,
    PairLooked,
    StaticRecorded,
)
from procedures.rate_ladder.result import (
    LadderAxis,
    LadderBody,
    LadderCheck,
    PairEntry,
    RateEntry,
)
from procedures.rate_ladder.settings import (
    MAINS_CANDIDATES_HZ,
    MAINS_FOUND,
    LadderSettings,
    tolerance_for,
)


def counter_budget(c: CounterSettings) -> CounterBudget:
    """docs/method.md A1: dT = sqrt(d_counter^2 + d_trigger^2), plus the timebase."""
    profile = get_profile(c.model)
    return CounterBudget(time_tie_u_s=c.time_tie.latency_u_s if c.time_tie else 0.0,
                         timestamp_u_s=profile.single_shot_s,
                         trigger_jitter_s=c.trigger_jitter_s or 0.0,
                         timebase_limit_rel=(c.timebase_limit_rel
                                             if c.timebase_limit_rel is not None
                                             else profile.timebase_limit_rel))


#: the run folder's corrections file (issue 58): instrument corrections the analysis
#: applies, as data; absent, nothing is corrected and every figure is as measured
CORRECTIONS = "corrections.json"


#: the coverage factor a correction's stated U is taken at (a calibration certificate's
#: U, about 95 %: k = 2, CONTRACT section 3), to give its standard uncertainty
CORRECTION_U_COVERAGE = 2.0


@dataclass(frozen=True)
class TimebaseCorrection:
    """A counter's time-base offset e the run folder's corrections file states, with its
    standard uncertainty (the file's U / 2; 0 when it states no U)."""

    value_rel: float
    ustd_rel: float


def counter_timebase_offsets(run_path: Path) -> dict[str, TimebaseCorrection]:
    """The counters' time-base corrections by axis that the run folder's corrections file
    states (`where` axes.<axis>.counter, `quantity` timebase_offset_rel, `value` e, `U` its
    expanded uncertainty); {} without one. A malformed entry raises, naming the file and
    the key: a correction is never half applied."""
    path = Path(run_path) / CORRECTIONS
    if not path.is_file():
        return {}
    out: dict[str, TimebaseCorrection] = {}
    for i, c in enumerate(read_corrections(path)[0]):
        where = c.where.split(".")
        if c.quantity == "timebase_offset_rel" and len(where) == 3 \
                and where[0] == "axes" and where[2] == "counter":
            if not math.isfinite(c.value):
                raise ValueError(f"{path}: corrections[{i}].value: a finite number, got "
                                 f"{c.value!r}")
            out[where[1]] = TimebaseCorrection(
                c.value, 0.0 if c.U is None else c.U / CORRECTION_U_COVERAGE)
    return out


def corrected_edges(edges_s: np.ndarray, offset_rel: float, t0_s: float) -> np.ndarray:
    """Edges read by a counter whose time base is off by e, corrected: every interval it
    timed from its start t0 divided by 1 + e, T = T_measured / (1 + e) (docs/method.md
    A1, "A counter's time-base correction"): the edges where the counter would have put
    them with a true time base, the first one too (it sat e times the wait from the
    counter's start late)."""
    if edges_s.size == 0:
        return edges_s
    return t0_s + (edges_s - t0_s) / (1.0 + offset_rel)


def fog_bracket(edges_s: np.ndarray, rate_hz: float) -> tuple[int, int]:
    """The FOG samples that bracket the timed turns, the rule the run chooses them by (the
    half's acquisition, procedures/rate_ladder/kind.py, calls this): from the sample at or before
    the first edge to the second after the last (the analysis integrates from the first
    edge to the last, interpolating between samples)."""
    return (math.floor(float(edges_s[0]) * rate_hz),
            math.floor(float(edges_s[-1]) * rate_hz) + 2)


def edges_from_replies(records: Iterable[CounterReply], model: str, n_edges: int,
                       t_start_s: float = 0.0) -> np.ndarray:
    """The zero-mark edges in the counter's raw replies of one acquisition, placed on the
    FOG's axis by the start event the time tie gave during the run (journaled)."""
    fmt = get_profile(model).timestamp_format
    n_values = fmt.n_values(n_edges)
    found = None
    for r in records:
        if r.dir != "rx" or r.data is None:
            continue
        try:
            values = parse_numbers(r.data)
        except ValueError:
            continue
        if values.size == n_values:
            found = fmt.decode(values)
    if found is None:
        raise ValueError(f"no counter reply with {n_edges} timestamps in the raw log")
    return t_start_s + found


def counter_start_s(h: HalfAcquired) -> float:
    """The counter's start on the half's session FOG axis, from the journaled time tie
    (the sync pulse number, its period and the link's latency) when there is one; it must
    agree with the start the run used, else the journal is inconsistent and says so."""
    tie = h.time_tie or {}
    if "sync_pulse" not in tie:
        return float(h.counter_t0_s)
    t0 = (int(float_field(tie, "sync_pulse")) * float(float_field(tie, "sync_period_s"))
          + float(float_field(tie, "latency_s")))
    if abs(t0 - float(h.counter_t0_s)) > 1e-6:
        raise ValueError(f"{h.unit} half {h.half} (session {h.session}): the journaled time "
                         f"tie places the counter's start at {t0:.9f} s, the run used "
                         f"{h.counter_t0_s:.9f} s")
    return t0


def window_on_disk(cursor: CaptureCursor, i_from: int, i_to: int, stem: Path,
                   span: TemperatureSpan | None = None) -> tuple[DiskArray, DiskArray]:
    """FOG samples i_from .. i_to - 1 that are valid, as (times, rates) files at `stem`:
    what a HalfRecord holds, written chunk by chunk, read back the same way; `span` takes
    the frames' temperatures on the way (the conditions, without a second decode)."""
    t_path, f_path = stem.with_suffix(".t.f64"), stem.with_suffix(".f.f64")
    with open(t_path, "wb") as ft, open(f_path, "wb") as ff:
        for s in cursor.window(i_from, i_to):
            ft.write(s.t_s[s.valid].tobytes())
            ff.write(s.rate_dps[s.valid].tobytes())
            if span is not None:
                span.add(s)
    return DiskArray(t_path), DiskArray(f_path)


class RawData:
    """One run directory's raw files, read as the analysis needs them, in bounded memory.

    A FOG window (a half's samples) is decoded from the raw capture in chunks by a cursor
    that moves forward through the file (drivers.fog.CaptureCursor), and its valid
    samples are written to a scratch file the analysis reads chunk by chunk
    (bench.analysis.disk.DiskArray): the memory used does not grow with the record.
    `live=True` (during a run) takes the zero-mark edges from the acquire event instead
    of re-parsing the counter's growing log: the same numbers (JSON keeps a float exact).
    """

    def __init__(self, run: RunDir, cfg: Config, *, live: bool = False,
                 chunk_bytes: int = 1 << 20) -> None:
        self.run = run
        self.cfg = cfg
        self.live = live
        self.chunk_bytes = chunk_bytes
        self._cursors: dict[tuple[int, str], CaptureCursor] = {}
        self._scratch = tempfile.TemporaryDirectory(prefix="ratebench-windows-")
        self._windows: list[DiskArray] = []
        self._read: dict[tuple[int, str, int, int], tuple[DiskArray, DiskArray]] = {}
        self._statics: dict[tuple[int, str, int, int], np.ndarray] = {}
        self._first_index: dict[tuple[int, str], int] | None = None
        #: each window's FOG temperatures, as decoded (conditions.memo_key: span)
        self.temperatures: dict[str, TemperatureSpan] = {}
        #: the counters' time-base corrections the run folder states (issue 58), by axis
        self.timebase_offsets = counter_timebase_offsets(run.path)

    def close(self) -> None:
        self.drop_windows()
        for c in self._cursors.values():
            c.close()
        self._cursors.clear()
        self._scratch.cleanup()

    def __enter__(self) -> RawData:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def drop_windows(self) -> None:
        """Delete the scratch files of the windows read so far (a pair is done)."""
        for w in self._windows:
            w.close()
            w.path.unlink(missing_ok=True)
        self._windows.clear()
        self._read.clear()

    @lru_cache(maxsize=8)  # noqa: B019
    def counter_log(self, session: int, axis: str) -> list[CounterReply]:
        return counter_replies(layout.raw_file(self.run.path, session,
                                               layout.counter_log(axis)))

    def _cursor(self, session: int, axis: str, i_from: int,
                 mark: FogCheckpoint | None = None) -> CaptureCursor:
        """A cursor at or before sample i_from: the current one, or one started afresh at
        the event's capture checkpoint `mark` (or the file's start) when that is nearer."""
        key = (session, axis)
        c = self._cursors.get(key)
        start = mark if mark is not None and mark["last_index"] < i_from else None
        ahead = start is not None and (c is None or c.position <= start["last_index"])
        if c is None or c.position > i_from or ahead:
            if c is not None:
                c.close()
            f = self.cfg.fog(axis)
            if self._first_index is None:
                self._first_index = fog_capture_starts(self.run.events())
            c = CaptureCursor(layout.raw_file(self.run.path, session, layout.fog_capture(axis)),
                              fmt=f.format, axis=f.axis, rate_hz=f.rate_hz, units=f.units,
                              chunk_bytes=self.chunk_bytes, start=start,
                              first_index=self._first_index.get(key))
            self._cursors[key] = c
        return c

    def fog_window(self, session: int, axis: str, i_from: int, i_to: int,
                   mark: FogCheckpoint | None = None) -> tuple[DiskArray, DiskArray]:
        """The valid samples i_from .. i_to - 1 (times, rates), on disk; a window read
        before (read_half_ahead) is not read again."""
        key = (session, axis, i_from, i_to)
        if key in self._read:
            return self._read[key]
        cursor = self._cursor(session, axis, i_from, mark)
        stem = Path(self._scratch.name) / f"s{session}-{axis}-{i_from}-{i_to}"
        span = TemperatureSpan()
        t, f = window_on_disk(cursor, i_from, i_to, stem, span)
        self.temperatures[memo_key(session, axis, i_from, i_to)] = span
        self._windows += [t, f]
        self._read[key] = (t, f)
        return t, f

    def edges(self, h: HalfAcquired) -> np.ndarray:
        corr = self.timebase_offsets.get(h.axis)
        if self.live:
            edges = np.asarray(h.edges_s, dtype=float)
        else:
            log = self.counter_log(h.session, h.axis)
            i0, i1 = h.counter_records
            model = _counter(self.cfg, h.axis).model
            edges = edges_from_replies(log[i0:i1], model, h.turns + 1, counter_start_s(h))
        if corr is None:
            return edges
        return corrected_edges(edges, corr.value_rel, counter_start_s(h))

    def half(self, h: HalfAcquired) -> HalfRecord:
        edges = self.edges(h)
        i_from, i_to = h.fog_from, h.fog_to
        if h.axis in self.timebase_offsets and edges.size:
            # docs/method.md A1, a counter's time-base correction: the FOG samples the
            # corrected edges bracket, as the run would have chosen them with a true time
            # base (the capture holds every sample from the half's checkpoint on)
            i_from, i_to = fog_bracket(edges, h.rate_hz)
        t, w = self.fog_window(h.session, h.axis, i_from, i_to, h.fog_capture)
        return HalfRecord(h.sign, edges, t, w, session=h.session)

    def static(self, e: StaticRecorded) -> np.ndarray:
        """The FOG at rest, in memory (minutes of samples, for the floor and Allan)."""
        key = (e.session, e.axis, e.fog_from, e.fog_to)
        if key not in self._statics:
            cursor = self._cursor(e.session, e.axis, e.fog_from, e.fog_capture)
            parts = [s.rate_dps[s.valid] for s in cursor.window(e.fog_from, e.fog_to)]
            self._statics[key] = np.concatenate(parts) if parts else np.empty(0)
        return self._statics[key]


def _settings(cfg: Config) -> dict[str, Any]:
    return LadderSettings.from_config(cfg).method()


def unit_halves(events: Sequence[Event], unit: str, session: int
                ) -> list[HalfAcquired]:
    """A unit's acquisitions as of `session`: for each half, the last one acquired up to it.

    A half is kept once acquired (its acquire event is written when it is complete), so a
    resumed pair may take its halves from several sessions (docs/resume.md).
    """
    by_half: dict[int, HalfAcquired] = {}
    for h in HalfAcquired.all_in(events):
        if h.unit == unit and h.session <= session:
            by_half[h.half] = h
    return [by_half[h] for h in sorted(by_half)]


def unit_acquisitions(events: Sequence[Event]) -> list[HalfAcquired]:
    """Acquisitions of the units not yet done (what a --resume may keep)."""
    done = units_done(events)
    return [h for h in HalfAcquired.all_in(events) if h.unit not in done]


def static_record(events: Sequence[Event], axis: str) -> StaticRecorded | None:
    """The axis's FOG-at-rest record that completed its unit (the last such)."""
    done_in = units_done(events)
    return next((s for s in reversed(StaticRecorded.all_in(events)) if s.axis == axis
                 and done_in.get(s.unit) == s.session), None)


def analyze_unit(raw: RawData, cfg: Config, axis: str, rate_dps: float,
                 acquisitions: list[HalfAcquired], static: StaticRecorded | None) -> PairAnalysis:
    """docs/method.md A1-A5 for one pair. Mains: the stated frequency (procedure, else the
    stand's grid), or, when neither states it, each candidate grid is fitted and the one
    whose tone is the more significant is kept (`systematic.mains.source` says which)."""
    s = _settings(cfg)
    fog_hz = cfg.fog(axis).rate_hz
    static_dps = raw.static(static) if static else None  # before the halves: in file order
    halves = [raw.half(h) for h in sorted(acquisitions, key=lambda h: h.half)]
    stated = s["mains_hz"]
    try:
        return analyze_pair_mains(
            halves, rate_dps, fog_rate_hz=fog_hz,
            candidates_hz=[stated] if stated is not None else list(MAINS_CANDIDATES_HZ),
            source=s["mains_source"] if stated is not None else MAINS_FOUND,
            counter_budget=corrected_budget(counter_budget(_counter(cfg, axis)),
                                            raw.timebase_offsets.get(axis)),
            harmonics=int(s["harmonics"]), static_fog_dps=static_dps)
    finally:
        raw.drop_windows()


def corrected_budget(b: CounterBudget, corr: TimebaseCorrection | None) -> CounterBudget:
    """The counter budget with an applied time-base correction's e and u(e), which the
    rate error's U and k's take as a Type B term of their own (docs/method.md A1, a
    counter's time-base correction); none applied, the budget as it was."""
    if corr is None:
        return b
    return dataclasses.replace(b, timebase_correction_rel=corr.value_rel,
                               timebase_correction_u_rel=corr.ustd_rel)


def _instability_u(value: float | None, turns: int) -> float:
    """U (k = 2) of eq. 2's sigma from N turns (infinite from one turn)."""
    u = std_interval_u_rel(value, turns)
    return math.inf if u is None else u


#: one-sided coverage of the upper limit of sigma (the k = 2 level of a normal variable)
SIGMA_UPPER_P = 0.975


def instability_upper(value: float, turns: int) -> float:
    """One-sided upper limit of eq. 2's sigma from N turns at SIGMA_UPPER_P, for normal
    per-turn rates: sigma * sqrt((N - 1) / chi2_{1-p}(N - 1)). From 4 turns this is 3.7
    sigma: the normal approximation 2 s / sqrt(2 (N - 1)) understates it badly."""
    if turns < 2:
        return math.inf
    return value * math.sqrt((turns - 1) / chi2_ppf(1.0 - SIGMA_UPPER_P, turns - 1))


def instability_lower(value: float, turns: int) -> float:
    """The chi-square lower limit of eq. 2's sigma at 1 - SIGMA_UPPER_P (0 below 2 turns)."""
    if turns < 2:
        return 0.0
    return value * math.sqrt((turns - 1) / chi2_ppf(SIGMA_UPPER_P, turns - 1))


def with_sigma_terms(entry: RateEntry) -> RateEntry:
    """A rate's entry with eq. 2's U, its chi-square limits, whether it is resolved above
    the timing floor (what the certificate and the conformity check read) and its standard
    uncertainty, docs/method.md A1-A2."""
    s, n = entry.rate_instability_rel, entry.turns or 0
    floor = _required(entry.rate_instability_floor_rel, "rate_instability_floor_rel")
    # one turn: no sigma (None), an infinite U and upper limit, a lower limit of 0
    lower = instability_lower(_required(s, "rate_instability_rel"), n) if n >= 2 else 0.0
    upper = instability_upper(_required(s, "rate_instability_rel"), n) if n >= 2 \
        else math.inf
    # its standard uncertainty s / sqrt(2 (N - 1)) (docs/method.md A2, C1): what the DCC
    # states beside the chi-square interval
    ustd = s / math.sqrt(2.0 * (n - 1)) if s is not None and n >= 2 else None
    u = _instability_u(s, n)
    return msgspec.structs.replace(
        entry, rate_instability_u_rel=u, rate_instability_U_rel=u,
        rate_instability_ustd_rel=ustd, rate_instability_upper_rel=upper,
        rate_instability_lower_rel=lower,
        rate_instability_resolved=sigma_resolved(lower, floor))


def _required(x: float | None, key: str) -> float:
    """A figure the conformity check needs, from a rate's entry (None or not finite: the
    analysis gave no finite value, which it does only for a degenerate record)."""
    if x is None or not math.isfinite(x):
        raise ValueError(f"axes.<axis>.rates[].{key}: no finite value to judge")
    return x


def sigma_resolved(lower: float, floor: float) -> bool:
    """docs/method.md A1/A2: sigma shows the table's own turn-to-turn scatter only when its
    chi-square lower limit (2.5 %) stands above the timing floor."""
    return lower > floor


def _counter(cfg: Config, axis: str) -> CounterSettings:
    """The axis's counter (validated: the ladder needs one on each of its axes)."""
    c = cfg.stand_settings.axes[axis].counter
    if c is None:
        raise ValueError(f"axis {axis} has no counter")
    return c


def _checks(cfg: Config, axis: str, entry: RateEntry, rule: str) -> list[LadderCheck]:
    """The conformity checks of one rate's entry against the tolerances (docs/method.md
    A6), as the result's `checks[]` hold them."""
    tol = LadderSettings.from_config(cfg).tolerance
    out: list[LadderCheck] = []
    rate = entry.set_rate_dps
    for quantity, value, u in (
        ("rate_error", entry.rate_error_rel, entry.rate_error_u_rel),
        ("rate_instability", entry.rate_instability_rel, entry.rate_instability_u_rel),
        ("intra_turn_instability", entry.intra_turn_instability_rel,
         entry.intra_turn_instability_u_rel),
    ):
        t = tolerance_for(tol.get(quantity), rate)
        if t is None:
            continue
        if quantity == "rate_instability":
            out.append(sigma_check(axis, rate, entry, t, rule))
            continue
        if quantity == "intra_turn_instability" and entry.intra.raw_resolved is False:
            out.append(raw_limit_check(axis, rate, entry, t, rule))
            continue
        out.append(LadderCheck.of(judge(axis, rate, quantity, _required(value, f"{quantity}_rel"),
                                        _required(u, f"{quantity}_u_rel"), t, rule)))
    return out


def raw_limit_check(axis: str, rate: float, entry: RateEntry, tolerance: float,
                    rule: str) -> LadderCheck:
    """Conformity of the raw intra-turn instability when it is not resolved above the FOG
    floor (docs/method.md D2: stated '< L', L = raw + U never below the floor): judged by
    the one rule for limits, as sigma is (bench.report.conformity.judge_limit)."""
    value = _required(entry.intra_turn_instability_rel, "intra_turn_instability_rel")
    u = _required(entry.intra_turn_instability_u_rel, "intra_turn_instability_u_rel")
    upper = _required(entry.intra.raw_upper_rel, "intra_turn.raw_upper_rel")
    floor = _required(entry.intra.floor_rel, "intra_turn.floor_rel")
    c = judge_limit(axis, rate, "intra_turn_instability", value, u, upper, tolerance, rule,
                    "97.5 % normal (value + U)")
    return msgspec.structs.replace(
        LadderCheck.of(c), floor_rel=floor, floor_name="FOG floor",
        reason=c.reason + (f" (the raw figure {value:.3g} is not resolved above the FOG "
                           f"floor {floor:.3g}: value - U is at or below it)"))


def sigma_check(axis: str, rate: float, entry: RateEntry, tolerance: float,
                rule: str) -> LadderCheck:
    """Conformity of eq. 2's sigma. Resolved above the counter chain's timing floor: judged
    with the one-sided chi-square upper limit as the guard (false-accept risk at most
    1 - SIGMA_UPPER_P for normal per-turn rates). Not resolved: stated as "< L" (L the same
    chi-square limit, which bounds the table's sigma whatever the floor's share) and judged
    by the one rule for limits (bench.report.conformity.judge_limit): pass when L is within the
    tolerance, not assessed only when it is not."""
    value = _required(entry.rate_instability_rel, "rate_instability_rel")
    u = _required(entry.rate_instability_u_rel, "rate_instability_u_rel")
    floor = _required(entry.rate_instability_floor_rel, "rate_instability_floor_rel")
    upper = _required(entry.rate_instability_upper_rel, "rate_instability_upper_rel")
    level = f"{SIGMA_UPPER_P * 100:g} % chi-square"
    if not entry.rate_instability_resolved:
        c = judge_limit(axis, rate, "rate_instability", value, u, upper, tolerance, rule,
                        level)
        return msgspec.structs.replace(
            LadderCheck.of(c), floor_rel=floor, floor_name="timing floor",
            reason=c.reason + (f" (sigma {value:.2g} is not resolved above the timing floor "
                               f"{floor:.2g}: its {100 - SIGMA_UPPER_P * 100:g} % chi-square "
                               "lower limit is at or below it)"))
    c = judge(axis, rate, "rate_instability", value, upper - value, tolerance, rule)
    reason = c.reason
    if rule == "guard-band" and value <= tolerance:
        reason = (f"one-sided upper limit {upper:.3g} ({level}) "
                  f"{'<=' if upper <= tolerance else '>'} tolerance {tolerance:.3g}")
    return msgspec.structs.replace(
        LadderCheck.of(c), u_rel=u, U_rel=u, upper_rel=upper,
        lower_rel=entry.rate_instability_lower_rel, floor_rel=floor,
        capability_ratio=u / tolerance, capability_ok=u / tolerance <= CAPABILITY_LIMIT,
        reason=reason)


def analyze_run(run: RunDir, cfg: Config) -> KindResult[LadderBody]:
    hashes = RawHashes(run)  # in threads, while the pairs are decoded and analysed
    with RawData(run, cfg) as raw:
        result = _analyze_run(run, cfg, raw, hashes)
        run.memo.update(raw.temperatures)   # for the conditions: decoded once
        if raw.timebase_offsets:    # issue 58: the corrections applied, stated
            result = KindResult(result.head, msgspec.structs.replace(
                result.body, corrections=read_corrections(run.path / CORRECTIONS)[1]))
        return result


def _analyze_run(run: RunDir, cfg: Config, raw: RawData, hashes: RawHashes
                 ) -> KindResult[LadderBody]:
    events = run.events()
    rule = _settings(cfg)["decision_rule"]
    done_in = units_done(events)
    axes: dict[str, LadderAxis] = {}
    checks: list[LadderCheck] = []
    complete = True
    for axis, spec in LadderSettings.from_config(cfg).axes.items():
        static = static_record(events, axis)
        rates: list[RateEntry] = []
        pairs: list[PairEntry] = []
        for rate in spec.rates_dps:
            unit = f"{axis}/{rate:g}dps"
            if unit not in done_in:
                complete = False
                continue
            acqs = unit_halves(events, unit, done_in[unit])
            # the worker's first look at this pair in this process, when it had the same
            # halves and static record: the same analysis of the same bytes (a resumed or
            # re-analysed run decodes the raw files again)
            looked = run.memo.pop(first_look_key(unit, acqs, static), None)
            pa = looked if isinstance(looked, PairAnalysis) \
                else analyze_unit(raw, cfg, axis, rate, acqs, static)
            for r in pa.rates:
                entry, c = judged(cfg, axis, r, rule)
                # frames the FOG's decoder lost or found broken in this direction's halves
                # (their samples are left out of the window; the integrals run on time)
                lost = sum(h.fog_lost for h in acqs
                           if h.sign == (1 if r.set_rate_dps > 0 else -1))
                rates.append(msgspec.structs.replace(
                    entry, session=done_in[unit], fog_lost_frames=lost, checks=tuple(c),
                    verdict="fail" if any(x.verdict == "fail" for x in c) else "pass"))
                checks += c
            pairs.append(result_model.pair_entry(pa.pair))
        floor = None
        if static is not None:
            w = raw.static(static)
            hz = cfg.fog(axis).rate_hz
            floor = result_model.noise_floor(
                int(w.size), w.size / hz, float(np.std(w, ddof=1)),
                float(np.mean(w)),   # bias at rest (bench control)
                allan_deviation(w, hz))
        axes[axis] = with_budgets(LadderAxis(rates=tuple(rates), pairs=tuple(pairs),
                                             noise_floor=floor))
    head = result_head(run, cfg, events, complete=complete, checks=checks, rule=rule,
                       raw_hashes=hashes,
                       method={**_settings(cfg),
                               "tolerance": LadderSettings.from_config(cfg).tolerance_doc()})
    # the body after the frame: its uncertainty twins are fields of the model
    return KindResult(head, LadderBody(axes=axes))


def judged(cfg: Config, axis: str, r: RateResult, rule: str
           ) -> tuple[RateEntry, list[LadderCheck]]:
    """One direction's entry with eq. 2's sigma terms, and its conformity checks
    (docs/method.md A1-A2, A6)."""
    entry = with_sigma_terms(result_model.rate_entry(r))
    return entry, _checks(cfg, axis, entry, rule)


_WORKER_READERS: dict[str, RawData] = {}  # in the analysis worker: one per run directory


def first_look_key(unit: str, acquisitions: list[HalfAcquired],
                   static: StaticRecorded | None) -> str:
    """What a pair's analysis rests on (its halves, the static record): a first look made
    on the same is the final analysis (RunDir.memo)."""
    halves = sorted(acquisitions, key=lambda h: h.half)
    return f"rate-ladder first look {unit} {halves!r} {static!r}"


@dataclass(frozen=True)
class FirstLook:
    """The worker's answer: the summary journaled as the `pair` event, and the whole
    analysis, which the final result.json reuses instead of decoding the halves again."""

    summary: PairLooked
    analysis: PairAnalysis
    key: str
    temperatures: dict[str, TemperatureSpan]


def _worker_raw(run_path: str, cfg: Config) -> RawData:
    raw = _WORKER_READERS.get(run_path)
    if raw is None:
        raw = _WORKER_READERS[run_path] = RawData(RunDir(run_path), cfg, live=True)
    return raw


def read_half_ahead(run_path: str, cfg: Config, half: HalfAcquired,
                    static: StaticRecorded | None) -> None:
    """In the analysis worker, as soon as a half is acquired: its FOG window decoded from
    the raw capture now, while the bench acquires the next half, so the pair's first
    look (pair_summary) finds it read. Only the reading goes ahead: the analysis needs
    the whole pair (its provisional calibration). The axis's static record is read
    first, as analyze_unit reads them, so the capture is read forward once. On the paper
    ladder this took the wait for the last 0.1 deg/s pair's first look, at the run's
    end, from ~6 s to ~1 s."""
    raw = _worker_raw(run_path, cfg)
    if static is not None:
        raw.static(static)
    raw.fog_window(half.session, half.axis, half.fog_from, half.fog_to, half.fog_capture)


def pair_summary(run_path: str, cfg: Config, axis: str, rate_dps: float,
                 acquisitions: list[HalfAcquired], static: StaticRecorded | None
                 ) -> FirstLook:
    """A first look at the pair just measured (the same analysis the final result.json
    makes), from the raw capture as it is being written; runs in the analysis worker
    (bench.core.engine.AnalysisWorker), whose reader moves on from pair to pair."""
    raw = _worker_raw(run_path, cfg)
    pa = analyze_unit(raw, cfg, axis, rate_dps, acquisitions, static)
    rule = _settings(cfg)["decision_rule"]
    figures: dict[int, tuple[float, float]] = {}    # by the direction's sign
    directions = []
    for r in pa.rates:
        figures[1 if r.set_rate_dps > 0 else -1] = (r.rate_error_rel, r.rate_error_u_rel)
        # the station page's row: the same figures and checks result.json will hold
        entry, checks = judged(cfg, axis, r, rule)
        directions.append(PairDirection(
            set_rate_dps=r.set_rate_dps, turns=entry.turns,
            rate_error_rel=r.rate_error_rel, rate_error_U_rel=r.rate_error_u_rel,
            rate_instability_rel=entry.rate_instability_rel,
            verdict=("fail" if any(c.verdict == "fail" for c in checks)
                     else "pass" if checks else "not-assessed")))
    unit = f"{axis}/{rate_dps:g}dps"
    plus, minus = figures.get(1, (None, None)), figures.get(-1, (None, None))
    out = PairLooked(axis=axis, unit=unit, k=pa.pair.k, k_U=pa.pair.k_u,
                     w0_dps=pa.pair.w0_dps, w0_U_dps=pa.pair.w0_u_dps,
                     rate_error_plus_rel=plus[0], rate_error_plus_U_rel=plus[1],
                     rate_error_minus_rel=minus[0], rate_error_minus_U_rel=minus[1],
                     directions=directions)
    spans, raw.temperatures = raw.temperatures, {}
    return FirstLook(out, pa, first_look_key(unit, acquisitions, static), spans)
