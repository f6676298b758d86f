"""Shared test helpers."""

from __future__ import annotations

import os
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parent.parent
CONFIGS = ROOT / "configs"
#: the serials the outer axis's twins of configs/stands/sim-two-axis.yaml report (the FOG's
#: as the stand states it, the counter's *IDN? field, the drive's 0x1018:4): the records
#: keep check values per instrument under them
OUTER_SERIALS = {"fog": "1760-20231", "counter": "MY62000117", "drive": "41001"}


def unavailable(reason: str) -> None:
    """A test's server or facility (PostgreSQL, a browser, a multicast bus, a tmpfs) is
    missing: in CI (`CI` set, as .ci/run's caller does) that is a failure, since .ci/run
    installs them and a skip would hide the gap; on a developer's machine, a skip saying so.
    """
    if os.environ.get("CI"):
        pytest.fail(f"{reason} (CI installs it: see .ci/run)", pytrace=False)
    pytest.skip(reason)


@pytest.fixture
def configs() -> Path:
    return CONFIGS


def when_step_starts(run: Any, match: Callable[[dict[str, Any]], bool],
                     action: Callable[[], Any], delay_s: float = 0.05) -> threading.Thread:
    """Call `action` (e.g. inject a fault into a twin) once a matching step has started."""
    def watch() -> None:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            if any(e.get("event") == "step_start" and match(e) for e in run.events()):
                time.sleep(delay_s)
                action()
                return
            time.sleep(0.01)
    t = threading.Thread(target=watch, daemon=True)
    t.start()
    return t
