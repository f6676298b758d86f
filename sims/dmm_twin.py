"""The digitizing DMM's twin: samples the platform's angle sensor over real SCPI (the
words of drivers/dmm.py, imported, not copied).

After INIT it waits for its trigger: with TRIG:SOUR EXT, an edge on the wire from the
pulse generator's trigger output (`external_trigger`, called with the edge times; the
slope setting picks the edge). The first sample starts `trigger_latency_s` plus the
trigger delay after that edge, then one every SAMP:TIM; each reading is the mean of
U(t) over its aperture (`GyroPlatform.sample_u` with the aperture), so it belongs to the
aperture's middle, as on a real integrating DMM. A reading beyond 1.2 x range is
+/-9.9E37 (overload). The readings exist once the stand clock has passed the last
aperture; FETC? waits for that. STAT:OPER:COND? has bit 5 while waiting for the
trigger and bit 4 while measuring.

Faults (`inject`): 'no-trigger' (the next record never sees its trigger: a loose wire),
plus the base's 'garbage' and 'drop' on FETC?.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from drivers.dmm import DmmProfile, get_profile
from sims.platform import GyroPlatform
from sims.scpi_server import (
    ExecError,
    ScpiServer,
    bool_param,
    bool_reply,
    count_param,
    enum_param,
    nr3,
    number_param,
    ranged_param,
)

MEASURING_BIT = 0x10


@dataclass
class Record:
    """One INIT's record: when it was triggered and, once read, its readings."""

    count: int
    interval_s: float
    aperture_s: float
    delay_s: float
    blind: bool = False
    t_first_s: float | None = None
    values: np.ndarray | None = None

    @property
    def t_end_s(self) -> float | None:
        if self.t_first_s is None:
            return None
        return self.t_first_s + (self.count - 1) * self.interval_s + self.aperture_s


