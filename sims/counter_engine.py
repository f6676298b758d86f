"""The counter twin's measurement engine: from an INIT (or READ?) to the readings, out of
the stand's zero-mark edges, and the replies they make.

A measurement is armed at the stand clock's now(); its readings are the zero-mark edges
after its start event (`AxisModel.zero_marks(...).t_edge_s`), on the stand's time axis
as this counter's time base reads it, rounded to the profile's resolution. It is
brought up to the clock's now() each time it is looked at (`_progress`), so a driver
waiting for it sees the timing a real counter would give it, sped up.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from drivers.counter_profiles import TIMESTAMP_FORMATS, encode_values
from drivers.counter_profiles import nr3 as profile_nr3
from drivers.scpi import SCPI_NAN, parse_numbers
from sims.counter_state import CounterSettings, Kind, TwinAcquisition
from sims.scpi_server import ExecError, nr3


class CounterEngine(CounterSettings):
    """Measurements on the stand's zero mark, and their readings as the model replies."""

    def pending(self) -> bool:
        return self.acquisition is not None and not self._progress(self.acquisition)

    def _sees_edges(self, channel: int) -> bool:
        s = self.inputs[channel]
        low, high = self.signal_v
        return channel == self.signal_channel and not s.level_auto and low < s.level_v < high

    def _per_init(self) -> int:
        """Readings one INIT makes: SAMP:COUN x TRIG:COUN, at most the memory's."""
        return min(self.sample_count * self.trigger_count,
                   self.twin_profile.reading_memory or self.profile.max_count)

    def _start_source(self) -> str:
        """What starts a measurement after INIT: 'imm', 'sync' (the FOG's sync pulse at
        the external input it is wired to) or 'bus' (*TRG)."""
        if self.twin_profile.start_by_arming:
            # start arming (CNT-90 series Programmer's Handbook, :ARM:SOURce): the sync
            # is wired to the rear arming input E (EXT4); A and B carry the signals
            if self.arm_source in ("EXT1", "EXT2"):
                raise ExecError(-221, "Settings conflict;start arming on input A or B is "
                                      "not modelled by this twin")
            return "sync" if self.arm_source == "EXT4" else "imm"
        return {"EXT": "sync", "BUS": "bus"}.get(self.trigger_source, "imm")

    def _arm(self, kind: Kind, n: int) -> TwinAcquisition:
        ch = self.function_channel
        source = self._start_source()
        blind = self.take_fault("no-trigger") or not self._sees_edges(ch)
        t_arm = self.clock.now()
        t_start = t_arm
        if source == "sync":
            if self.sync is None:
                blind = True  # nothing is wired to the external trigger input
            else:
                t_start = self.sync.next_pulse_s(t_arm, self.rng)
        elif source == "bus":
            t_start = math.inf  # the first *TRG (53220A/53230A Prog. Ref. TRIG:SOUR BUS)
        bus = source == "bus"
        self.acquisition = TwinAcquisition(
            kind, n, ch, t_arm, self.timeout_s, blind, t_start,
            edge_to_edge=(kind == "timestamps" and self.first_value == "edge-to-edge"
                          and self.profile.timestamps == "keysight-tst"),
            invert=kind == "periods" and self.invert,
            walk=kind == "periods" and self.walk,
            gate_s=self.totalize_gate_s if kind == "totals" else self.aperture_s,
            back_to_back=self.back_to_back, bus=bus,
            blocks=max(1, n // max(self.sample_count, 1)) if bus else 1,
            waiting_trigger=bus)
        self.last_acquisition = self.acquisition  # kept after the client leaves (tests)
        return self.acquisition

    def _bus_trigger(self, a: Mapping[str, str]) -> None:
        """*TRG (IEEE 488.2 10.37): with TRIG:SOUR BUS, starts the readings of one trigger
        of a measurement INIT left waiting for it; anything else is -211 "Trigger
        ignored" (SCPI-99 vol. 2, 21.8.10), as is a trigger while a block is measured."""
        acq = self.acquisition
        if acq is None or not acq.bus or self.trigger_source != "BUS" \
                or self._progress(acq) or not acq.waiting_trigger:
            raise ExecError(-211, "Trigger ignored")
        now = self.clock.now()
        if not acq.triggers:
            acq.t_start_s = now
        acq.triggers.append(now)
        acq.waiting_trigger = False

    def _select(self, acq: TwinAcquisition
                ) -> tuple[np.ndarray, np.ndarray, float, bool]:
        """The edges the readings use so far; for each, the stand time it began to be
        waited for (the previous edge, or its block's start); that time for the next
        edge; and whether the next reading waits for a trigger (*TRG), not an edge.

        One block (IMM, EXT): the first edges after the start event. With TRIG:SOUR BUS
        each trigger's readings take the first edges after the later of that trigger
        and the end of the previous trigger's readings."""
        edges = acq.edges_s
        start0 = max(acq.t_start_s, acq.t_arm_s)
        if not acq.bus:
            chosen = edges[:acq.edges_needed]
            refs = np.concatenate([[start0], chosen[:-1]])[:chosen.size]
            return chosen, refs, float(chosen[-1]) if chosen.size else start0, False
        per = (acq.n // acq.blocks) * acq.edges_per_reading
        parts: list[np.ndarray] = []
        refs_parts: list[np.ndarray] = []
        prev_end, next_ref = -math.inf, start0
        for k in range(acq.blocks):
            if k >= len(acq.triggers):
                return _cat(parts), _cat(refs_parts), next_ref, True
            start = max(acq.triggers[k], prev_end)
            extra = acq.edges_needed - acq.n * acq.edges_per_reading if k == 0 else 0
            i = int(np.searchsorted(edges, start, side="right"))
            block = edges[i:i + per + extra]
            parts.append(block)
            refs_parts.append(np.concatenate([[start], block[:-1]])[:block.size])
            next_ref = float(block[-1]) if block.size else start
            if block.size < per + extra:
                break
            prev_end = next_ref
        return _cat(parts), _cat(refs_parts), next_ref, False

    def _progress(self, acq: TwinAcquisition) -> bool:
        """Bring the acquisition up to the clock's now; True once its readings exist."""
        if acq.values is not None:
            return True
        if acq.bus and not acq.triggers:
            return False  # INIT waits for *TRG
        now = self.clock.now()
        if not acq.blind and now > acq.t_start_s:
            self.axis.advance_to(now)
            acq.edges_s = self.axis.zero_marks(acq.t_start_s, now).t_edge_s
        if acq.kind == "totals":
            if now < acq.t_start_s + acq.n * acq.gate_s:
                return False
            acq.values = self._totals(acq, acq.n)
            return True
        if acq.walk:
            readings = self._walk(acq)
            if readings.size < acq.n:
                return False
            acq.values = readings[:acq.n]
            return True
        chosen, refs, next_ref, waiting = self._select(acq)
        acq.waiting_trigger = waiting
        # per reading (p. 459): the next stamp must come within the timeout of the last
        late = (np.flatnonzero(chosen - refs > acq.timeout_s) if acq.timeout_s is not None
                else np.empty(0, int))
        if late.size:
            chosen = chosen[:int(late[0])]
        timed_out = acq.timeout_s is not None and not waiting and (
            late.size > 0 or now >= next_ref + acq.timeout_s)
        if chosen.size < acq.edges_needed and not timed_out:
            return False
        values = self._values(acq, chosen)
        acq.values = np.concatenate([values, np.full(acq.n - values.size, SCPI_NAN)])
        return True

    def _values(self, acq: TwinAcquisition, chosen: np.ndarray) -> np.ndarray:
        """The readings the chosen edges make, as the instrument resolves them."""
        edges = self.profile.quantise(self._counter_time(acq, chosen))
        if acq.kind == "timestamps":
            if acq.edge_to_edge:
                if edges.size:
                    acq.stamp0_s = float(edges[0])
                elif acq.stamp0_s is None:
                    acq.stamp0_s = acq.t_start_s
                return edges[1:]
            return edges
        pairs = edges.size // 2
        values = edges[1:2 * pairs:2] - edges[0:2 * pairs:2]
        out: np.ndarray = 1.0 / values if acq.invert else values
        return out

    def _counter_time(self, acq: TwinAcquisition, t_s: np.ndarray) -> np.ndarray:
        """Stand times as this counter's time base reads them: every interval from the
        start event scaled by 1 + e (docs/method.md A1, the timebase; issue 58). With
        e = 0 the times are returned untouched, to the bit."""
        if self.timebase_offset_rel == 0.0:
            return t_s
        t0 = acq.t_start_s if math.isfinite(acq.t_start_s) else 0.0
        return t0 + (np.asarray(t_s, dtype=float) - t0) * (1.0 + self.timebase_offset_rel)

    def _totals(self, acq: TwinAcquisition, n: int) -> np.ndarray:
        """Totalize, timed (53220A/53230A CONFigure:TOTalize:TIMed): the edges counted in
        each of n gates, back to back from the start event (gate dead time not
        modelled)."""
        bounds = acq.t_start_s + acq.gate_s * np.arange(n + 1)
        return np.diff(np.searchsorted(acq.edges_s, bounds, side="left")).astype(float)

    def _walk(self, acq: TwinAcquisition) -> np.ndarray:
        """Gated readings from the edges so far: each from an edge to the first edge at
        least the gate time later (a reciprocal counter's measurement, CNT-90 series
        Programmer's Handbook, :ACQuisition:APERture), frequency = turns / time."""
        e = self.profile.quantise(self._counter_time(acq, acq.edges_s))
        out: list[float] = []
        i = 0
        while len(out) < acq.n and i < e.size:
            later = np.flatnonzero(e[i + 1:] - e[i] >= acq.gate_s)
            if not later.size:
                break
            j = i + 1 + int(later[0])
            span, turns = e[j] - e[i], j - i
            out.append(turns / span if acq.invert else span / turns)
            i = j if acq.back_to_back else j + 1
        return np.array(out)

    def _available(self, acq: TwinAcquisition) -> np.ndarray:
        """The readings that exist now (all of them once the acquisition is done): what
        R?, DATA:REM? and DATA:POIN? see of the reading memory."""
        if self._progress(acq):
            assert acq.values is not None
            return acq.values
        if acq.bus and not acq.triggers:
            return np.empty(0)
        if acq.kind == "totals":
            done = int((self.clock.now() - acq.t_start_s) // acq.gate_s)
            return self._totals(acq, max(0, min(done, acq.n)))
        if acq.walk:
            return self._walk(acq)
        chosen, _, _, _ = self._select(acq)
        return self._values(acq, chosen)

    def _readings(self, acq: TwinAcquisition | None) -> np.ndarray:
        if acq is None:
            raise ExecError(-230, "Data corrupt or stale")
        self.wait(lambda: self._progress(acq))
        assert acq.values is not None
        return acq.values

    def _encode(self, acq: TwinAcquisition, values: np.ndarray, first: int = 0) -> str:
        p = self.profile
        if acq.kind == "timestamps":
            fmt = TIMESTAMP_FORMATS[p.timestamps or ""]
            if fmt.name == "pendulum-stst" and not self.timestamp_info \
                    and self.ts_layout == "stst":
                return ",".join(str(i + 1) for i in range(values.size))
            nan = values >= 0.999 * SCPI_NAN
            stamp0 = acq.t_start_s if acq.stamp0_s is None else acq.stamp0_s
            digits = (self.ascii_digits - 1 if fmt.name == "keysight-tst"  # intervals
                      else self._time_digits(values[~nan] - stamp0))
            if fmt.name == "pendulum-stst" and not self.timestamp_info:
                # CNT-91 TSTAmp without FORM:TINF: the time stamps alone (unverified
                # layout, see the profile's notes)
                text = ",".join(profile_nr3(t - stamp0, digits, p.reply_exp_digits)
                                for t in np.where(nan, stamp0, values))
            else:
                text = fmt.encode(np.where(nan, stamp0, values), stamp0, digits,
                                  p.reply_exp_digits, first)
            return _nan_tail(text, int(nan.sum()))
        digits = self.ascii_digits - 1 if self.twin_profile.digits_from_format \
            else p.reply_digits
        return encode_values(values, digits, p.reply_exp_digits)

    def _reply(self, acq: TwinAcquisition, values: np.ndarray, first: int = 0, *,
               fetch: bool = False) -> str | bytes:
        """ASCII (FORM ASC), or FORM REAL: 8-byte doubles in a block (`_formatted`);
        `fetch`: the reply of FETC? or READ?."""
        return self._formatted(self._encode(acq, values, first), fetch=fetch)

    def _formatted(self, text: str, *, fetch: bool = False) -> str | bytes:
        """The readings as FORMat[:DATA] says. REAL on the 53230A (Programmer's
        Reference, FORMat[:DATA]): IEEE 754 doubles, byte order FORM:BORD (NORMal:
        big-endian); FETC? and READ? answer an indefinite-length block, `#0<bytes>`
        then the terminator, as the FORMat:DATA page shows; R? (and DATA:REM?) a
        definite-length one. REAL on the CNT-91 (CNT-90 series Programmer's Handbook,
        :FORMat[:DATA]): big-endian doubles in a definite-length block."""
        if self.data_format != "REAL":
            return text
        numbers = parse_numbers(text)
        as_53230a = self.twin_profile.real_as_53230a
        big = not as_53230a or self.byte_order == "NORM"
        data = numbers.astype(">f8" if big else "<f8").tobytes()
        return b"#0" + data if as_53230a and fetch else block(data)

    def _time_digits(self, t_s: np.ndarray) -> int:
        """Digits after the point that carry the resolution (up to 17 significant):
        times on an axis of hours need more than the 15 a period needs."""
        finite = np.abs(t_s[t_s < SCPI_NAN])
        t_max = float(finite.max()) if finite.size else 1.0
        span = math.floor(math.log10(max(t_max, 1e-300))) \
            - math.floor(math.log10(self.profile.resolution_s))
        return int(min(16, max(self.profile.reply_digits, span + 1)))


def _cat(parts: list[np.ndarray]) -> np.ndarray:
    return np.concatenate(parts) if parts else np.empty(0)


def _nan_tail(text: str, n_nan: int) -> str:
    """Replace the last n values of a reply by 9.91E37 (readings that timed out)."""
    if n_nan == 0:
        return text
    parts = text.split(",")
    parts[len(parts) - n_nan:] = [nr3(SCPI_NAN)] * n_nan
    return ",".join(parts)


def block(data: bytes) -> bytes:
    """IEEE 488.2 definite-length arbitrary block: `#<digits><length><data>`."""
    length = str(len(data))
    return f"#{len(length)}{length}".encode("ascii") + data
