"""The counter driver against its twin over the real pyvisa-py TCPIP SOCKET path.

Truth is the simulated stand's zero-mark edge times: every reported edge must be the
stand's edge rounded to the profile's resolution, every period the difference of two
such edges (so within one resolution step of the true difference).
"""

from __future__ import annotations

import dataclasses
import re
import time

import numpy as np
import pytest

from drivers.counter import (
    Counter,
    CounterCommandError,
    CounterError,
    CounterMeasurementTimeout,
)
from drivers.counter_profiles import PROFILES
from drivers.scpi import Command
from drivers.time_tie import TimeTie
from sims.counter_twin import CounterTwin, SyncLink
from tests.conftest import Twins
from tests.counter_rig import AXIS, PERIOD_S, SPEED, counter_block, truth_edges, turning_stand

TIMESTAMP_MODELS = [m for m, p in PROFILES.items() if p.supports_timestamps]

pytestmark = pytest.mark.timeout(30)


@pytest.fixture
def stand():
    return turning_stand()


#: the FOG's sync output on the counter's external trigger: a pulse every 2 virtual s
#: (10 ms real at SPEED), 3 us of link latency, known exactly here (no jitter)
SYNC = SyncLink(period_s=2.0, latency_s=3e-6)
TIE = TimeTie("fog-sync", sync_period_s=2.0, latency_s=3e-6)


def open_pair(stand, model, **kw):
    twin = CounterTwin(stand, AXIS, counter_block(model), sync=SYNC)
    resource = twin.start()
    tie = TIE if PROFILES[model].words.trigger_source is not None else None
    try:
        counter = Counter.open(resource, model, stand.clock, time_tie=tie,
                               timeout_margin_s=kw.pop("timeout_margin_s", 1.0), **kw)
    except BaseException:
        twin.stop()
        raise
    return twin, counter


def configured_pair(stand, model):
    twin, counter = open_pair(stand, model)
    with twin, counter:
        counter.configure(channel=1, level_v=2.5)
        yield twin, counter


@pytest.fixture(params=sorted(PROFILES))
def pair(request, stand):
    yield from configured_pair(stand, request.param)


@pytest.fixture(params=TIMESTAMP_MODELS)
def ts_pair(request, stand):
    yield from configured_pair(stand, request.param)


def test_every_profile_identifies_and_takes_its_input_setup(pair):
    twin, counter = pair
    assert counter.identify() == counter.profile.idn
    state = twin.inputs[1]
    assert (state.level_v, state.level_auto, state.coupling, state.impedance_ohm,
            state.slope) == (2.5, False, "DC", 1e6, "POS")
    assert not twin.errors


def test_edges_are_the_stands_next_edges_after_the_arm(ts_pair, stand):
    twin, counter = ts_pair
    res = counter.profile.resolution_s
    edges = counter.acquire_edges(6, PERIOD_S)
    t_start = twin.acquisition.t_start_s
    truth = truth_edges(stand, t_start, t_start + 6.5 * PERIOD_S)
    assert truth.size >= 6 and truth[6:].size <= 1
    truth = truth[:6]                         # consecutive: no edge skipped, none extra
    assert truth[0] >= t_start                # the first edge after the start event
    if counter.time_tie.uses_external_trigger:  # the tie places them on the stand's axis
        np.testing.assert_array_less(np.abs(edges - truth), 0.5 * res + 1e-15 * truth)
    else:  # a host-clock tie: the start is INIT, which the host only brackets
        # INIT took effect inside the bracket the driver timed: within its stated u
        assert abs(edges[0] - truth[0]) <= counter.last_acquisition.t_start_u_s + 1e-9
        edges = edges - edges[0] + truth[0]
    np.testing.assert_array_less(np.abs(np.diff(edges) - np.diff(truth)), res * 1.001)
    # not nominal: the harmonic makes the turns differ by far more than the resolution
    assert np.ptp(np.diff(edges)) > 1e3 * res


