"""The pulse generator of the drift-pulse method (docs/method.md B): a SCPI arbitrary
waveform generator playing the +/- pulse pair once per bus trigger.

The pair is uploaded as an arbitrary waveform (values in [-1, 1]) and played as a burst
of one cycle on `*TRG`; the generator's trigger output, wired to the digitizer's
external trigger input, starts the angle-sensor record in step with it. Sequence:

    OUTP<n> OFF; SOUR<n>:DATA:VOL:CLE; SOUR<n>:DATA:ARB name,v1,..; SOUR<n>:FUNC:ARB "name";
    SOUR<n>:FUNC ARB; ..:SRAT fs; ..:FILT STEP; OUTP<n>:LOAD INF; VOLT:OFFS 0; VOLT vpp;
    BURS:MODE TRIG; BURS:NCYC 1; BURS:STAT ON; TRIG<n>:SOUR BUS; TRIG<n>:DEL 0;
    OUTP:TRIG:SOUR CH<n>; OUTP:TRIG:SLOP POS; OUTP:TRIG ON; OUTP<n> ON     -- load_pair()
    *TRG                                                                     -- trigger()

Why these settings. STEP filter: the output holds each point (zero-order hold), so a
rectangular pulse has square edges and a midpoint-sampled staircase stays symmetric in
time (procedures/drift_pulse/analysis.py, `PulseShape.pair_points`); the default smoothing
filter would round the edges and delay them. LOAD INF: the torque-sensor current
amplifier's input is high-impedance; with the default 50 ohm setting the generator would
put out twice the voltage asked. The waveform starts and ends with zeros, so the output
idles at 0 V between bursts whatever the model's idle rule, and the record begins before
the first edge.

Where we were unsure of the real syntax the profile's `notes` says so; a wrong word is
rejected by the instrument with -113 at `load_pair()`, by name.

Waits: none beyond each command's checked reply. `*TRG` starts the burst and returns; the
record's wait is the digitizer's (drivers/dmm.py), so on a stepped clock the burst starts
at the clock's time when the bench triggers it, fixed by the data.
"""

from __future__ import annotations

import contextlib
import re
from dataclasses import dataclass
from typing import TYPE_CHECKING

from drivers.clock import Clock
from drivers.scpi import Command, ErrorKinds, InstrumentError, ParameterError, RawCallback
from drivers.scpi_profile import InstrumentProfile, ProfiledInstrument, lookup_profile

if TYPE_CHECKING:
    import numpy as np

AWG_ERRORS = ErrorKinds.family("Awg", "the waveform generator", __name__)
AwgError, AwgCommandError, AwgTimeout, AwgReplyError, AwgConnectionError = AWG_ERRORS


@dataclass(frozen=True)
class ArbDataCommand(Command):
    """`DATA:ARB name, v1, v2, ...`: a list parameter, which a plain template cannot parse."""

    def parse_params(self, text: str) -> dict[str, str]:
        parts = [p.strip() for p in text.split(",")]
        if len(parts) < 2 or not parts[0]:
            raise ParameterError(-109, "Missing parameter")
        if any(not p for p in parts[1:]):
            raise ParameterError(-102, "Syntax error")
        return {"name": parts[0], "values": ",".join(parts[1:])}


@dataclass(frozen=True)
class AwgWords:
    """The SCPI words of a waveform generator model, by role."""

    clear_volatile: Command = Command("SOURce{channel}:DATA:VOLatile:CLEar",
                                      doc="delete the arbitrary waveforms in volatile memory")
    arb_data: Command = ArbDataCommand("SOURce{channel}:DATA:ARBitrary", "{name},{values}",
                                       doc="upload a waveform, values in [-1, 1]")
    arb_select: Command = Command("SOURce{channel}:FUNCtion:ARBitrary", '"{name}"')
    function: Command = Command("SOURce{channel}:FUNCtion", "{function}", doc="ARB")
    sample_rate: Command = Command("SOURce{channel}:FUNCtion:ARBitrary:SRATe", "{rate_hz}")
    arb_filter: Command = Command("SOURce{channel}:FUNCtion:ARBitrary:FILTer", "{filter}",
                                  doc="NORMal, STEP or OFF")
    amplitude: Command = Command("SOURce{channel}:VOLTage", "{vpp}", doc="peak to peak, V")
    offset: Command = Command("SOURce{channel}:VOLTage:OFFSet", "{offset_v}")
    load: Command = Command("OUTPut{channel}:LOAD", "{ohm}", doc="50 or INFinity")
    burst_mode: Command = Command("SOURce{channel}:BURSt:MODE", "{mode}", doc="TRIGgered")
    burst_cycles: Command = Command("SOURce{channel}:BURSt:NCYCles", "{cycles}")
    burst_state: Command = Command("SOURce{channel}:BURSt:STATe", "{state}")
    trigger_source: Command = Command("TRIGger{channel}:SOURce", "{source}",
                                      doc="IMMediate, EXTernal, TIMer or BUS")
    trigger_delay: Command = Command("TRIGger{channel}:DELay", "{delay_s}")
    output: Command = Command("OUTPut{channel}", "{state}")
    trigger_out: Command = Command("OUTPut:TRIGger", "{state}", doc="the rear trigger output")
    trigger_out_source: Command = Command("OUTPut:TRIGger:SOURce", "{source}", doc="CH1, CH2")
    trigger_out_slope: Command = Command("OUTPut:TRIGger:SLOPe", "{slope}")
    bus_trigger: Command = Command("*TRG", doc="IEEE 488.2 bus trigger")


