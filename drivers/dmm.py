"""The angle-sensor readout of the drift-pulse method (docs/method.md B): a SCPI digitizing DMM.

A Keysight 34465A (DIG option) records U(t) of the command angle sensor in step with the
pulses: DC volts on a fixed range, a fixed aperture, auto-zero off (with it on, every
other reading would be a zero measurement and the interval would not hold), N samples on
the sample timer after one external trigger (the pulse generator's trigger output).

    ABOR; CONF:VOLT:DC r; VOLT:RANG r; VOLT:APER a; VOLT:ZERO:AUTO OFF; VOLT:IMP:AUTO ON;
    TRIG:SOUR EXT; TRIG:SLOP POS; TRIG:DEL d; TRIG:COUN 1;
    SAMP:SOUR TIM; SAMP:TIM dt; SAMP:COUN n; FORM ASC                  -- configure()
    INIT; *OPC; STAT:OPER:COND? until "waiting for trigger"            -- arm()
    *ESR? until operation complete; FETC?                              -- fetch()

Timing: the first sample starts the trigger delay after the trigger edge, then one every
interval. An integrating reading is the mean over its aperture, so it belongs to the
aperture's middle: sample k stands for `delay + k * dt + aperture / 2` after the edge
(`DigitizerSetup.sample_time_s`). That half aperture is a real offset against the pulse
edges (docs/method.md B's half-sample pitfall in another guise); the procedure sets the
trigger delay so the samples' middles land on the edges.

Waits. On hardware and on a paced simulated stand they are real seconds scaled by the
clock's speed (a virtual stand runs faster). On a stepped clock (the twins' co-simulation,
drivers/clock.py) the same polls are spaced and bounded in clock time: the clock's time
passes only while the bench waits, so the armed check and the wait for the record's end
let it pass, and when each poll happens depends on the data alone, never on the host's
load.
"""

from __future__ import annotations

import contextlib
import math
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING

from drivers.clock import Clock, real_budget_s, stepped
from drivers.scpi import (
    ABORT,
    CLS,
    ESR_OPC,
    ESR_Q,
    INIT,
    OPC,
    Command,
    ErrorKinds,
    InstrumentError,
    RawCallback,
    parse_numbers,
)
from drivers.scpi_profile import InstrumentProfile, ProfiledInstrument, lookup_profile
from drivers.transport import Transport
from drivers.waits import poll_time

if TYPE_CHECKING:
    import numpy as np

DMM_ERRORS = ErrorKinds.family("Dmm", "the digitizer", __name__)
DmmError, DmmCommandError, DmmTimeout, DmmReplyError, DmmConnectionError = DMM_ERRORS


# the family is declared at run time (ErrorKinds.family): mypy cannot see its classes
class DmmOverload(DmmError):  # type: ignore[misc,valid-type]
    """A reading beyond the range (the DMM answers +/-9.9E37)."""


@dataclass(frozen=True)
class DmmWords:
    """The SCPI words of a digitizing DMM model, by role."""

    configure_dcv: Command = Command("CONFigure:VOLTage[:DC]", "{range_v}")
    range: Command = Command("[SENSe:]VOLTage[:DC]:RANGe", "{range_v}")
    aperture: Command = Command("[SENSe:]VOLTage[:DC]:APERture", "{aperture_s}")
    autozero: Command = Command("[SENSe:]VOLTage[:DC]:ZERO:AUTO", "{state}")
    impedance_auto: Command = Command("[SENSe:]VOLTage[:DC]:IMPedance:AUTO", "{state}",
                                      doc="ON: >10 Gohm input on the 10 V range and below")
    trigger_source: Command = Command("TRIGger:SOURce", "{source}", doc="EXTernal")
    trigger_slope: Command = Command("TRIGger:SLOPe", "{slope}")
    trigger_delay: Command = Command("TRIGger:DELay", "{delay_s}")
    trigger_count: Command = Command("TRIGger:COUNt", "{count}")
    sample_source: Command = Command("SAMPle:SOURce", "{source}", doc="TIMer")
    sample_timer: Command = Command("SAMPle:TIMer", "{interval_s}")
    sample_timer_limit: Command = Command(
        "SAMPle:TIMer?", "{limit}", doc="MIN: the measurement-dependent shortest interval")
    questionable_event: Command = Command(
        "STATus:QUEStionable[:EVENt]?", doc="read-and-clear; bit 2: sample timing violation")
    sample_count: Command = Command("SAMPle:COUNt", "{count}")
    format_data: Command = Command("FORMat[:DATA]", "{format}")
    operation_condition: Command = Command("STATus:OPERation:CONDition?")
    abort: Command = ABORT
    initiate: Command = INIT
    fetch: Command = Command("FETCh?", doc="the readings of the last measurement")


