"""The pulse generator's twin: plays its arbitrary waveforms into the platform's torque
sensors, over real SCPI (the words of drivers/awg.py, imported, not copied).

On `*TRG` every channel that is on, in burst mode, triggered from the bus and set to an
uploaded arbitrary waveform plays it once: from the stand clock's now plus
`output_latency_s`, as a zero-order hold at its sample rate (the STEP filter; with the
smoothing filter a real generator would round the edges, which the twin refuses to
pretend it does not: it queues -221 at *TRG). The voltage that reaches the load follows
the output's load setting and the real load, as on the bench: a 50 ohm setting into the
amplifier's high-impedance input doubles it. The values are quantised to the DAC's bits.

The trigger output, if on, fires `trigger_out` listeners (the wire to the digitizer's
Ext Trig input) with the times of its rising and falling edge, `trigger_out_skew_s`
after the burst starts. Faults (`inject`): 'no-output' (the next burst does not reach
the torque sensor: a broken wire), plus the base's.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np

from drivers.awg import AwgProfile, get_profile
from sims.platform import GyroPlatform
from sims.scpi_server import (
    ExecError,
    ScpiServer,
    bool_param,
    bool_reply,
    enum_param,
    nr3,
    number_param,
    ranged_param,
    suffix_item,
)

#: the trigger output's wire: (rising edge, falling edge), stand time
TriggerListener = Callable[[float, float], None]

HIGH_Z_OHM = 1e12


@dataclass
class Channel:
    """One output's settings as the twin holds them (*RST values)."""

    arbs: dict[str, np.ndarray] = field(default_factory=dict)
    arb: str | None = None
    function: str = "SIN"
    sample_rate_hz: float = 40e3
    arb_filter: str = "NORM"
    vpp: float = 0.1
    offset_v: float = 0.0
    load_ohm: float = 50.0          # the setting (the real load is the twin's wiring)
    burst_mode: str = "TRIG"
    burst_cycles: int = 1
    burst_on: bool = False
    trigger_source: str = "IMM"
    trigger_delay_s: float = 0.0
    output_on: bool = False