@dataclass(frozen=True, kw_only=True)
class AwgProfile(InstrumentProfile):
    """One generator model: words, limits, and what its twin answers to *IDN?."""

    words: AwgWords
    channels: tuple[int, ...]
    max_points: int
    min_points: int
    sample_rate_range_hz: tuple[float, float]
    amplitude_range_vpp: tuple[float, float]      # into a high-impedance load
    dac_bits: int


KEYSIGHT_33500B = AwgProfile(
    model="keysight-33500b",
    maker="Keysight",
    description="33500B series (e.g. 33522B, two channels) waveform generator",
    words=AwgWords(),
    idn_pattern=r"335\d\dB",
    channels=(1, 2),
    max_points=1_000_000,                 # standard memory; 16 M with the MEM option
    min_points=8,
    sample_rate_range_hz=(1e-6, 160e6),
    amplitude_range_vpp=(2e-3, 20.0),
    dac_bits=16,
    notes=("Words as the 33500B Programming Reference spells them (SOURce<n>:DATA:ARB, "
           "FUNC:ARB:SRAT, FUNC:ARB:FILT, BURS:*, TRIG<n>:SOUR BUS, *TRG, OUTP:TRIG). "
           "Unsure: whether FUNC:ARB wants the name quoted (we quote it) and whether the "
           "trigger output marks the burst start after TRIG:DEL (we keep TRIG:DEL 0, so "
           "both readings agree); the record's start offset is measured anyway "
           "(timing cycles, docs/method.md B)."),
    idn="Keysight Technologies,33522B,MY00000000,4.03-1.19-2.00-58-00",
)

PROFILES: dict[str, AwgProfile] = {p.model: p for p in (KEYSIGHT_33500B,)}


def get_profile(model: str) -> AwgProfile:
    return lookup_profile(PROFILES, model, "waveform generator")


@dataclass(frozen=True)
class LoadedPair:
    """What a channel plays on each trigger, with the timing the analysis needs."""

    channel: int
    name: str
    sample_rate_hz: float
    amplitude_v: float          # peak: point 1.0 is this many volts
    lead_points: int            # zeros before the first pulse edge
    points: int                 # all points, with the leading and trailing zeros

    @property
    def lead_s(self) -> float:
        """From the burst's start (the trigger output's edge) to the first pulse edge."""
        return self.lead_points / self.sample_rate_hz

    @property
    def duration_s(self) -> float:
        return self.points / self.sample_rate_hz


def format_points(values: np.ndarray) -> str:
    """Waveform values as the upload's list: 7 significant digits, finer than 16 bits."""
    return ",".join(f"{v:.7g}" for v in values)


