"""Injected faults: each gives a clear exception within a bounded time, and afterwards the
counter is in a known state (idle, error queue empty) and measures correctly again."""

from __future__ import annotations

import time

import numpy as np
import pytest

from drivers.counter import (
    Counter,
    CounterConnectionError,
    CounterMeasurementTimeout,
    CounterReplyError,
    CounterTimeout,
)
from drivers.counter_profiles import PROFILES
from sims.counter_twin import CounterTwin
from tests.conftest import Twins
from tests.counter_rig import AXIS, PERIOD_S, counter_block, truth_edges, turning_stand

COMMAND_TIMEOUT_S = 0.3
MARGIN_S = 0.3

# (fault, model) -> what the driver must raise, and a phrase of its message
EXPECTED = {
    ("no-trigger", "keysight-53230a"): (CounterMeasurementTimeout, r"9\.91E37.*0 of 4"),
    ("no-trigger", "pendulum-cnt-91"): (CounterTimeout, r"not complete within"),
    ("no-trigger", "generic-scpi-period"): (CounterTimeout, r"no reply to 'READ\?'"),
    ("garbage", "keysight-53230a"): (CounterReplyError, r"'FETC\?' is not ASCII"),
    ("garbage", "pendulum-cnt-91"): (CounterReplyError, r"'FETC:ARR\? 4' is not ASCII"),
    ("garbage", "generic-scpi-period"): (CounterReplyError, r"'READ\?' is not ASCII"),
    ("drop", "keysight-53230a"): (CounterConnectionError, r"FETC\?.*link was lost"),
    ("drop", "pendulum-cnt-91"): (CounterConnectionError, r"FETC:ARR\? 4.*link was lost"),
    ("drop", "generic-scpi-period"): (CounterConnectionError, r"READ\?.*link was lost"),
}


@pytest.mark.timeout(20)
@pytest.mark.parametrize("fault,model", sorted(EXPECTED))
def test_fault_gives_a_clear_error_then_the_counter_works(fault, model, twins: Twins):
    stand = turning_stand()
    exc_type, phrase = EXPECTED[fault, model]
    twin = twins.counter(stand, AXIS, model=model)
    counter = Counter.open(twin.resource, model, stand.clock,
                           command_timeout_s=COMMAND_TIMEOUT_S, timeout_margin_s=MARGIN_S)
    with counter:
        counter.configure(level_v=2.5)
        twin.inject(fault)
        what = "edges" if counter.supports_timestamps else "periods"
        t0 = time.monotonic()
        with pytest.raises(exc_type, match=phrase) as info:
            counter.arm(4, PERIOD_S, what=what)
            counter.fetch()
        took = time.monotonic() - t0
        # bounded: the measurement's own span plus a few command timeouts
        assert took < 4 * PERIOD_S * 2.5 / stand.clock.speed + MARGIN_S \
            + 5 * COMMAND_TIMEOUT_S
        notes = " ".join(getattr(info.value, "__notes__", []))
        assert "recovered" in notes and "idle" in notes
        if fault == "drop":
            assert twin.sessions == 2 and "reopened" in notes
        # known state: nothing measuring, nothing queued; and it measures again
        assert twin.acquisition is None or twin.acquisition.values is not None
        assert not twin.errors
        t_from = stand.clock.now()
        periods = counter.acquire_periods(2, PERIOD_S)
        truth = np.diff(truth_edges(stand, t_from, np.inf))
        assert len(periods) == 2, periods
        assert all(np.min(np.abs(truth - p)) <= PROFILES[model].resolution_s * 1.001
                   for p in periods)


@pytest.mark.timeout(20)
def test_faults_are_named_and_unknown_ones_refused():
    stand = turning_stand()
    twin = CounterTwin(stand, AXIS, counter_block())
    assert {"no-trigger", "garbage", "drop"} <= twin.fault_names
    with pytest.raises(ValueError, match="unknown fault 'smoke'.*drop"):
        twin.inject("smoke")
