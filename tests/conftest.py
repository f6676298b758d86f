"""Shared test helpers."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parent.parent
CONFIGS = ROOT / "configs"


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
