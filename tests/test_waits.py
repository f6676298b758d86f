"""drivers/waits.py: real-time limits that a starved host slows and does not fail.

Truth: a real process stopped with SIGSTOP (what a loaded host, Ctrl-Z or a paused VM does
to the bench) for a known real time, and the limit's own arithmetic by hand.
"""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time

import pytest

from drivers.waits import HOST_STALL_S, Deadline
from tests.conftest import ROOT

#: polls a 1.5 s Deadline every 5 ms; prints when it starts, then when it expires
POLLER = """
import json, sys, time
from drivers.waits import Deadline
d = Deadline(1.5)
t0 = time.monotonic()
print("polling", flush=True)
while not d.expired():
    time.sleep(0.005)
print(json.dumps({"took_s": time.monotonic() - t0, "stalled_s": d.stalled_s}), flush=True)
"""


def test_a_deadline_polled_without_stalls_expires_on_time() -> None:
    d = Deadline(0.2)
    t0 = time.monotonic()
    while not d.expired():
        time.sleep(0.005)
    took = time.monotonic() - t0
    assert 0.2 <= took < 0.2 + HOST_STALL_S   # late only by what the host may add
    assert d.stalled_s == 0.0


@pytest.mark.timeout(30)
def test_a_stopped_process_does_not_count_its_stop_against_the_limit() -> None:
    p = subprocess.Popen([sys.executable, "-c", POLLER], cwd=ROOT, text=True,
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        assert p.stdout is not None and p.stdout.readline().strip() == "polling"
        time.sleep(0.3)
        p.send_signal(signal.SIGSTOP)        # 3 s: twice the whole limit
        time.sleep(3.0)
        p.send_signal(signal.SIGCONT)
        out, err = p.communicate(timeout=20)
    finally:
        p.kill()
    result = json.loads(out.strip().splitlines()[-1])
    # the stop (3 s, and no less: it is real time) is forgiven; the limit's 1.5 s remain
    assert result["stalled_s"] >= 3.0 - 0.05, (result, err)
    assert result["took_s"] >= 1.5 + 3.0 - 0.05, result
    # without the forgiveness the wait would have failed on waking, 1.8 s after it began
    assert result["took_s"] - result["stalled_s"] >= 1.5 - 0.01, result
