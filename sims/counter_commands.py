"""The counter twin's command table for the words of its CounterProfile
(drivers/counter_profiles.py CounterWords): one handler per word, setting the twin's
settings or starting and fetching its measurements.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

from drivers.counter_profiles import nr3 as profile_nr3
from sims.counter_engine import CounterEngine
from sims.counter_state import InputState, Kind
from sims.scpi_server import (
    ExecError,
    bool_param,
    bool_reply,
    count_param,
    enum_param,
    number_param,
    ranged_param,
    suffix_item,
)


class CounterCommands(CounterEngine):
    """The handlers of the profile's words, and what the model tables share."""

    # -- routes: one handler per word the profile has --------------------------------------
    def _route_words(self) -> None:
        self.route_words(self.profile.words, {
            "input_coupling": (self._set_coupling, lambda a: self._inp(a).coupling),
            "input_impedance": (self._set_impedance, lambda a: self._nr3(self._inp(a).impedance_ohm)),
            "input_level_auto": (self._set_level_auto,
                                 lambda a: bool_reply(self._inp(a).level_auto)),
            "input_level": (self._set_level, lambda a: self._nr3(self._inp(a).level_v)),
            "input_slope": (self._set_slope, lambda a: self._inp(a).slope),
            "configure_timestamps": (self._conf_timestamps, None),
            "configure_period": (self._conf_period, None),
            "timestamp_rate": (self._set_rate, lambda a: self._nr3(self.timestamp_rate_hz)),
            "timestamp_info": (self._set_tinf, lambda a: bool_reply(self.timestamp_info)),
            "sample_count": (self._set_count, lambda a: f"+{self.sample_count}"),
            "gate_time": (self._set_gate, None),
            "measurement_timeout": (self._set_timeout, lambda a: self._nr3(
                9.9e37 if self.timeout_s is None else self.timeout_s)),  # p. 459: 9.9E37
            "format_data": (self._set_format, lambda a: self.data_format),
            "trigger_source": (self._set_trigger_source, lambda a: (
                self.arm_source if self.twin_profile.start_by_arming
                else self.trigger_source)),
            "reference_source": (self._set_reference, lambda a: self.reference),
            "reference_check": (self._check_reference, None),
            "abort": (self._abort, None),
            "initiate": (self._initiate, None),
            "fetch": (None, self._fetch, True),
            "fetch_array": (None, self._fetch_array, True),
            "read": (None, self._read, True),
        })

    def _nr3(self, value: float) -> str:
        """A setting's query reply as the model prints it: `+1.00000000E+006` (53230A
        Programmer's Reference p. 377, p. 459)."""
        return profile_nr3(value, 8, self.profile.reply_exp_digits)

    def _inp(self, a: Mapping[str, str]) -> InputState:
        return suffix_item(self.inputs, a)

    def _set_coupling(self, a: Mapping[str, str]) -> None:
        self._inp(a).coupling = enum_param(a["coupling"], self.profile.couplings)

    def _set_impedance(self, a: Mapping[str, str]) -> None:
        z = number_param(a["impedance_ohm"], {"MIN": min(self.profile.impedances_ohm),
                                              "MAX": max(self.profile.impedances_ohm),
                                              "DEF": 1.0e6})
        if not any(math.isclose(z, x) for x in self.profile.impedances_ohm):
            raise ExecError(-224, "Illegal parameter value")
        self._inp(a).impedance_ohm = z

    def _set_level_auto(self, a: Mapping[str, str]) -> None:
        state = a["state"].upper()
        if state == "ONCE":  # one auto-level on a pulse this slow finds nothing useful
            self._inp(a).level_auto = False
            return
        self._inp(a).level_auto = bool_param(state)

    def _set_level(self, a: Mapping[str, str]) -> None:
        v = ranged_param(a["level_v"], *self.profile.level_range_v, default=0.0)
        inp = self._inp(a)
        inp.level_v, inp.level_auto = v, False  # a level given turns auto-level off

    def _set_slope(self, a: Mapping[str, str]) -> None:
        self._inp(a).slope = enum_param(a["slope"], ("POSitive", "NEGative"))

    def _channel_list(self, a: Mapping[str, str]) -> int:
        ch = int(number_param(a["channel"], {}))
        if ch not in self.profile.channels:
            raise ExecError(-222, "Data out of range")
        return ch

    def _conf_timestamps(self, a: Mapping[str, str]) -> None:
        count = count_param(a["count"], self.profile.max_count, default=100)
        self.function, self.function_channel = "timestamps", self._channel_list(a)
        self.sample_count = count
        self.timestamp_info = True  # CONF turns the timestamp information on (CNT-91)
        self.ts_layout = "stst"
        self.acquisition = None

    def _conf_period(self, a: Mapping[str, str]) -> None:
        self.function, self.function_channel = "periods", self._channel_list(a)
        self.sample_count = 1
        self.invert = False
        self.acquisition = None

    def _set_rate(self, a: Mapping[str, str]) -> None:
        rate = number_param(a["rate_hz"], {"MIN": 1e4, "MAX": 1e6, "DEF": 1e6})
        if not any(math.isclose(rate, r) for r in (1e4, 1e5, 8e5, 1e6)):
            raise ExecError(-224, "Illegal parameter value")
        self.timestamp_rate_hz = rate

    def _set_tinf(self, a: Mapping[str, str]) -> None:
        self.timestamp_info = bool_param(a["state"])

    def _set_count(self, a: Mapping[str, str]) -> None:
        self.sample_count = count_param(a["count"], self.profile.max_count)

    def _set_gate(self, a: Mapping[str, str]) -> None:
        self.gate = a["gate_s"]  # one period per reading whatever the gate: turns are slow

    def _set_timeout(self, a: Mapping[str, str]) -> None:
        lo, hi = self.profile.measurement_timeout_range_s or (0.0, math.inf)
        value = a["timeout_s"].upper()
        if value.startswith("INF"):
            self.timeout_s = None
            return
        self.timeout_s = ranged_param(value, lo, hi, default=1.0)

    def _set_reference(self, a: Mapping[str, str]) -> None:
        source = enum_param(a["source"], self.twin_profile.reference_sources)
        if not self.twin_profile.reference_checked_on_select:
            self.reference = source
            return
        # CNT-91 [:SENSe]:ROSCillator:SOURce {INTernal|EXTernal|AUTO} (unverified, see
        # the profile's notes): EXTernal with no valid signal at the reference input is
        # an error here (the model has no check word), and the source stays as it was
        if source == "EXT" and not self.external_reference:
            raise ExecError(-241, "Hardware missing;no valid external reference signal")
        self.reference = source

    def _check_reference(self, a: Mapping[str, str]) -> None:
        """SENS:ROSC:EXT:CHEC ONCE: an error when no valid signal is at Ext Ref In."""
        if enum_param(a["when"], ("ONCE",)) and not self.external_reference:
            raise ExecError(-241, "Hardware missing; no valid external timebase")

    def _set_trigger_source(self, a: Mapping[str, str]) -> None:
        if self.twin_profile.start_by_arming:   # the start arming source (CNT-91)
            self._set_arm_source({"raw": a["source"]})
            return
        self.trigger_source = enum_param(a["source"], ("IMMediate", "EXTernal", "BUS"))

    def _set_arm_source(self, a: Mapping[str, str]) -> None:
        src = a["raw"].strip().upper()
        names = {"IMM": "IMM", "IMMEDIATE": "IMM", "EXT1": "EXT1", "EXTERNAL1": "EXT1",
                 "EXT2": "EXT2", "EXTERNAL2": "EXT2", "EXT4": "EXT4", "EXTERNAL4": "EXT4"}
        if src not in names:
            raise ExecError(-224, "Illegal parameter value")
        self.arm_source = names[src]

    def _set_format(self, a: Mapping[str, str]) -> None:
        """FORMat[:DATA] {ASCii|REAL} (CNT-90 series Programmer's Handbook); PACKed is
        not modelled (-224)."""
        fmt = enum_param(a["format"], ("ASCii", "REAL", "PACKed"))
        if fmt == "PACK":
            raise ExecError(-224, "Illegal parameter value")
        self.data_format = fmt

    def _abort(self, a: Mapping[str, str]) -> None:
        self.acquisition = None

    def _kind(self) -> Kind:
        """What INIT / READ? measure; -221 for a function set but not modelled (a clear
        error, not a wrong number)."""
        if self.function is None:
            raise ExecError(-221, "Settings conflict")
        if self.function == "tint":
            raise ExecError(-221, "Settings conflict;time interval (CONF:TINT) is not "
                                  "modelled by this twin")
        return self.function  # type: ignore[return-value]

    def _initiate(self, a: Mapping[str, str]) -> None:
        kind = self._kind()
        if self.pending():
            raise ExecError(-213, "Init ignored")
        self._arm(kind, self._per_init())

    def _fetch(self, a: Mapping[str, str]) -> str | bytes:
        acq = self.acquisition
        values = self._readings(acq)
        assert acq is not None
        return self._reply(acq, values, fetch=True)

    def _fetch_array(self, a: Mapping[str, str]) -> str | bytes:
        acq = self.acquisition
        values = self._readings(acq)
        assert acq is not None
        count = a["count"].upper()
        left = values.size - acq.fetched
        limit = self.profile.fetch_max_results or values.size
        n = min(left, limit) if count.startswith("MAX") else int(number_param(count, {}))
        if not 1 <= n <= min(left, limit):
            raise ExecError(-222, "Data out of range")
        first = acq.fetched
        acq.fetched += n
        return self._reply(acq, values[first:first + n], first)

    def _read(self, a: Mapping[str, str]) -> str | bytes:
        kind = self._kind()
        if self._start_source() == "bus":
            # READ? (ABORt, INIT, FETCh?) cannot be followed by the *TRG it would wait
            # for: SCPI-99 vol. 2, 21.8.10, -214 "Trigger deadlock"
            raise ExecError(-214, "Trigger deadlock")
        acq = self._arm(kind, self._per_init())
        return self._reply(acq, self._readings(acq), fetch=True)

    def _count_and_channel(self, raw: str, high: int, default: int = 1
                           ) -> tuple[int | None, int]:
        """`[(<count>) | <count>][,(@<ch>)]`: the count (None if absent) and channel (1)."""
        items = split_params(raw)
        chan = 1
        if items and items[-1].startswith("(@"):
            chan = self._channel_list({"channel": items.pop().strip("(@)")})
        if len(items) > 1:
            raise ExecError(-108, "Parameter not allowed")
        count = count_param(items[0].strip("()"), high, default) if items else None
        return count, chan


def split_params(raw: str) -> list[str]:
    """A parameter text's parameters (commas outside parentheses), blanks removed."""
    text = raw.replace(" ", "")
    if not text:
        return []
    out, depth, cur = [], 0, ""
    for ch in text:
        depth += (ch == "(") - (ch == ")")
        if ch == "," and depth == 0:
            out.append(cur)
            cur = ""
        else:
            cur += ch
    return [*out, cur]
