"""The drive's own checks in the records (bench/app/records/checks.py `_drive`, docs/method.md
C1): the settle time beyond the commanded ramp, and the velocity ripple while the counter
times turns, on a hand-written journal and drive log whose values are derived by hand.

Why: the ripple's window is the step that timed the half, found without naming any kind's
step (issue 61): a feedback sample of an earlier step of the same unit (the move, the
settle) must not enter it. Nothing real produces this journal: it is written here so every
number is known (a run of the twins is covered by test_records' recertifications).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from bench.app.records.checks import _drive
from bench.core import rundir_layout as layout
from bench.core.events import Event, StepStarted
from procedures.rate_ladder.events import HalfAcquired


def _half(t_s: float, rate_dps: float) -> HalfAcquired:
    return HalfAcquired(axis="outer", unit="u1", half=0, set_rate_dps=rate_dps, turns=1,
                        edges_s=[0.0, 1.0], counter_records=[0, 1], fog_from=0, fog_to=1,
                        rate_hz=1.0, t_s=t_s, session=1)


def _log(path: Path, records: list[dict[str, object]]) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("".join(json.dumps(r) + "\n" for r in records))


def test_the_ripple_is_taken_over_the_step_that_timed_the_half_only(tmp_path: Path) -> None:
    rate = 10.0
    events: list[Event] = [
        StepStarted(index=0, action="move", axis="outer", unit="u1", t_s=0.0, session=1),
        StepStarted(index=1, action="hold", axis="outer", unit="u1", t_s=2.0, session=1),
        StepStarted(index=2, action="time", axis="outer", unit="u1", t_s=4.0, session=1),
        _half(8.0, rate),
    ]
    _log(tmp_path / layout.RAW / "s1" / layout.drive_log("outer"), [
        {"kind": "command", "t_s": 0.0, "sent_dps": rate, "accel_dps2": 5.0},
        {"kind": "feedback", "t_s": 1.0, "velocity_dps": 5.0},     # the move: outside
        {"kind": "feedback", "t_s": 3.0, "velocity_dps": 9.0},     # the hold: outside
        {"kind": "settled", "t_s": 3.5, "target_dps": rate, "hold_s": 1.0, "samples": 11},
        {"kind": "feedback", "t_s": 5.0, "velocity_dps": 10.1},    # timed: +1 %
        {"kind": "feedback", "t_s": 6.0, "velocity_dps": 9.9},     # timed: -1 %
        {"kind": "feedback", "t_s": 7.0, "velocity_dps": 10.0},    # timed: 0
        {"kind": "feedback", "t_s": 9.0, "velocity_dps": 0.0},     # after the half: outside
    ])
    checks = {c.quantity: c for c in _drive("outer", layout.raw_root(tmp_path), events,
                                            "41001", None)}
    # ripple: rms of (+0.01, -0.01, 0) = sqrt(2e-4 / 3)
    assert checks["ripple_rel"].value == pytest.approx(math.sqrt(2e-4 / 3), rel=1e-12)
    # settle: settled at 3.5 after holding 1.0, commanded at 0.0, ramp 10 / 5 = 2.0 s
    # -> 3.5 - 1.0 - 0.0 - 2.0 = 0.5 s; known to one feedback interval 1.0 / 10 = 0.1 s
    # (rectangular): U = 2 * 0.1 / sqrt(3)
    assert checks["settle_time_s"].value == pytest.approx(0.5, rel=1e-12)
    assert checks["settle_time_s"].u == pytest.approx(0.2 / math.sqrt(3), rel=1e-12)


def test_a_half_of_another_session_does_not_take_this_sessions_start(tmp_path: Path) -> None:
    events: list[Event] = [
        StepStarted(index=2, action="time", axis="outer", unit="u1", t_s=4.0, session=2),
        _half(8.0, 10.0),              # session 1: no step of it started -> no window
    ]
    _log(tmp_path / layout.RAW / "s1" / layout.drive_log("outer"),
         [{"kind": "feedback", "t_s": 5.0, "velocity_dps": 12.0}])
    checks = {c.quantity for c in _drive("outer", layout.raw_root(tmp_path), events,
                                         "41001", None)}
    assert "ripple_rel" not in checks
