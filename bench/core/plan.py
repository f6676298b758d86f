"""A plan: the procedure as steps you can print, limit-check and time with no hardware.

The engine executes exactly these steps; `bench plan` prints them. Each step belongs to
a unit (a static record, a +/- rate pair); a unit is the grain of `--resume`.
"""

from __future__ import annotations

from collections.abc import Collection, Iterable
from dataclasses import dataclass
from typing import TypeVar


@dataclass(frozen=True, slots=True)
class NoParams:
    """The parameters of a step that needs nothing beyond its axis (prompt, enable, ...)."""


@dataclass(frozen=True, slots=True)
class Duration:
    """The parameters of a step that lasts a stated time (a record at rest, a wait)."""

    duration_s: float


P = TypeVar("P")


@dataclass(frozen=True)
class Step:
    """One thing the bench does. `estimate_s` is bench time on a real table."""

    action: str  # prompt, static, enable, set_rate, settle, acquire, analyze, stop, ...
    axis: str | None
    describe: str
    estimate_s: float = 0.0
    unit: str | None = None  # completing the unit's last step completes the unit
    #: the action's typed parameters (a frozen dataclass per action, the kind's), made
    #: once where the plan is built; its handler reads them with `params_as`
    params: object = NoParams()

    @property
    def on_axis(self) -> str:
        """The axis of a step that acts on one; a step built without one is a plan bug."""
        if self.axis is None:
            raise ValueError(f"step {self.action!r} ({self.describe}) names no axis")
        return self.axis

    @property
    def in_unit(self) -> str:
        """The unit of a step that completes part of one (for --resume)."""
        if self.unit is None:
            raise ValueError(f"step {self.action!r} ({self.describe}) belongs to no unit")
        return self.unit

    def params_as(self, kind: type[P]) -> P:
        """The parameters as the type its action's handler takes (else a plan bug)."""
        if not isinstance(self.params, kind):
            raise TypeError(f"step {self.action!r} ({self.describe}) carries "
                            f"{type(self.params).__name__}, not {kind.__name__}")
        return self.params

    @property
    def key(self) -> str:
        return f"{self.unit or self.axis or '-'}:{self.action}:{self.describe}"


def format_duration(seconds: float) -> str:
    s = int(round(seconds))
    h, rem = divmod(s, 3600)
    m, s = divmod(rem, 60)
    if h:
        return f"{h} h {m:02d} min"
    if m:
        return f"{m} min {s:02d} s"
    return f"{s} s"


@dataclass(frozen=True)
class Plan:
    title: str
    steps: tuple[Step, ...]
    #: what the operator should know before starting (e.g. an odd turn count split
    #: unevenly); printed by `bench plan` and at the start of `bench run`
    warnings: tuple[str, ...] = ()

    @property
    def total_s(self) -> float:
        return sum(s.estimate_s for s in self.steps)

    def units(self) -> list[str]:
        seen: list[str] = []
        for s in self.steps:
            if s.unit and s.unit not in seen:
                seen.append(s.unit)
        return seen

    def remaining(self, done_units: Iterable[str]) -> Plan:
        """The steps still to run when `done_units` are complete (for --resume).

        Per-axis setup steps (prompt, enable, stop) are kept for any axis with work left.
        """
        done = set(done_units)
        axes_left = {s.axis for s in self.steps if s.unit and s.unit not in done}
        keep = [s for s in self.steps
                if (s.unit not in done if s.unit else s.axis in axes_left or s.axis is None)]
        return Plan(self.title, tuple(keep), self.warnings)

    def lines(self) -> list[str]:
        """The plan as a table whose columns fit the longest axis name and action."""
        width = len(str(len(self.steps)))
        axis_w = max([len("axis"), *(len(s.axis or "") for s in self.steps)])
        action_w = max([len("action"), *(len(s.action) for s in self.steps)])
        out = [f"Plan: {self.title}", "",
               f"{'#':>{width}}  {'starts at':>12}  {'axis':<{axis_w}}  "
               f"{'action':<{action_w}}  what"]
        t = 0.0
        for i, s in enumerate(self.steps, 1):
            out.append(f"{i:>{width}}  {format_duration(t):>12}  {s.axis or '':<{axis_w}}  "
                       f"{s.action:<{action_w}}  {s.describe}")
            t += s.estimate_s
        out += [""] + [f"Warning: {w}" for w in self.warnings]
        out += [f"Estimated bench time: {format_duration(self.total_s)} "
                f"({self.total_s:.0f} s) for {len(self.steps)} steps"]
        return out


def check_actions(plan: Plan, actions: Collection[str]) -> Plan:
    """`plan`, once every step's action is one the kind has a handler for: a step no
    handler takes is the kind's bug, found when the plan is built (`bench plan`,
    `bench validate` of a run) rather than when the bench reaches it mid-run."""
    missing = sorted({s.action for s in plan.steps} - set(actions))
    if missing:
        raise ValueError(f"plan {plan.title!r}: no step handler for action(s) "
                         f"{', '.join(missing)} (the kind's steps.handlers)")
    return plan
