"""Control charts of the bench's own instruments (ISO/IEC 17025 7.7.1; docs/method.md C2).

Each instrument's check values (checks.py) form one series per quantity and rate, in run
order. Per series (NIST/SEMATECH e-Handbook of Statistical Methods, 6.3.2):

- the baseline is the series' first BASELINE_RUNS points, stated on every chart: its mean
  is the centre line, sigma the larger of the moving-range estimate MR/1.128 (6.3.2.2)
  and the points' own median standard uncertainty U/2 (a point within its own U of the
  centre is never a signal, however alike the baseline runs happened to be);
- every later point is judged by the Western Electric rules (6.3.2: one point beyond
  3 sigma; 2 of 3 beyond 2 sigma on one side; 4 of 5 beyond 1 sigma on one side; 8 in a
  row on one side) and by an EWMA chart (6.3.2.4, lambda = 0.2, limits at 3 sigma of the
  EWMA);
- an attribute (the counter's reference read back) signals whenever it differs from
  its baseline value.

An instrument is out of control while one of its signals is not covered by a recorded
review (a review covers the signals of every run up to the last one it saw), not enough
history while no series has a full baseline, and in control otherwise.
"""

from __future__ import annotations

import datetime as dt
import math
import statistics
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

from bench.app.records.checks import ATTRIBUTES, quantities
from bench.app.records.store import CheckPoint, Records, ReviewInfo

BASELINE_RUNS = 8          # points that set a series' limits
D2 = 1.128                 # E[moving range of 2] / sigma, NIST 6.3.2.2
EWMA_LAMBDA = 0.2          # NIST 6.3.2.4
EWMA_L = 3.0
IN_CONTROL, OUT_OF_CONTROL, NOT_ENOUGH = "in control", "out of control", "not enough history"
RULES = {
    "WE1": "Western Electric rule 1: one point beyond 3 sigma",
    "WE2": "Western Electric rule 2: 2 of 3 points beyond 2 sigma on one side",
    "WE3": "Western Electric rule 3: 4 of 5 points beyond 1 sigma on one side",
    "WE4": "Western Electric rule 4: 8 points in a row on one side",
    "EWMA": f"EWMA beyond its {EWMA_L:g} sigma limit (lambda {EWMA_LAMBDA:g})",
    "ATTR": "attribute differs from its baseline value",
}


@dataclass(frozen=True)
class Signal:
    """One rule broken at one point of one series."""

    rule: str                  # a key of RULES
    series: str
    run_uid: str
    run_dir: str
    date_utc: dt.datetime | None
    value: float
    text: str

    @property
    def line(self) -> str:
        when = self.date_utc.strftime("%Y-%m-%d %H:%M UTC") if self.date_utc else "?"
        return f"{self.rule} ({RULES[self.rule]}): {self.series}, run {self.run_dir} " \
               f"({when}): {self.text}"


@dataclass(frozen=True)
class Series:
    """One control chart: one quantity (at one rate) of one instrument."""

    quantity: str
    set_rate_dps: float | None
    points: tuple[CheckPoint, ...]
    centre: float | None = None
    sigma: float | None = None
    sigma_source: str = ""
    ewma: tuple[float | None, ...] = ()
    ewma_limit: tuple[float | None, ...] = ()
    signals: tuple[Signal, ...] = ()

    @property
    def name(self) -> str:
        rate = f" at {self.set_rate_dps:g} deg/s" if self.set_rate_dps is not None else ""
        return f"{self.quantity}{rate}"

    @property
    def label(self) -> str:
        unit, text = quantities().get(self.quantity, ("", self.quantity))
        rate = f" at ±{self.set_rate_dps:g} deg/s" if self.set_rate_dps is not None else ""
        return f"{text}{rate}, {unit}"

    @property
    def has_baseline(self) -> bool:
        return len(self.points) >= BASELINE_RUNS

    @property
    def baseline_text(self) -> str:
        if not self.has_baseline:
            return f"no baseline yet ({len(self.points)} of {BASELINE_RUNS} runs)"
        b = self.points[:BASELINE_RUNS]
        d0, d1 = b[0].date_utc, b[-1].date_utc
        span = (f", {d0:%Y-%m-%d} to {d1:%Y-%m-%d}" if d0 and d1 else "")
        return f"baseline: the first {BASELINE_RUNS} runs ({b[0].run_dir} to {b[-1].run_dir}" \
               f"{span})"


