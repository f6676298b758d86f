"""The CNT-91's words beyond its profile's: what PyMeasure's driver sends
(drivers/counter_profiles.py Cnt91ScriptWords; CNT-90 series Programmer's Handbook),
served by the twin of a model whose TwinProfile names them (sims/counter_models.py).
"""

from __future__ import annotations

from collections.abc import Mapping

from drivers.counter_profiles import CNT91_SCRIPT_WORDS
from sims.counter_commands import CounterCommands
from sims.scpi_server import (
    ExecError,
    bool_reply,
    count_param,
    enum_param,
    number_param,
    ranged_param,
)


class Cnt91Script(CounterCommands):
    """The CNT-91's script words (counter_profiles.Cnt91ScriptWords)."""

    def _route_cnt91_words(self) -> None:
        w = CNT91_SCRIPT_WORDS
        smax = self.profile.fetch_max_results or self.profile.max_count
        self.route(w.format_smax, on_query=lambda a: str(smax))
        self.route(w.continuous, on_set=lambda a: setattr(
            self, "continuous", _scpi_bool(a["raw"])),
            on_query=lambda a: bool_reply(self.continuous), raw=True)
        self.route(w.aperture, on_set=lambda a: setattr(
            self, "aperture_s", ranged_param(a["raw"], 2e-8, 1000.0, 0.01)),
            on_query=lambda a: self._nr3(self.aperture_s), raw=True)
        self.route(w.arm_source, on_set=self._set_arm_source,
                   on_query=lambda a: self.arm_source, raw=True)
        self.route(w.arm_slope, on_set=lambda a: setattr(
            self, "arm_slope", enum_param(a["raw"], ("POSitive", "NEGative"))),
            on_query=lambda a: self.arm_slope, raw=True)
        self.route(w.arm_count, on_set=lambda a: setattr(
            self, "arm_count", count_param(a["raw"], 2_000_000_000)),
            on_query=lambda a: str(self.arm_count), raw=True)
        self.route(w.interpolator_auto, on_set=lambda a: setattr(
            self, "interpolator_auto", _scpi_bool(a["raw"])),
            on_query=lambda a: bool_reply(self.interpolator_auto), raw=True)
        self.route(w.configure_frequency_array_btb,
                   on_set=lambda a: self._conf_gated(a, invert=True, array=True, btb=True),
                   raw=True)
        self.route(w.configure_frequency_array,
                   on_set=lambda a: self._conf_gated(a, invert=True, array=True, btb=False),
                   raw=True)
        self.route(w.configure_frequency, on_set=lambda a: self._conf_gated(
            a, invert=True, array=False, btb=False), raw=True)
        self.route(w.configure_period, on_set=lambda a: self._conf_gated(
            a, invert=False, array=False, btb=False), raw=True)
        self.route(w.measure_frequency, on_query=lambda a: self._measure_gated(a, True),
                   data=True, raw=True)
        self.route(w.measure_period, on_query=lambda a: self._measure_gated(a, False),
                   data=True, raw=True)
        self.route(w.read, on_query=self._read, data=True)
        self.route(w.fetch, on_query=self._fetch, data=True)
        self.route(w.status_byte, on_query=lambda a: str(4 if self.errors else 0))
        self.route(w.options, on_query=lambda a: "0")  # IEEE 488.2 10.20: none
        # :MEASure:ARRay:STSTamp? (p. 8-72) and :MEASure:ARRay:TSTAmp?, :CONF:ARR:TSTAmp
        self.route(w.measure_single_timestamps, on_query=lambda a: self._measure_ts(
            a, "stst"), data=True, raw=True)
        self.route(w.measure_timestamps, on_query=lambda a: self._measure_ts(a, "tsta"),
                   data=True, raw=True)
        self.route(w.configure_timestamps, on_set=lambda a: self._conf_ts(a, "tsta"),
                   raw=True)

    def _conf_ts(self, a: Mapping[str, str], layout: str) -> None:
        """:CONF:ARR:STSTamp / :CONF:ARR:TSTAmp (<n>)[,(@<ch>)]: n time stamps. STST turns
        FORM:TINF on (X,TS pairs, p. 8-72); TSTA leaves it (TS alone while it is off)."""
        count, chan = self._count_and_channel(a["raw"], self.profile.max_count, 100)
        if count is None:
            raise ExecError(-109, "Missing parameter")
        self._conf_timestamps({"count": str(count), "channel": str(chan)})
        self.ts_layout = layout
        if layout == "tsta":
            self.timestamp_info = False

    def _measure_ts(self, a: Mapping[str, str], layout: str) -> str | bytes:
        info = self.timestamp_info
        self._conf_ts(a, layout)
        if layout == "tsta":
            self.timestamp_info = info
        return self._read({})

    def _conf_gated(self, a: Mapping[str, str], *, invert: bool, array: bool,
                    btb: bool) -> None:
        """CONF:ARR:FREQ[:BTB] <n>,(@ch), CONF:FREQ [(@ch)], CONF:PER [(@ch)]."""
        text = a["raw"].replace(" ", "")
        count, chan = "1", text
        if array:
            count, _, chan = text.partition(",")
        self.sample_count = count_param(count, self.profile.max_count)
        self.function_channel = self._channel_list({"channel": chan.strip("(@)")}) \
            if chan else 1
        self.function, self.invert, self.walk, self.back_to_back = "periods", invert, True, btb
        self.acquisition = None

    def _measure_gated(self, a: Mapping[str, str], invert: bool) -> str | bytes:
        self._conf_gated(a, invert=invert, array=False, btb=False)
        return self._read({})


def _scpi_bool(text: str) -> bool:
    """A SCPI boolean: ON/OFF, or a number (non-zero is ON once rounded, SCPI-99 7.3)."""
    t = text.strip().upper()
    if t in ("ON", "OFF"):
        return t == "ON"
    return round(number_param(t, {})) != 0