def test_periods_from_timestamps_are_consecutive_true_periods(ts_pair, stand):
    twin, counter = ts_pair
    periods = counter.acquire_periods(5, PERIOD_S)
    acq = counter.last_acquisition
    assert acq.consecutive and acq.method == "timestamps" and periods.size == 5
    truth = truth_edges(stand, twin.acquisition.t_start_s, np.inf)[:6]
    err = periods - np.diff(truth)
    assert np.max(np.abs(err)) <= counter.profile.resolution_s * 1.001


def test_53230a_period_mode_times_every_other_turn(stand):
    twin, counter = open_pair(stand, "keysight-53230a")
    with twin, counter:
        counter.configure(level_v=1.0)
        periods = counter.acquire_periods(3, PERIOD_S, method="init-fetch")
        assert not counter.last_acquisition.consecutive
        e = truth_edges(stand, twin.acquisition.t_arm_s, np.inf)[:6]
        truth = e[1::2] - e[0::2]
        assert np.max(np.abs(periods - truth)) <= 20e-12 * 1.001
        assert "CONF:PER (@1)" in twin.received and "SAMP:COUN 3" in twin.received


def test_generic_counter_reads_one_true_period_per_read(stand):
    twin, counter = open_pair(stand, "generic-scpi-period")
    with twin, counter:
        counter.configure(level_v=2.5)
        t0 = stand.clock.now()
        periods = counter.acquire_periods(3, PERIOD_S)
        truth = np.diff(truth_edges(stand, t0, np.inf))
        # each reading is some true turn (1 ns resolution), the turns in order. Periods
        # differ by the edges' 27 ns jitter only, so two turns can lie within 1 ns of
        # each other: a reading is matched to the first turn after the previous match
        # that agrees within the resolution (nearest of all turns picked an earlier
        # twin of the right one now and then, on a quiet machine too)
        assert len(periods) == 3, periods
        k: list[int] = []
        for p in periods:
            later = np.flatnonzero(np.abs(truth - p) <= 1e-9)
            later = later[later > (k[-1] if k else -1)]
            assert later.size, (p, truth, k)
            k.append(int(later[0]))
        assert twin.received.count("READ?") == 3
        with pytest.raises(CounterError, match="cannot timestamp"):
            counter.acquire_edges(3, PERIOD_S)


def test_raw_callback_sees_every_byte_and_the_data_is_unaltered(stand):
    log: list[tuple[str, bytes]] = []
    twin, counter = open_pair(stand, "keysight-53230a", raw=lambda d, b: log.append((d, b)))
    with twin, counter:
        counter.configure(level_v=2.5)
        edges = counter.acquire_edges(4, PERIOD_S)
    tx = [b for d, b in log if d == "tx"]
    rx = [b for d, b in log if d == "rx"]
    assert all(b.endswith(b"\n") for b in tx + rx)
    assert b"INP1:LEV 2.5\n" in tx and b"INP1:LEV:AUTO OFF\n" in tx
    i = tx.index(b"FETC?\n")
    reply = [b for d, b in log[log.index(("tx", b"FETC?\n")):] if d == "rx"][0]
    assert i > tx.index(b"INIT\n")
    values = [float(v) for v in reply.decode().strip().split(",")]
    assert values[0] == 1                                  # prescaler, then intervals
    t_start = counter.last_acquisition.t_start_s
    assert values[1] == pytest.approx(edges[0] - t_start, abs=1e-10)
    np.testing.assert_allclose(values[2:], np.diff(edges), rtol=0, atol=1e-10)
    assert re.search(rb"E[+-]\d{3}(,|\n)", reply)          # the 53230A's 3-digit exponent


def test_timeouts_scale_with_the_expected_period_and_the_clock(stand):
    twin, counter = open_pair(stand, "keysight-53230a", timeout_margin_s=0.7)
    with twin, counter:
        counter.configure(level_v=2.5)
        acq = counter.arm(8, 4.0)
        allowed = acq.deadline_real_s - acq.armed_real_s
        # n turns, plus the wait for the first sync pulse of the time tie
        assert allowed == pytest.approx((8 * 4.0 * 1.25 + TIE.sync_period_s) / SPEED + 0.7,
                                        rel=1e-6)
        # per reading (Programmer's Reference p. 459): a start edge and one turn
        assert twin.timeout_s == pytest.approx(2 * 4.0 * 1.25)   # instrument s (virtual)
        counter.fetch()
    assert twin.timeout_s is None   # non-volatile: restored to what it was (disabled)