@dataclass(frozen=True, kw_only=True)
class DmmProfile(InstrumentProfile):
    words: DmmWords
    ranges_v: tuple[float, ...]
    aperture_range_s: tuple[float, float]
    min_interval_s: float
    interval_overhead_s: float     # the timer interval must exceed the aperture by this
    max_readings: int
    max_trigger_delay_s: float
    waiting_for_trigger_bit: int   # STAT:OPER:COND? bit set while armed
    overload_v: float = 9.9e37
    #: STAT:QUES bit: "Sample Timing Violation ... Sample timing may not be valid"
    sample_timing_violation_bit: int = 0x04


KEYSIGHT_34465A = DmmProfile(
    model="keysight-34465a",
    maker="Keysight",
    description="Truevolt 34465A 6.5-digit DMM with the DIG (digitizing) option",
    words=DmmWords(),
    idn_pattern=r"3446[05]A",
    ranges_v=(0.1, 1.0, 10.0, 100.0, 1000.0),
    aperture_range_s=(20e-6, 1.0),
    min_interval_s=20e-6,          # 50 kSa/s with the DIG option
    interval_overhead_s=10e-6,
    max_readings=50_000,           # reading memory without the MEM option (2 M with it)
    max_trigger_delay_s=3600.0,
    waiting_for_trigger_bit=0x20,
    manual=("Keysight Truevolt Series Operating and Service Guide, SCPI Programming "
            "Reference: SAMPle:TIMer (MIN measurement dependent; SAMPle:TIMer? MIN). "
            "Unverified for the 34465A itself, taken from the 34410A/11A User's Guide: MIN "
            "not enforced; STATus:QUEStionable bit 2 'Sample Timing Violation'"),
    notes=("Words as the 34465A Programming Reference spells them (SAMP:SOUR TIM, "
           "SAMP:TIM, SAMP:COUN, TRIG:SOUR EXT, VOLT:APER, VOLT:ZERO:AUTO). Unsure: the "
           "minimum interval over the aperture (10 us assumed) and STAT:OPER:COND? bit 5 "
           "as 'waiting for trigger' (used only to know the DMM is armed before the "
           "generator fires; if wrong, arm() times out by name on the first connection)."),
    idn="Keysight Technologies,34465A,MY00000000,A.03.01-03.15-03.01-00.52-03-02",
)

PROFILES: dict[str, DmmProfile] = {p.model: p for p in (KEYSIGHT_34465A,)}


def get_profile(model: str) -> DmmProfile:
    return lookup_profile(PROFILES, model, "DMM")


@dataclass(frozen=True)
class DigitizerSetup:
    """A configured record: how many samples, how far apart, and when each one is."""

    range_v: float
    aperture_s: float
    interval_s: float
    count: int
    trigger_delay_s: float
    slope: str

    @property
    def duration_s(self) -> float:
        return self.trigger_delay_s + (self.count - 1) * self.interval_s + self.aperture_s

    def sample_time_s(self, k: np.ndarray | int) -> np.ndarray:
        """Sample k's time after the trigger edge: the middle of its aperture."""
        import numpy as np
        return self.trigger_delay_s + np.asarray(k) * self.interval_s + 0.5 * self.aperture_s


#: the wait for a record may run this fraction over its nominal length
SPAN_SLACK_REL = 0.25
#: between looks at STAT:OPER:COND? while the DMM arms (s: real, or clock on a stepped clock)
ARM_POLL_S = 0.005