def _chart(quantity: str, rate: float | None, pts: Sequence[CheckPoint]) -> Series:
    """Limits from the baseline, then the rules at every later point."""
    pts = tuple(pts)
    if len(pts) < BASELINE_RUNS:
        return Series(quantity, rate, pts)
    name = Series(quantity, rate, ()).name
    x = [p.check.value for p in pts]
    base = x[:BASELINE_RUNS]
    centre = statistics.fmean(base)
    signals: list[Signal] = []
    if quantity in ATTRIBUTES:
        ref = statistics.mode(base)
        for p in pts[BASELINE_RUNS:]:
            if p.check.value != ref:
                signals.append(_signal("ATTR", name, p, f"{p.check.value:g}, baseline "
                                                        f"{ref:g}"))
        return Series(quantity, rate, pts, ref, 0.0, "attribute", signals=tuple(signals))
    mr = [abs(b - a) for a, b in zip(base, base[1:], strict=False)]
    sigma_mr = statistics.fmean(mr) / D2
    us = [p.check.u / 2.0 for p in pts[:BASELINE_RUNS] if p.check.u]
    sigma_u = statistics.median(us) if us else 0.0
    sigma, source = ((sigma_mr, "moving range MR/1.128") if sigma_mr >= sigma_u
                     else (sigma_u, "median U/2 of the baseline points"))
    if sigma <= 0:
        sigma, source = abs(centre) * 1e-12 or 1e-300, "baseline without spread"
    z = [(v - centre) / sigma for v in x]
    ewma: list[float | None] = [None] * BASELINE_RUNS
    lim: list[float | None] = [None] * BASELINE_RUNS
    e = centre
    for j, i in enumerate(range(BASELINE_RUNS, len(x)), start=1):
        p = pts[i]
        e = EWMA_LAMBDA * x[i] + (1 - EWMA_LAMBDA) * e
        half = EWMA_L * sigma * math.sqrt(EWMA_LAMBDA / (2 - EWMA_LAMBDA)
                                          * (1 - (1 - EWMA_LAMBDA) ** (2 * j)))
        ewma.append(e)
        lim.append(half)

        side = 1.0 if z[i] >= 0 else -1.0
        if abs(z[i]) > 3:
            signals.append(_signal("WE1", name, p, f"{x[i]:.9g} beyond the 3 sigma limits "
                                   f"{centre - 3 * sigma:.9g} .. {centre + 3 * sigma:.9g}"))
        elif _beyond(z, i, 2, 2, 3, side):
            signals.append(_signal("WE2", name, p, f"{x[i]:.9g}, 2 of the last 3 beyond "
                                   f"{centre + side * 2 * sigma:.9g}"))
        elif _beyond(z, i, 1, 4, 5, side):
            signals.append(_signal("WE3", name, p, f"{x[i]:.9g}, 4 of the last 5 beyond "
                                   f"{centre + side * sigma:.9g}"))
        elif i >= 7 and all(v * side > 0 for v in z[i - 7:i + 1]):
            signals.append(_signal("WE4", name, p, f"{x[i]:.9g}, the last 8 on the "
                                   f"{'high' if side > 0 else 'low'} side of {centre:.9g}"))
        if abs(e - centre) > half:
            signals.append(_signal("EWMA", name, p, f"EWMA {e:.9g} beyond "
                                   f"{centre - half:.9g} .. {centre + half:.9g}"))
    return Series(quantity, rate, pts, centre, sigma, source, tuple(ewma), tuple(lim),
                  tuple(signals))


def _beyond(z: Sequence[float], i: int, k: float, n: int, m: int, sign: float) -> bool:
    """n of the m points ending at i (i among them) beyond k sigma on the side `sign`."""
    w = z[max(0, i - m + 1):i + 1]
    return len(w) == m and sum(1 for v in w if v * sign > k) >= n and z[i] * sign > k


def _signal(rule: str, series: str, p: CheckPoint, text: str) -> Signal:
    return Signal(rule, series, p.run_uid, p.run_dir, p.date_utc, p.check.value, text)


def charts(points: Sequence[CheckPoint]) -> list[Series]:
    """One chart per quantity and rate, in the order of `checks.quantities()`."""
    groups: dict[tuple[str, float | None], list[CheckPoint]] = {}
    for p in points:
        groups.setdefault((p.check.quantity, p.check.set_rate_dps), []).append(p)
    order = list(quantities())
    keys = sorted(groups, key=lambda k: (order.index(k[0]) if k[0] in order else 99,
                                         k[1] if k[1] is not None else -1.0))
    return [_chart(q, r, groups[(q, r)]) for q, r in keys]