class AwgTwin(ScpiServer):
    """A generator of `model` whose channels drive gyros of `platform` (`outputs`)."""

    fault_names = ScpiServer.fault_names | {"no-output"}

    def __init__(self, platform: GyroPlatform, outputs: Mapping[int, str],
                 model: str = "keysight-33500b", host: str = "127.0.0.1", port: int = 0, *,
                 output_latency_s: float = 0.0, trigger_out_skew_s: float = 0.0,
                 trigger_out_width_s: float = 1e-6, load_ohm: float = 10e3,
                 amplitude_error_rel: float = 0.0) -> None:
        self.profile: AwgProfile = get_profile(model)
        super().__init__(idn=self.profile.idn, host=host, port=port)
        if platform.clock is None:
            raise ValueError("the platform must sit on a simulated stand (for its clock)")
        unknown = [ch for ch in outputs if ch not in self.profile.channels]
        if unknown:
            raise ValueError(f"{self.profile.model} has no channel(s) {unknown}")
        self.platform = platform
        self.clock = platform.clock
        self.outputs = dict(outputs)
        self.output_latency_s = float(output_latency_s)
        self.trigger_out_skew_s = float(trigger_out_skew_s)
        self.trigger_out_width_s = float(trigger_out_width_s)
        self.real_load_ohm = float(load_ohm)
        #: the output's true amplitude error a, unknown to the lab (issue 58): every
        #: waveform point reaches the load x (1 + a)
        self.amplitude_error_rel = float(amplitude_error_rel)
        self.trigger_out: list[TriggerListener] = []
        self.bursts: list[tuple[int, float]] = []    # (channel, start time) played
        self.reset()
        self._route_words()

    def reset(self) -> None:
        self.channels = {ch: Channel() for ch in self.profile.channels}
        self.trig_out_on = False
        self.trig_out_source = 1
        self.trig_out_slope = "POS"

    # -- routes -----------------------------------------------------------------------------
    def _route_words(self) -> None:
        ch = self._ch
        self.route_words(self.profile.words, {
            "clear_volatile": (lambda a: self._clear(a), None),
            "arb_data": (self._arb_data, None),
            "arb_select": (self._arb_select, lambda a: f'"{ch(a).arb or ""}"'),
            "function": (lambda a: setattr(ch(a), "function", enum_param(
                a["function"], ("SINusoid", "SQUare", "RAMP", "PULSe", "ARBitrary", "DC",
                                "NOISe", "TRIangle", "PRBS"))),
                         lambda a: ch(a).function),
            "sample_rate": (self._sample_rate, lambda a: nr3(ch(a).sample_rate_hz)),
            "arb_filter": (lambda a: setattr(ch(a), "arb_filter", enum_param(
                a["filter"], ("NORMal", "STEP", "OFF"))), lambda a: ch(a).arb_filter),
            "amplitude": (self._amplitude, lambda a: nr3(ch(a).vpp)),
            "offset": (lambda a: setattr(ch(a), "offset_v", number_param(a["offset_v"], {})),
                       lambda a: nr3(ch(a).offset_v)),
            "load": (self._load, lambda a: nr3(ch(a).load_ohm)),
            "burst_mode": (lambda a: setattr(ch(a), "burst_mode", enum_param(
                a["mode"], ("TRIGgered", "GATed"))), lambda a: ch(a).burst_mode),
            "burst_cycles": (self._cycles, lambda a: f"{ch(a).burst_cycles}"),
            "burst_state": (lambda a: setattr(ch(a), "burst_on", bool_param(a["state"])),
                            lambda a: bool_reply(ch(a).burst_on)),
            "trigger_source": (lambda a: setattr(ch(a), "trigger_source", enum_param(
                a["source"], ("IMMediate", "EXTernal", "TIMer", "BUS"))),
                               lambda a: ch(a).trigger_source),
            "trigger_delay": (self._delay, lambda a: nr3(ch(a).trigger_delay_s)),
            "output": (lambda a: setattr(ch(a), "output_on", bool_param(a["state"])),
                       lambda a: bool_reply(ch(a).output_on)),
            "trigger_out": (lambda a: setattr(self, "trig_out_on", bool_param(a["state"])),
                            lambda a: bool_reply(self.trig_out_on)),
            "trigger_out_source": (self._trig_out_source, lambda a: f"CH{self.trig_out_source}"),
            "trigger_out_slope": (lambda a: setattr(self, "trig_out_slope", enum_param(
                a["slope"], ("POSitive", "NEGative"))), lambda a: self.trig_out_slope),
            "bus_trigger": (lambda a: self._bus_trigger(), None),
        })

    def _ch(self, a: Mapping[str, str]) -> Channel:
        return suffix_item(self.channels, a)

    def _clear(self, a: Mapping[str, str]) -> None:
        c = self._ch(a)
        c.arbs.clear()
        c.arb = None

    def _arb_data(self, a: Mapping[str, str]) -> None:
        try:
            values = np.array([float(v) for v in a["values"].split(",")])
        except ValueError:
            raise ExecError(-104, "Data type error") from None
        p = self.profile
        if not p.min_points <= values.size <= p.max_points:
            raise ExecError(-222, "Data out of range")
        if np.max(np.abs(values)) > 1.0:
            raise ExecError(-222, "Data out of range")
        full = 2 ** (p.dac_bits - 1) - 1
        self._ch(a).arbs[a["name"].strip().strip('"').upper()] = np.round(values * full) / full

    def _arb_select(self, a: Mapping[str, str]) -> None:
        c = self._ch(a)
        name = a["name"].strip().strip('"').upper()
        if name not in c.arbs:
            raise ExecError(-256, "File name not found")
        c.arb = name

    def _sample_rate(self, a: Mapping[str, str]) -> None:
        rate_hz = ranged_param(a["rate_hz"], *self.profile.sample_rate_range_hz, default=40e3)
        self._ch(a).sample_rate_hz = rate_hz

    def _amplitude(self, a: Mapping[str, str]) -> None:
        self._ch(a).vpp = ranged_param(a["vpp"], *self.profile.amplitude_range_vpp, default=0.1)

    def _load(self, a: Mapping[str, str]) -> None:
        text = a["ohm"].strip().upper()
        self._ch(a).load_ohm = HIGH_Z_OHM if text.startswith("INF") else \
            number_param(text, {"MIN": 1.0, "MAX": 10e3, "DEF": 50.0})

    def _cycles(self, a: Mapping[str, str]) -> None:
        n = int(number_param(a["cycles"], {"MIN": 1, "DEF": 1}))
        if n < 1:
            raise ExecError(-222, "Data out of range")
        self._ch(a).burst_cycles = n

    def _delay(self, a: Mapping[str, str]) -> None:
        self._ch(a).trigger_delay_s = ranged_param(a["delay_s"], 0.0, 1000.0, default=0.0)

    def _trig_out_source(self, a: Mapping[str, str]) -> None:
        text = a["source"].strip().upper()
        if text not in {f"CH{c}" for c in self.profile.channels}:
            raise ExecError(-224, "Illegal parameter value")
        self.trig_out_source = int(text[2:])

    # -- playing --------------------------------------------------------------------------
    def load_volts(self, c: Channel) -> float:
        """Volts per unit point at the real load: the setting, the 50 ohm source, the load."""
        open_v = 0.5 * c.vpp * (1.0 if c.load_ohm >= HIGH_Z_OHM else
                                (c.load_ohm + 50.0) / c.load_ohm)
        if self.amplitude_error_rel != 0.0:     # issue 58; 0: to the bit as before
            open_v *= 1.0 + self.amplitude_error_rel
        return open_v * self.real_load_ohm / (self.real_load_ohm + 50.0)

    def _bus_trigger(self) -> None:
        now = self.clock.now()
        no_output = self.take_fault("no-output")
        for n, c in self.channels.items():
            if not (c.output_on and c.burst_on and c.trigger_source == "BUS"):
                continue
            if c.function != "ARB" or c.arb is None:
                raise ExecError(-221, "Settings conflict")
            if c.arb_filter != "STEP":
                raise ExecError(-221, "Settings conflict")  # see the module docstring
            t0 = now + self.output_latency_s + c.trigger_delay_s
            wave = np.tile(c.arbs[c.arb], c.burst_cycles)
            volts = c.offset_v + self.load_volts(c) * wave
            gyro = self.outputs.get(n)
            if gyro is not None and not no_output:
                self.platform.apply_voltage(gyro, t0, 1.0 / c.sample_rate_hz, volts)
            self.bursts.append((n, t0))
            if self.trig_out_on and self.trig_out_source == n:
                lead = t0 + self.trigger_out_skew_s
                trail = lead + self.trigger_out_width_s
                rise, fall = (lead, trail) if self.trig_out_slope == "POS" else (trail, lead)
                for listener in list(self.trigger_out):
                    listener(rise, fall)