class Digitizer(ProfiledInstrument[DmmProfile]):
    """A SCPI DMM recording one triggered burst of samples at a fixed interval."""

    error_kinds = DMM_ERRORS
    words: DmmWords
    kind, stand_key, profiles = "DMM", "dmm", PROFILES

    def __init__(self, resource: str, profile: DmmProfile, clock: Clock, *,
                 raw: RawCallback | None = None, command_timeout_s: float = 2.0,
                 timeout_margin_s: float = 5.0, visa_library: str = "@py",
                 transport: Transport | None = None) -> None:
        self.timeout_margin_s = float(timeout_margin_s)
        self.recovery_commands = (profile.words.abort, CLS)
        self.setup: DigitizerSetup | None = None
        #: settings the record depends on, as the DMM reads them back
        self.readback: dict[str, float | int] = {}
        self._armed_real_s: float | None = None
        self._armed_at_s = 0.0   # the clock's time at arm()
        super().__init__(resource, profile, clock, raw=raw,
                         command_timeout_s=command_timeout_s, visa_library=visa_library,
                         transport=transport)

    def configure(self, range_v: float, aperture_s: float, interval_s: float, count: int,
                  trigger_delay_s: float = 0.0, slope: str = "POS") -> DigitizerSetup:
        """Set up one externally triggered record of `count` samples `interval_s` apart."""
        p = self.profile
        problems = []
        if not any(math.isclose(range_v, r) for r in p.ranges_v):
            problems.append(f"range {range_v:g} V (one of {', '.join(f'{r:g}' for r in p.ranges_v)})")
        if not p.aperture_range_s[0] <= aperture_s <= p.aperture_range_s[1]:
            problems.append(f"aperture {aperture_s:g} s (range {p.aperture_range_s[0]:g} .. "
                            f"{p.aperture_range_s[1]:g} s)")
        if interval_s < max(p.min_interval_s, aperture_s + p.interval_overhead_s):
            problems.append(f"interval {interval_s:g} s is shorter than the aperture plus "
                            f"{p.interval_overhead_s:g} s (or the model's minimum "
                            f"{p.min_interval_s:g} s)")
        if not 1 <= count <= p.max_readings:
            problems.append(f"{count} samples (the reading memory holds {p.max_readings})")
        if not 0.0 <= trigger_delay_s <= p.max_trigger_delay_s:
            problems.append(f"trigger delay {trigger_delay_s:g} s")
        slope_u = slope.upper()[:3]
        if slope_u not in ("POS", "NEG"):
            problems.append(f"slope {slope!r} (POS or NEG)")
        if problems:
            raise DmmError(f"{self.name}: configure(): " + "; ".join(problems))
        w = self.words
        with self.recovering():
            self.send(w.abort)
            self.send(w.configure_dcv, range_v=range_v)
            self.send(w.range, range_v=range_v)
            self.send(w.aperture, aperture_s=aperture_s)
            self.send(w.autozero, state=False)
            self.send(w.impedance_auto, state=True)
            self.send(w.trigger_source, source="EXT")
            self.send(w.trigger_slope, slope=slope_u)
            self.send(w.trigger_delay, delay_s=trigger_delay_s)
            self.send(w.trigger_count, count=1)
            self.send(w.sample_source, source="TIM")
            self.send(w.sample_timer, interval_s=interval_s)
            self.send(w.sample_count, count=int(count))
            self.send(w.format_data, format="ASC")
            # the shortest interval is measurement dependent and not enforced (the
            # manual's SAMPle:TIMer remarks): read it for this set-up, and refuse below it
            text = w.sample_timer_limit.text(limit="MIN")
            minimum = self._float_reply(text, self.query(text))
            self.readback["dmm.sample_timer_min_s"] = minimum
            if interval_s < minimum:
                raise DmmError(f"{self.name}: sample interval {interval_s:g} s is below "
                               f"SAMP:TIM? MIN = {minimum:g} s for this range, aperture and "
                               "auto-zero: the samples would fall off their grid",
                               command=text)
            self.query(w.questionable_event.text())  # read-and-clear before the record
        self.setup = DigitizerSetup(float(range_v), float(aperture_s), float(interval_s),
                                    int(count), float(trigger_delay_s), slope_u)
        return self.setup

    def arm(self) -> None:
        """INIT and wait until the DMM waits for its trigger (bounded)."""
        if self.setup is None:
            raise DmmError(f"{self.name}: arm() before configure()")
        w = self.words
        bit = self.profile.waiting_for_trigger_bit
        with self.recovering():
            self.send(w.initiate)
            self.write(OPC.text(), check=False)
            now, sleep = poll_time(self.clock)   # co-simulation: on clock time
            start = now()
            while True:
                text = w.operation_condition.text()
                cond = self._int_reply(text, self.query(text))
                if cond & bit:
                    break
                if now() - start > self.command_timeout_s:
                    raise DmmTimeout(f"{self.name}: not waiting for its trigger "
                                     f"{self.command_timeout_s:g} s after INIT "
                                     f"({text} = {cond})", command=w.initiate.text())
                sleep(ARM_POLL_S)
        self._armed_real_s = time.monotonic()
        self._armed_at_s = self.clock.now()

    def fetch(self) -> np.ndarray:
        """Wait for the record (bounded by its length: in clock time on a stepped clock, else
        in real time at the clock's speed) and read it."""
        import numpy as np
        if self.setup is None or self._armed_real_s is None:
            raise DmmError(f"{self.name}: fetch() without arm()")
        setup, armed, armed_at_s = self.setup, self._armed_real_s, self._armed_at_s
        self._armed_real_s = None
        span_s = setup.duration_s * (1.0 + SPAN_SLACK_REL)
        now, sleep = poll_time(self.clock)
        if stepped(self.clock):
            # co-simulation: the first look, the polls and the limit are in clock time
            # (a stepped clock runs no slower than real time: the same margin holds)
            start, unit, span = armed_at_s, "stand time", span_s
            limit_s = span_s + self.timeout_margin_s
        else:
            start, unit, span = armed, "real", span_s / self.clock.speed
            limit_s = real_budget_s(self.clock, span_s) + self.timeout_margin_s
        first_s, poll_s = 0.5 * span, min(max(span / 50.0, 0.005), 0.5)
        with self.recovering():
            sleep(max(start + first_s - now(), 0.0))
            while True:
                esr = self._int_reply(ESR_Q.text(), self.query(ESR_Q.text()))
                if esr & 0x3C:
                    self.check_errors(f"the record (ESR {esr})")
                if esr & ESR_OPC:
                    break
                if now() - start > limit_s:
                    raise DmmTimeout(
                        f"{self.name}: {setup.count} samples not complete within "
                        f"{limit_s:.3g} s ({unit}): did the trigger reach the DMM's "
                        f"Ext Trig input?", command=self.words.initiate.text())
                sleep(poll_s)
            text = self.words.fetch.text()
            reply = self.query(text, timeout_s=self.command_timeout_s + setup.count * 20 / 1e5)
            try:
                values = parse_numbers(reply)
            except ValueError as e:
                raise DmmReplyError(f"{self.name}: the reply to {text!r} is not a list of "
                                    f"numbers ({e}): {reply[:80]!r}", command=text,
                                    reply=reply.encode()[:200]) from e
            if values.size != setup.count:
                raise DmmReplyError(f"{self.name}: {text!r} returned {values.size} readings, "
                                    f"expected {setup.count}", command=text)
            text = self.words.questionable_event.text()
            ques = self._int_reply(text, self.query(text))
            self.readback["dmm.questionable_event"] = ques
            if ques & self.profile.sample_timing_violation_bit:
                raise DmmError(f"{self.name}: STAT:QUES bit 2 (sample timing violation) is "
                               f"set after the record: the samples are not on their "
                               f"{setup.interval_s:g} s grid; lengthen the interval or shorten "
                               "the aperture", command=text)
        over = np.abs(values) >= 0.999 * self.profile.overload_v
        if over.any():
            raise DmmOverload(f"{self.name}: {int(over.sum())} reading(s) beyond the "
                              f"{setup.range_v:g} V range (first at sample "
                              f"{int(np.argmax(over))}): the angle sensor's excursion is too "
                              f"large for the range, or the pulse amplitude too high",
                              command=text)
        return values

    def _float_reply(self, text: str, reply: str) -> float:
        try:
            return float(reply)
        except ValueError as e:
            raise DmmReplyError(f"{self.name}: {text!r} replied {reply!r}", command=text,
                                reply=reply.encode()) from e

    def _int_reply(self, text: str, reply: str) -> int:
        try:
            return int(float(reply))
        except ValueError as e:
            raise DmmReplyError(f"{self.name}: {text!r} replied {reply!r}", command=text,
                                reply=reply.encode()) from e

    def close(self) -> None:
        """Abort a record still armed (best effort), then close the link."""
        if self._armed_real_s is not None and self.is_open:
            with contextlib.suppress(InstrumentError):
                self.write(self.words.abort.text(), check=False)
        self._armed_real_s = None
        super().close()