def test_wrong_model_is_refused_by_identity(stand, twins: Twins):
    twin = twins.counter(stand, AXIS, model="pendulum-cnt-91")
    with pytest.raises(CounterError, match=r"\*IDN\?.*not a keysight-53230a"):
        Counter.open(twin.resource, "keysight-53230a", stand.clock)


def test_misspelt_profile_word_names_the_command_and_minus_113(stand, twins: Twins):
    base = PROFILES["keysight-53230a"]
    typo = dataclasses.replace(base, words=dataclasses.replace(
        base.words, input_level=Command("INPut{channel}:LVL", "{level_v}")))
    twin = twins.counter(stand, AXIS, model="keysight-53230a")
    counter = Counter.open(twin.resource, typo, stand.clock)
    with counter:
        with pytest.raises(CounterCommandError, match=r"'INP1:LVL 2\.5'.*-113.*Undefined"):
            counter.configure(level_v=2.5)
        assert not twin.errors                      # drained and reported, not left


def test_unknown_command_and_unknown_query_name_themselves(stand):
    twin, counter = open_pair(stand, "keysight-53230a", command_timeout_s=0.3)
    with twin, counter:
        with pytest.raises(CounterCommandError, match=r"'CONF:PERX \(@1\)'.*-113") as e:
            counter.write("CONF:PERX (@1)")
        assert e.value.errors[0].code == -113
        t0 = time.monotonic()
        with pytest.raises(CounterCommandError, match=r"'FETX\?' got no reply.*-113"):
            counter.query("FETX?")
        assert time.monotonic() - t0 < 2.0
        assert counter.identify().startswith("Keysight")   # still in step


def test_configure_refuses_bad_settings_before_sending(stand):
    twin, counter = open_pair(stand, "pendulum-cnt-91")
    with twin, counter:
        sent = len(twin.received)
        for kwargs, word in [({}, "needs level_v"), ({"level_v": 9.0}, "level_v 9.0"),
                             ({"level_v": 1, "slope": "UP"}, "slope"),
                             ({"level_v": 1, "channel": 3}, "channel 3"),
                             ({"level_v": 1, "impedance_ohm": 75}, "impedance_ohm 75")]:
            with pytest.raises(CounterError, match=word):
                counter.configure(**kwargs)
        assert len(twin.received) == sent
        with pytest.raises(CounterError, match="before configure"):
            counter.arm(3, PERIOD_S)


def test_a_level_outside_the_signal_gives_a_measurement_timeout_then_works(stand):
    twin, counter = open_pair(stand, "keysight-53230a")
    with twin, counter:
        counter.configure(level_v=-1.0)      # the pulse swings 0 .. 5 V: never crossed
        with pytest.raises(CounterMeasurementTimeout, match=r"9\.91E37.*0 of 3.*crossing -1\.0 V"):
            counter.acquire_edges(3, PERIOD_S)
        counter.configure(level_v=2.5)
        assert counter.acquire_edges(3, PERIOD_S).size == 3


def test_profiles_have_the_error_budget_data():
    for p in PROFILES.values():
        assert p.resolution_s > 0 and p.single_shot_s > 0 and p.timebase_limit_rel > 0
        assert p.notes
    k = PROFILES["keysight-53230a"]
    # docs/method.md A1 d_counter by hand: sqrt(2) * 20 ps and 1e-6/sqrt(3) * 0.36 s
    assert k.period_u_s(0.36) == pytest.approx(np.hypot(np.sqrt(2) * 20e-12,
                                                        1e-6 / np.sqrt(3) * 0.36))
    assert k.period_u_s(0.36) == pytest.approx(2.0785e-7, rel=1e-4)
