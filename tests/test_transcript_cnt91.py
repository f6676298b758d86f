"""Pendulum CNT-91: single time stamps beyond 10 000, fetched in chunks as the handbook
says; the X counter read as a count of crossings; the twin over TCP too.

Sources: Pendulum CNT-90 series Programmer's Handbook (also CNT-91R), Command Reference:
- :FETCh:ARRay? (p. 8-35): "the first measurement made is the first result to be
  fetched ... The second :FETCh:ARRay? 10 fetches the result 11 to 20, and so on";
  "<fetch array size> ... The maximum limit is 10000 due to the physical size of the
  output buffer."
- :MEASure:ARRay:STSTamp? (p. 8-72): with :FORMat:TINFormation ON each stamp gives
  "<number of trg lvl crossings>,<TS for trg lvl crossing>"; "The X counter records the
  number of trigger level crossings"; TS is seconds "since a certain start event that is
  not available for external control".
The old driver asked for all results in one FETC:ARR? (refused by a real CNT-91 beyond
10 000) and required X to step by exactly 1.

The start arming (:ARM:SOURce, as PyMeasure's cnt91 driver sends it: IMM, or EXT4 for
the rear arming input E that the FOG's sync pulse drives) is set and read back before
INIT; the driver takes TS as counted from that start and refuses edges whose first TS
is longer than a turn (a TS counted from another start event, which p. 8-72 allows).
"""

from __future__ import annotations

import numpy as np
import pytest

from drivers.counter import Counter, CounterError
from drivers.counter_profiles import PENDULUM_CNT91, nr3
from drivers.transport import Like, expected_protocol
from sims.clock import VirtualClock
from sims.counter_twin import CounterTwin
from tests.counter_rig import AXIS, counter_block, turning_stand
from tests.transcripts import NO_ERROR_PENDULUM, checked, replay_on_twin

N = 12_000
IDN = "Pendulum Instruments AB,CNT-91,608500,V1.28 26 Jan 2011 08:57"
#: the stamps: X counts every crossing (here 2 a turn: both slopes of the mark pass the
#: level), TS from the measurement's start, a turn of ~1 s
X = 7 + 2 * np.arange(N)
TS = 0.5 + 1.000001 * np.arange(N)


def pairs(lo: int, hi: int, offset_s: float = 0.0) -> str:
    return ",".join(f"{x},{nr3(t + offset_s, 14, 2)}"
                    for x, t in zip(X[lo:hi], TS[lo:hi], strict=True))


def chk(cmd: str) -> list:
    return checked(cmd, NO_ERROR_PENDULUM)


def transcript() -> list:
    inputs = [*chk("INP1:COUP DC"), *chk("INP1:IMP 1000000"), *chk("INP1:LEV:AUTO OFF"),
              *chk("INP1:LEV 2.5"), *chk("INP1:SLOP POS")]
    return [
        ("ABOR", None), ("*CLS", None), ("*OPC?", "1"), ("SYST:ERR?", NO_ERROR_PENDULUM),
        ("*IDN?", IDN),
        *inputs, ("INP1:COUP?", "DC"), ("INP1:IMP?", "1.000000E+06"),
        ("INP1:LEV:AUTO?", "0"), ("INP1:LEV?", "2.500000E+00"), ("INP1:SLOP?", "POS"),
        *chk("ABOR"), *chk(f"CONF:ARR:STST ({N}),(@1)"), *inputs, *chk("FORM ASCii"),
        *chk("FORM:TINF ON"), *chk("ARM:SOUR IMM"), ("ARM:SOUR?", "IMM"),
        *chk("INIT"), ("*OPC", None), ("*ESR?", "1"),
        ("FETC:ARR? 10000", pairs(0, 10_000)),       # at most 10 000 a call (p. 8-35)
        ("FETC:ARR? 2000", pairs(10_000, N)),        # then the next ones
        ("SYST:ERR?", NO_ERROR_PENDULUM),
    ]


def make(transport) -> Counter:
    return Counter.open("GPIB0::10::INSTR", PENDULUM_CNT91, VirtualClock(1e6, start_s=50.0,
                                                                         running=False),
                        transport=transport, timeout_margin_s=0.5)


def test_twelve_thousand_stamps_come_in_two_fetches():
    with expected_protocol(make, transcript()) as counter:
        counter.configure(channel=1, level_v=2.5, slope="POS", coupling="DC",
                          impedance_ohm=1e6)
        edges = counter.acquire_edges(N, 1.0)
        counter.close()
    assert edges.size == N
    # TS from the start: the edges are INIT's time (the paused host clock) plus TS
    np.testing.assert_allclose(edges, 50.0 + TS, rtol=0, atol=1e-9)
    assert counter.readback["counter.first TS"] == "0.5 s"


def test_a_ts_from_another_start_event_is_refused_for_edges_not_for_periods():
    """p. 8-72: TS is 'since a certain start event that is not available for external
    control'. A first TS of 12.5 s on ~1 s turns cannot be the first crossing after the
    start: placed by it, the edges would sit 12 turns off on the FOG's axis."""
    late = [(s, r.replace(pairs(0, 10_000), pairs(0, 10_000, 12.0))
             .replace(pairs(10_000, N), pairs(10_000, N, 12.0)) if r else r)
            for s, r in transcript()]
    refused = late[:late.index(("SYST:ERR?", NO_ERROR_PENDULUM), len(late) - 2)]
    refused += [("ABOR", None), ("*CLS", None), ("*OPC?", "1")]
    with expected_protocol(make, refused) as counter:
        counter.configure(channel=1, level_v=2.5, slope="POS", coupling="DC",
                          impedance_ohm=1e6)
        with pytest.raises(CounterError, match=r"first time stamp .* is 12\.5 s, not "
                                               r"within the first turn"):
            counter.acquire_edges(N, 1.0)
        counter.close()
    with expected_protocol(make, late) as counter:    # N stamps: N - 1 periods
        counter.configure(channel=1, level_v=2.5, slope="POS", coupling="DC",
                          impedance_ohm=1e6)
        got = counter.acquire_periods(N - 1, 1.0)
        counter.close()
    np.testing.assert_allclose(got, np.diff(TS), rtol=0, atol=1e-9)


@pytest.mark.timeout(60)
def test_the_twin_serves_the_same_chunks():
    stand = turning_stand(rate_dps=36_000.0)   # 0.01 s a turn: 12 000 turns in 0.6 s real
    twin = CounterTwin(stand, AXIS, counter_block("pendulum-cnt-91"))
    lines = [(s, Like(r, r".+") if s.startswith(("*IDN", "FETC")) or
              (s.endswith("?") and s.startswith("INP")) else r)
             for s, r in transcript() if s not in ("*ESR?", "*OPC")]
    lines.insert(lines.index(("FETC:ARR? 10000", lines[-3][1])), ("*OPC?", "1"))
    with twin:
        stand.clock.start()
        got = replay_on_twin(twin.start(), lines, timeout_s=30.0)
    first, second = (np.array(g.split(","), dtype=float) for g in got[-3:-1])
    assert first.size == 2 * 10_000 and second.size == 2 * 2_000
    ts = np.concatenate([first[1::2], second[1::2]])
    x = np.concatenate([first[0::2], second[0::2]])
    assert np.all(np.diff(x) == 1) and np.all(np.diff(ts) > 0)
    np.testing.assert_allclose(np.diff(ts), 0.01, rtol=1e-3)   # a turn each
