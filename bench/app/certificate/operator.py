"""What the event log says about the people and the software behind a run: the operator's
answers to the set-up prompts (or that --yes answered them), and the ratebench version of
every session and of the certificate itself."""

from __future__ import annotations

import datetime as dt
from collections.abc import Sequence

from bench.core.events import Event, Prompted, SessionStarted, of_kind
from bench.report.certificate.model import Block, Para, Table
from bench.report.certificate.parts import NOT_RECORDED
from drivers.json_types import JsonValue


def utc_text(stamp: str | None) -> str:
    """A journal stamp as the certificate prints it (UTC, to the second)."""
    if not stamp:
        return NOT_RECORDED
    try:
        t = dt.datetime.fromisoformat(str(stamp).replace("Z", "+00:00"))
    except ValueError:
        return str(stamp)
    if t.tzinfo is not None:
        t = t.astimezone(dt.UTC)
    return t.strftime("%Y-%m-%d %H:%M:%S UTC")


def _answered_by(e: Prompted) -> str:
    """'--yes' or 'operator' (older logs say only answered: yes | operator)."""
    return e.answered_by or ("--yes" if e.answered == "yes" else "operator")


def _answer(e: Prompted) -> str:
    if _answered_by(e) == "--yes":
        return "confirmed by --yes (unattended run: nobody was asked)"
    typed = e.answer.strip()
    if e.answered == "abort":
        return f"aborted by the operator ({typed!r})"
    return "confirmed by the operator" + (f" ({typed!r})" if typed else " (Enter)")


def prompt_blocks(events: Sequence[Event]) -> tuple[Block, ...]:
    """The set-up prompts of the run, in order, with who answered and when."""
    prompts = of_kind(events, Prompted)
    if not prompts:
        return ()
    rows = tuple((str(e.session), e.text, utc_text(e.answered_utc or e.utc), _answer(e))
                 for e in prompts)
    notes: tuple[str, ...] = ()
    if any(_answered_by(e) == "--yes" for e in prompts):
        notes = ("--yes: the run was started unattended and the set-up steps were not "
                 "confirmed by a person at the time of the run.",)
    return (Table(("Session", "Set-up step asked of the operator", "Answered", "Answer"), rows,
                  widths=(0.7, 4.2, 1.7, 2.4), align="clll",
                  caption="Operator prompts (set-up steps confirmed during the run)",
                  notes=notes),)


def software_note(created: JsonValue, events: Sequence[Event],
                  issuing_version: str, run_dir: str) -> Para:
    """The version that created the run (`created`: meta.json's bench_version), ran each
    session and issued this certificate."""
    sessions = {e.session: e.version for e in of_kind(events, SessionStarted) if e.version}
    versions = sorted(set(sessions.values()) | ({str(created)} if created else set()))
    if not versions:
        ran = "version of the run not recorded"
    elif len(versions) == 1:
        ran = f"run with ratebench {versions[0]}"
    else:
        ran = "run with ratebench " + ", ".join(
            f"{v} (session {s})" for s, v in sorted(sessions.items()))
    return Para(f"Software: {ran}; certificate issued by ratebench {issuing_version}. "
                f"Run directory: {run_dir}.", "note")
