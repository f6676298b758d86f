"""Twins that drift across runs: a FOG scale step or ramp from run N (stand `sim:` keys).

Measurement assurance (docs/method.md C) is shown on twins only if a twin can change
between runs the way a real FOG does after a knock or with age:

    sim:
      run_number: 9                 # this run's number; absent: 1 + the runs of this
                                    # table in the records (resolved at the run's start)
      axes:
        outer:
          fog: {scale: 1.0003,
                scale_step: {from_run: 9, rel: 2.4e-5},        # scale * (1 + rel) from run 9
                scale_ramp: {from_run: 3, rel_per_run: 1e-7}}  # and/or + rel_per_run a run

`drifted(stand, run_number)` turns these keys into the truth's plain `scale` for this
run, before any twin sees the stand, and says what it applied.
"""

from __future__ import annotations

import dataclasses

import msgspec

from bench.core.config import SimSettings, StandSettings

DRIFT_KEYS = ("scale_step", "scale_ramp")


def has_drift(stand: StandSettings) -> bool:
    return stand.sim is not None and stand.sim.has_drift


def stated_run_number(stand: StandSettings) -> int | None:
    return stand.sim.run_number if stand.sim is not None else None


def drifted(sim: SimSettings, run_number: int) -> tuple[SimSettings, list[str]]:
    """The twins' truth with each drifting FOG's scale for run `run_number`; what was
    applied."""
    axes = dict(sim.axes)
    notes = []
    for axis, a in sim.axes.items():
        step, ramp = a.scale_step, a.scale_ramp
        if not (step or ramp):
            continue
        rel = 0.0
        if step and run_number >= step[0]:
            rel += step[1]
        if ramp and run_number >= ramp[0]:
            rel += ramp[1] * (run_number - ramp[0] + 1)
        fog = msgspec.structs.replace(a.truth.fog, scale=a.truth.fog.scale * (1.0 + rel),
                                      scale_step=None, scale_ramp=None)
        axes[axis] = dataclasses.replace(a, truth=msgspec.structs.replace(a.truth, fog=fog),
                                         scale_step=None, scale_ramp=None)
        notes.append(f"sim: axis {axis} FOG scale x (1 {rel:+.3g}) in run {run_number}")
    return msgspec.structs.replace(sim, axes=axes), notes