@dataclass(frozen=True)
class InstrumentStatus:
    """What `bench control`, the start of a run and the certificate say of an instrument."""

    serial: str
    role: str
    model: str | None
    state: str                                  # IN_CONTROL | OUT_OF_CONTROL | NOT_ENOUGH
    runs: int
    series: tuple[Series, ...] = ()
    open_signals: tuple[Signal, ...] = ()       # not covered by a review: refuse
    reviewed_signals: tuple[Signal, ...] = ()
    reviews: tuple[ReviewInfo, ...] = field(default=())
    #: charted from runs on the twins (a real run's chart never holds them)
    simulated: bool = False

    @property
    def rule(self) -> str | None:
        return self.open_signals[0].rule if self.open_signals else None

    @property
    def name(self) -> str:
        return f"{self.role} {self.serial}" + (f" ({self.model})" if self.model else "")

    @property
    def last_review(self) -> ReviewInfo | None:
        return self.reviews[-1] if self.reviews else None

    @property
    def line(self) -> str:
        """One line: the status, the rule, the count, the review."""
        if self.state == NOT_ENOUGH:
            text = f"not enough history ({self.runs} of {BASELINE_RUNS} runs for a baseline)"
            r = next((r for r in reversed(self.reviews) if r.new_baseline), None)
            if r is not None and r.through_utc is not None:
                text += (f"; baseline restarted at the run of "
                         f"{r.through_utc:%Y-%m-%d %H:%M} UTC by the review of "
                         f"{r.reviewer} on {r.utc:%Y-%m-%d}: {r.text}")
        elif self.state == OUT_OF_CONTROL:
            first = self.open_signals[0]
            more = len(self.open_signals) - 1
            text = f"OUT OF CONTROL, {first.line}" + (f" (and {more} more signal(s))"
                                                      if more else "")
        else:
            text = f"in control ({self.runs} runs; {self.series_baseline})"
        r = self.last_review
        if r is not None and self.state != NOT_ENOUGH and self.reviewed_signals:
            text += (f"; signal(s) up to {r.through_utc:%Y-%m-%d %H:%M UTC} reviewed by "
                     f"{r.reviewer} on {r.utc:%Y-%m-%d %H:%M UTC}: {r.text}"
                     if r.through_utc else f"; reviewed by {r.reviewer}: {r.text}")
        if self.simulated:
            text += "; SIMULATED runs only (kept apart from real runs)"
        return f"{self.name}: {text}"

    @property
    def series_baseline(self) -> str:
        b = next((s for s in self.series if s.has_baseline), None)
        return b.baseline_text if b else "no baseline"


def status_of(serial: str, role: str, model: str | None, points: Sequence[CheckPoint],
              reviews: Sequence[ReviewInfo]) -> InstrumentStatus:
    """The status from the points given (e.g. up to one run) and every review recorded."""
    restart = max((r.through_utc for r in reviews if r.new_baseline and r.through_utc),
                  default=None)
    if restart is not None:    # a reviewed change (a repair, a new level): chart afresh
        points = [p for p in points if p.date_utc is None or p.date_utc >= restart]
    series = charts(points)
    runs = len({p.run_uid for p in points})
    if not any(s.has_baseline for s in series):
        return InstrumentStatus(serial, role, model, NOT_ENOUGH, runs, tuple(series),
                                reviews=tuple(reviews))
    covered = max((r.through_utc for r in reviews if r.through_utc), default=None)
    signals = [g for s in series for g in s.signals]

    def is_covered(g: Signal) -> bool:
        return covered is not None and g.date_utc is not None and g.date_utc <= covered

    open_ = tuple(g for g in signals if not is_covered(g))
    done = tuple(g for g in signals if is_covered(g))
    return InstrumentStatus(serial, role, model, OUT_OF_CONTROL if open_ else IN_CONTROL,
                            runs, tuple(series), open_, done, tuple(reviews))


def instrument_status(rec: Records, serial: str, extra: Sequence[CheckPoint] = (),
                      through: dt.datetime | None = None, simulated: bool | None = None
                      ) -> InstrumentStatus | None:
    """One instrument's status from the records, with `extra` points (a run not yet
    registered) and only points up to `through` (the run a certificate is about).

    Runs on the twins and real runs are charted apart (twins report the serials a stand
    file states): `simulated` picks which; by default the kind of the `extra` run, else
    the real runs, or the simulated ones for an instrument that has no real run."""
    known = {i.serial: i for i in rec.instruments()}
    pts = [p for p in rec.checks(serial) if p.run_uid not in {e.run_uid for e in extra}]
    pts += list(extra)
    pts = same_kind(pts, extra[0].simulated if extra and simulated is None else simulated)
    if through is not None:
        pts = [p for p in pts if p.date_utc is None or p.date_utc <= through]
    epoch = dt.datetime.min.replace(tzinfo=dt.UTC)
    pts.sort(key=lambda p: p.date_utc or epoch)
    if serial not in known and not pts:
        return None
    info = known.get(serial)
    role = info.role if info else (extra[0].check.role if extra else "instrument")
    model = info.model if info else (extra[0].check.model if extra else None)
    status = status_of(serial, role, model, pts, rec.reviews(serial) if info else [])
    return replace(status, simulated=bool(pts) and pts[0].simulated)


def same_kind(points: Sequence[CheckPoint], simulated: bool | None) -> list[CheckPoint]:
    """The points of real runs, or of runs on the twins (`simulated`); None: the real ones
    where there are any, else the simulated ones."""
    if simulated is None:
        simulated = not any(not p.simulated for p in points)
    return [p for p in points if p.simulated == simulated]


def all_statuses(rec: Records) -> list[InstrumentStatus]:
    out = []
    for i in rec.instruments():
        s = instrument_status(rec, i.serial)
        if s is not None:
            out.append(s)
    return out
