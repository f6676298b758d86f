"""The operator's console: what a person (or a program) watching `bench run` sees.

    open_console(quiet=..., log_json=...) -> a console for the engine and the procedures

On a terminal, a live display (`live.py`); otherwise plain lines, one per step
(`plain.py`); `--quiet` keeps only what needs a person (`quiet.py`); `--log-json` writes
JSON lines (`jsonlog.py`). How long the run has left is `timeline.py`; the summary that
reads like the certificate is `bench/app/summary.py`.
"""

from __future__ import annotations

import os
import sys
from typing import IO

from bench.app.console.jsonlog import JsonConsole
from bench.app.console.live import LiveConsole
from bench.app.console.plain import PlainConsole
from bench.app.console.quiet import QuietConsole
from bench.app.console.timeline import Eta, Timeline, format_eta

__all__ = ["Eta", "JsonConsole", "LiveConsole", "PlainConsole", "QuietConsole", "Timeline", "format_eta",
           "is_terminal", "open_console"]


def is_terminal(stream: IO[str]) -> bool:
    """A terminal a person watches (not a pipe, a file, or TERM=dumb)."""
    isatty = getattr(stream, "isatty", None)
    return bool(isatty and isatty()) and os.environ.get("TERM", "") != "dumb"


def open_console(*, quiet: bool = False, log_json: bool = False,
                 stream: IO[str] | None = None) -> PlainConsole:
    stream = stream or sys.stderr
    if log_json:
        return JsonConsole(stream)
    if quiet:
        return QuietConsole(stream)
    if is_terminal(stream):
        return LiveConsole(stream)
    return PlainConsole(stream)