class WaveformGenerator(ProfiledInstrument[AwgProfile]):
    """A SCPI arbitrary waveform generator that plays a pulse pair per bus trigger."""

    error_kinds = AWG_ERRORS
    words: AwgWords
    kind, stand_key, profiles = "waveform generator", "awg", PROFILES

    def __init__(self, resource: str, profile: AwgProfile, clock: Clock, *,
                 raw: RawCallback | None = None, command_timeout_s: float = 5.0,
                 visa_library: str = "@py") -> None:
        self.loaded: dict[int, LoadedPair] = {}
        super().__init__(resource, profile, clock, raw=raw,
                         command_timeout_s=command_timeout_s, visa_library=visa_library)

    def _check_channel(self, channel: int) -> None:
        if channel not in self.profile.channels:
            raise AwgError(f"{self.name}: no channel {channel} (has {self.profile.channels})")

    def load_pair(self, channel: int, pair: np.ndarray, sample_rate_hz: float,
                  amplitude_v: float, *, lead_points: int = 1, trail_points: int = 1,
                  name: str = "DRIFTPAIR", trigger_out: bool = True) -> LoadedPair:
        """Upload the pulse pair (values in [-1, 1]) and arm the channel for bus triggers.

        `amplitude_v` is the peak voltage of a point 1.0 into the high-impedance load.
        """
        import numpy as np
        p = self.profile
        self._check_channel(channel)
        pair = np.asarray(pair, dtype=float)
        wave = np.concatenate((np.zeros(lead_points), pair, np.zeros(trail_points)))
        problems = []
        if pair.ndim != 1 or pair.size == 0 or not np.all(np.isfinite(pair)):
            problems.append("the pair must be a non-empty list of numbers")
        elif np.max(np.abs(pair)) > 1.0:
            problems.append(f"values must lie in [-1, 1] (max |v| {np.max(np.abs(pair)):g})")
        if not p.min_points <= wave.size <= p.max_points:
            problems.append(f"{wave.size} points (the {p.model} takes {p.min_points} .. "
                            f"{p.max_points})")
        lo, hi = p.sample_rate_range_hz
        if not lo <= sample_rate_hz <= hi:
            problems.append(f"sample rate {sample_rate_hz:g} Hz (range {lo:g} .. {hi:g})")
        vpp = 2.0 * abs(amplitude_v)
        if not p.amplitude_range_vpp[0] <= vpp <= p.amplitude_range_vpp[1]:
            problems.append(f"amplitude {amplitude_v:g} V peak ({vpp:g} Vpp; range "
                            f"{p.amplitude_range_vpp[0]:g} .. {p.amplitude_range_vpp[1]:g} "
                            f"Vpp into high impedance)")
        if not re.fullmatch(r"[A-Za-z][A-Za-z0-9_]{0,11}", name):
            problems.append(f"waveform name {name!r} (a letter, then up to 11 letters, "
                            f"digits or _)")
        if problems:
            raise AwgError(f"{self.name}: load_pair(): " + "; ".join(problems))
        w = self.words
        with self.recovering():
            self.send(w.output, channel=channel, state=False)
            self.send(w.clear_volatile, channel=channel)
            self.send(w.arb_data, channel=channel, name=name, values=format_points(wave))
            self.send(w.arb_select, channel=channel, name=name)
            self.send(w.function, channel=channel, function="ARB")
            self.send(w.sample_rate, channel=channel, rate_hz=float(sample_rate_hz))
            self.send(w.arb_filter, channel=channel, filter="STEP")
            self.send(w.load, channel=channel, ohm="INF")
            self.send(w.offset, channel=channel, offset_v=0.0)
            self.send(w.amplitude, channel=channel, vpp=vpp)
            self.send(w.burst_mode, channel=channel, mode="TRIG")
            self.send(w.burst_cycles, channel=channel, cycles=1)
            self.send(w.burst_state, channel=channel, state=True)
            self.send(w.trigger_source, channel=channel, source="BUS")
            self.send(w.trigger_delay, channel=channel, delay_s=0.0)
            if trigger_out:
                self.send(w.trigger_out_source, source=f"CH{channel}")
                self.send(w.trigger_out_slope, slope="POS")
                self.send(w.trigger_out, state=True)
            self.send(w.output, channel=channel, state=True)
        loaded = LoadedPair(channel, name, float(sample_rate_hz), float(amplitude_v),
                            lead_points, wave.size)
        self.loaded[channel] = loaded
        return loaded

    def trigger(self) -> float:
        """`*TRG`: every channel armed for bus triggers plays its pair; the clock's time."""
        if not self.loaded:
            raise AwgError(f"{self.name}: trigger() before load_pair()")
        with self.recovering():
            self.send(self.words.bus_trigger)
        return self.clock.now()

    def outputs_off(self) -> None:
        """No current into the torque sensors (the safe state)."""
        with self.recovering():
            for ch in self.profile.channels:
                self.send(self.words.output, channel=ch, state=False)

    def close(self) -> None:
        """Outputs off (best effort), then close the link."""
        if self.is_open:
            with contextlib.suppress(InstrumentError):
                for ch in self.profile.channels:
                    self.send(self.words.output, channel=ch, state=False, check=False)
        super().close()