class DmmTwin(ScpiServer):
    """A DMM of `model` on the angle sensor of `gyro` of the platform."""

    fault_names = ScpiServer.fault_names | {"no-trigger"}
    error_code_format = "{:+d}"  # `+0,"No error"`, as Keysight's manuals print it

    def __init__(self, platform: GyroPlatform, gyro: str, model: str = "keysight-34465a",
                 host: str = "127.0.0.1", port: int = 0, *,
                 trigger_latency_s: float = 0.0, gain_error_rel: float = 0.0,
                 offset_error_v: float = 0.0) -> None:
        self.profile: DmmProfile = get_profile(model)
        super().__init__(idn=self.profile.idn, host=host, port=port)
        if platform.clock is None:
            raise ValueError("the platform must sit on a simulated stand (for its clock)")
        if gyro not in platform.truth.gyros:
            raise ValueError(f"the platform has no gyro {gyro!r}")
        self.platform = platform
        self.gyro = gyro
        self.clock = platform.clock
        self.trigger_latency_s = float(trigger_latency_s)
        #: the DMM's own errors, unknown to the lab (issue 58): reading = (1 + g) U + o
        self.gain_error_rel = float(gain_error_rel)
        self.offset_error_v = float(offset_error_v)
        self.record: Record | None = None
        self.reset()
        self._route_words()

    def reset(self) -> None:
        self.range_v = 10.0
        self.aperture_s = 0.2          # 10 PLC at 50 Hz
        self.autozero = True
        self.impedance_auto = False
        self.trigger_source = "IMM"
        self.trigger_slope = "NEG"
        self.trigger_delay_s = 0.0
        self.trigger_count = 1
        self.sample_source = "IMM"
        self.sample_interval_s = 1.0
        self.questionable = 0
        self.sample_count = 1
        self.record = None

    def session_ended(self) -> None:
        self.record = None

    def pending(self) -> bool:
        r = self.record
        if r is None or r.values is not None:
            return False
        return r.t_end_s is None or self.clock.now() < r.t_end_s

    # -- routes -----------------------------------------------------------------------------
    def _route_words(self) -> None:
        self.route_words(self.profile.words, {
            "configure_dcv": (self._configure, None),
            "range": (self._range, lambda a: nr3(self.range_v)),
            "aperture": (self._aperture, lambda a: nr3(self.aperture_s)),
            "autozero": (lambda a: setattr(self, "autozero", bool_param(a["state"])),
                         lambda a: bool_reply(self.autozero)),
            "impedance_auto": (lambda a: setattr(self, "impedance_auto", bool_param(a["state"])),
                               lambda a: bool_reply(self.impedance_auto)),
            "trigger_source": (lambda a: setattr(self, "trigger_source", enum_param(
                a["source"], ("IMMediate", "EXTernal", "BUS", "INTernal"))),
                               lambda a: self.trigger_source),
            "trigger_slope": (lambda a: setattr(self, "trigger_slope", enum_param(
                a["slope"], ("POSitive", "NEGative"))), lambda a: self.trigger_slope),
            "trigger_delay": (self._delay, lambda a: nr3(self.trigger_delay_s)),
            "trigger_count": (self._trigger_count, lambda a: f"{self.trigger_count}"),
            "sample_source": (lambda a: setattr(self, "sample_source", enum_param(
                a["source"], ("IMMediate", "TIMer"))), lambda a: self.sample_source),
            "sample_timer_limit": (None, self._timer_limit),
            "questionable_event": (None, self._questionable),
            "sample_timer": (self._timer, lambda a: nr3(self.sample_interval_s)),
            "sample_count": (self._count, lambda a: f"{self.sample_count}"),
            "format_data": (self._format, lambda a: "ASC"),
            "abort": (lambda a: setattr(self, "record", None), None),
            "initiate": (self._initiate, None),
            "operation_condition": (None, self._condition),
            "fetch": (None, self._fetch, True),
        })

    def _configure(self, a: Mapping[str, str]) -> None:
        self.reset_measurement()
        self._range({"range_v": a["range_v"]})

    def reset_measurement(self) -> None:
        """CONF sets the measurement's defaults (one immediate sample, auto-zero on)."""
        self.autozero = True
        self.trigger_source, self.trigger_count, self.trigger_delay_s = "IMM", 1, 0.0
        self.sample_source, self.sample_count = "IMM", 1
        self.record = None

    def _range(self, a: Mapping[str, str]) -> None:
        r = number_param(a["range_v"], {"MIN": 0.1, "MAX": 1000.0, "DEF": 10.0, "AUTO": 10.0})
        match = [x for x in self.profile.ranges_v if x >= r * (1 - 1e-9)]
        if not match:
            raise ExecError(-222, "Data out of range")
        self.range_v = match[0]

    def _aperture(self, a: Mapping[str, str]) -> None:
        self.aperture_s = ranged_param(a["aperture_s"], *self.profile.aperture_range_s,
                                       default=0.1)

    def _delay(self, a: Mapping[str, str]) -> None:
        self.trigger_delay_s = ranged_param(a["delay_s"], 0.0,
                                            self.profile.max_trigger_delay_s, default=0.0)

    def _trigger_count(self, a: Mapping[str, str]) -> None:
        n = int(number_param(a["count"], {"MIN": 1, "DEF": 1}))
        if n != 1:
            raise ExecError(-221, "Settings conflict")  # the twin records one burst per INIT
        self.trigger_count = n

    def _timer(self, a: Mapping[str, str]) -> None:
        # "the MIN value is not enforced, and you can specify an <interval> less than MIN
        # (even zero)" (34410A/11A User's Guide, SAMPle:TIMer remarks; the Truevolt guide
        # says MIN is measurement dependent): any interval down to 0 is taken
        self.sample_interval_s = ranged_param(a["interval_s"], 0.0, 3600.0, default=1.0)

    def sampling_time_s(self) -> float:
        """How long one sample takes in this set-up: the aperture plus the overhead, twice
        over with auto-zero on (a zero reading after each one). The model's guess of the
        measurement-dependent MIN (the manual gives no formula)."""
        one = self.aperture_s + self.profile.interval_overhead_s
        return 2 * one if self.autozero else one

    def _timer_limit(self, a: Mapping[str, str]) -> str:
        which = a["limit"].upper()
        if which.startswith("MIN"):
            return nr3(max(self.sampling_time_s(), self.profile.min_interval_s))
        if which.startswith("MAX"):
            return nr3(3600.0)
        if which.startswith("DEF"):
            return nr3(1.0)
        raise ExecError(-224, "Illegal parameter value")

    def _questionable(self, a: Mapping[str, str]) -> str:
        with self._lock:
            value, self.questionable = self.questionable, 0  # read-and-clear (event)
        return f"+{value}"

    def _count(self, a: Mapping[str, str]) -> None:
        self.sample_count = count_param(a["count"], self.profile.max_readings)

    def _format(self, a: Mapping[str, str]) -> None:
        if enum_param(a["format"], ("ASCii", "REAL")) != "ASC":
            raise ExecError(-224, "Illegal parameter value")  # the twin speaks ASCII only

    # -- the record -----------------------------------------------------------------------
    def _initiate(self, a: Mapping[str, str]) -> None:
        if self.pending():
            raise ExecError(-213, "Init ignored")
        timed = self.sample_source == "TIM"
        interval = self.sample_interval_s if timed else self.aperture_s + 1e-3
        if timed and interval < self.sampling_time_s():
            # not refused: the samples come as fast as they can, off the timer's grid, and
            # Questionable Data bit 2 says so (STATus:QUEStionable, "Sample Timing
            # Violation ... Sample timing may not be valid")
            interval = self.sampling_time_s()
            self.questionable |= self.profile.sample_timing_violation_bit
        rec = Record(self.sample_count, interval, self.aperture_s, self.trigger_delay_s,
                     blind=self.take_fault("no-trigger"))
        with self._lock:
            self.record = rec
            if self.trigger_source == "IMM":
                self._start(rec, self.clock.now())

    def _start(self, rec: Record, t_edge: float) -> None:
        rec.t_first_s = t_edge + self.trigger_latency_s + rec.delay_s

    def external_trigger(self, rise_s: float, fall_s: float) -> None:
        """An edge on Ext Trig (the wire from the generator's trigger output)."""
        with self._lock:
            rec = self.record
            if rec is None or rec.t_first_s is not None or rec.blind:
                return
            if self.trigger_source != "EXT":
                return
            self._start(rec, rise_s if self.trigger_slope == "POS" else fall_s)

    def _condition(self, a: Mapping[str, str]) -> str:
        with self._lock:
            rec = self.record
            if rec is None or rec.values is not None:
                return "+0"
            if rec.t_first_s is None:
                return f"+{self.profile.waiting_for_trigger_bit}"
            return f"+{MEASURING_BIT}" if self.pending() else "+0"

    def _fetch(self, a: Mapping[str, str]) -> str:
        rec = self.record
        if rec is None:
            raise ExecError(-230, "Data corrupt or stale")
        self.wait(lambda: not self.pending())
        if rec.values is None:
            assert rec.t_first_s is not None
            t = rec.t_first_s + np.arange(rec.count) * rec.interval_s
            u = self._reading(self.platform.sample_u(self.gyro, t, rec.aperture_s))
            over = np.abs(u) > 1.2 * self.range_v
            rec.values = np.where(over, np.copysign(self.profile.overload_v, u), u)
        return ",".join(nr3(v) for v in rec.values)

    def _reading(self, u_v: np.ndarray) -> np.ndarray:
        """What this DMM reads for the true voltages: (1 + g) U + o (issue 58; docs/method.md
        B, "The drift kind's instrument corrections"). With g = o = 0 the voltages are
        returned untouched, to the bit."""
        if self.gain_error_rel == 0.0 and self.offset_error_v == 0.0:
            return u_v
        return u_v * (1.0 + self.gain_error_rel) + self.offset_error_v
