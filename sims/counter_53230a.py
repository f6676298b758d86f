"""The 53230A's words beyond its profile's: what users' own scripts send
(drivers/counter_profiles.py Keysight53230aScriptWords; Programmer's Reference: MEASure,
CONFigure, DATA, FORMat, TRIGger subsystems; R?, *LRN?, *STB?), served by the twin of a
model whose TwinProfile names them (sims/counter_models.py).
"""

from __future__ import annotations

from collections.abc import Mapping

from drivers.counter_profiles import (
    KEYSIGHT_53230A_COUNT_MAX,
    KEYSIGHT_53230A_MEMORY,
    KEYSIGHT_53230A_SCRIPT_WORDS,
)
from drivers.counter_profiles import nr3 as profile_nr3
from drivers.scpi import TRG, count_params
from sims.counter_commands import CounterCommands, split_params
from sims.counter_engine import block
from sims.scpi_server import ExecError, count_param, enum_param, number_param, ranged_param


class Keysight53230aScript(CounterCommands):
    """The 53230A's script words (counter_profiles.Keysight53230aScriptWords)."""

    def _route_script_words(self) -> None:
        """The 53230A as the public client programs script it (Programmer's Reference:
        MEASure, CONFigure, DATA, FORMat, TRIGger subsystems; R?, *LRN?, *STB?)."""
        w = KEYSIGHT_53230A_SCRIPT_WORDS
        # first: ahead of the profile's templated forms
        self.route(w.format_data, on_set=self._set_format_raw, on_query=lambda a: (
            f"ASC,{self.ascii_digits}" if self.data_format == "ASC" else "REAL,64"),
            first=True, raw=True)
        self.route(w.configure_period, on_set=lambda a: self._conf_scalar(a, invert=False),
                   first=True, raw=True)
        self.route(w.configure_frequency, on_set=lambda a: self._conf_scalar(a, invert=True),
                   raw=True)
        self.route(w.configure_timestamp, on_set=self._conf_tst, raw=True)
        self.route(w.measure_period, on_query=lambda a: self._measure_scalar(a, False),
                   data=True, raw=True)
        self.route(w.measure_frequency, on_query=lambda a: self._measure_scalar(a, True),
                   data=True, raw=True)
        self.route(w.measure_timestamps, on_query=self._measure_tst, data=True, raw=True)
        self.route(w.read_remove, on_query=self._r_query, data=True, raw=True)
        self.route(w.data_remove, on_query=self._data_remove, data=True, raw=True)
        self.route(w.data_points, on_query=lambda a: f"+{len(self._memory())}")
        self.route(w.configure_query, on_query=self._conf_query)
        self.route(w.learn, on_query=self._learn)
        self.route(w.status_byte, on_query=lambda a: f"+{4 if self.errors else 0}")
        self.route(w.scpi_version, on_query=lambda a: "1994.0")
        # TRIG:COUN? / SAMP:COUN? [MIN|MAX|DEF] (Programmer's Reference, TRIGger:COUNt
        # and SAMPle:COUNt: 1 to 1,000,000, default 1)
        self.route(w.trigger_count, on_set=self._set_trigger_count, on_query=lambda a: (
            _count_query(a["raw"], self.trigger_count, KEYSIGHT_53230A_COUNT_MAX)),
            raw=True)
        self.route(w.sample_count, on_set=self._set_sample_count_raw, on_query=lambda a: (
            _count_query(a["raw"], self.sample_count, KEYSIGHT_53230A_COUNT_MAX)),
            first=True, raw=True)
        self.route(w.trigger_delay, on_set=self._set_trigger_delay,
                   on_query=self._trigger_delay_query, raw=True)
        # IEEE 488.2 *TRG: the bus trigger TRIG:SOUR BUS waits for (TRIGger:SOURce page)
        self.route(TRG, on_set=self._bus_trigger)
        self.route(w.configure_time_interval, on_set=self._conf_tint, raw=True)
        self.route(w.configure_totalize_timed, on_set=self._conf_totalize, raw=True)
        self.route(w.trigger_slope, on_set=lambda a: setattr(
            self, "trigger_slope", enum_param(a["raw"], ("POSitive", "NEGative"))),
            on_query=lambda a: self.trigger_slope, raw=True)
        self.route(w.byte_order, on_set=lambda a: setattr(
            self, "byte_order", enum_param(a["raw"], ("NORMal", "SWAPped"))),
            on_query=lambda a: self.byte_order, raw=True)
        self.route(w.frequency_mode, on_set=lambda a: setattr(
            self, "frequency_mode", enum_param(a["raw"], ("AUTO", "CONTinuous",
                                                          "RCONtinuous", "RECiprocal"))),
            on_query=lambda a: self.frequency_mode, raw=True)

    def _nr3_15(self, value: float) -> str:
        return profile_nr3(value, 14, self.profile.reply_exp_digits)

    def _set_format_raw(self, a: Mapping[str, str]) -> None:
        """FORMat[:DATA] ASCii[,<digits 1..15>] | REAL[,64]."""
        kind, _, length = a["raw"].partition(",")
        fmt = enum_param(kind, ("ASCii", "REAL"))
        if fmt == "ASC":
            digits = int(number_param(length, {"MIN": 1, "MAX": 15, "DEF": 15})) \
                if length.strip() else 15
            if not 1 <= digits <= 15:
                raise ExecError(-222, "Data out of range")
            self.data_format, self.ascii_digits = "ASC", digits
        else:
            if length.strip() and int(number_param(length, {"DEF": 64})) != 64:
                raise ExecError(-224, "Illegal parameter value")
            self.data_format = "REAL"

    def _scalar_channel(self, raw: str) -> int:
        """`[<expected>,<resolution>,](@<ch>)` or nothing (channel 1): the channel."""
        text = raw.replace(" ", "")
        parts = [p for p in text.split(",") if p] if text else []
        chan = 1
        if parts and parts[-1].startswith("(@"):
            chan = self._channel_list({"channel": parts.pop().strip("(@)")})
        if len(parts) > 2:
            raise ExecError(-108, "Parameter not allowed")
        for p in parts:  # expected value and resolution: numbers, MIN, MAX or DEF
            number_param(p, {"MIN": 0.0, "MAX": 0.0, "DEF": 0.0})
        return chan

    def _conf_scalar(self, a: Mapping[str, str], invert: bool) -> None:
        self.function_channel = self._scalar_channel(a["raw"])
        self.function, self.sample_count, self.invert = "periods", 1, invert
        self.trigger_count = 1
        self.acquisition = None

    def _measure_scalar(self, a: Mapping[str, str], invert: bool) -> str | bytes:
        self._conf_scalar(a, invert)
        return self._read({})

    def _conf_tst(self, a: Mapping[str, str]) -> None:
        """CONFigure:TSTamp [{<count>|MIN|MAX|DEF}][,(@<ch>)] (the reference's example:
        `CONF:TST (5000)`); a count sets the readings (SAMP:COUN), none leaves them."""
        count, chan = self._count_and_channel(a["raw"], KEYSIGHT_53230A_MEMORY)
        self.function, self.function_channel = "timestamps", chan
        if count is not None:
            self.sample_count = count
        self.acquisition = None


    def _conf_tint(self, a: Mapping[str, str]) -> None:
        """CONFigure:TINTerval [(@<start>),(@<stop>)] (53220A/53230A Programmer's
        Reference; default (@1),(@2)). Configured and reported by CONF?; measuring it is
        not modelled (INIT, READ? give -221)."""
        items = split_params(a["raw"])
        if len(items) > 2:
            raise ExecError(-108, "Parameter not allowed")
        if any(not i.startswith("(@") for i in items):
            raise ExecError(-224, "Illegal parameter value")
        chans = [self._channel_list({"channel": i.strip("(@)")}) for i in items] or [1, 2]
        self.tint_channels = (chans[0], chans[-1])   # one list: start and stop on it
        self.function, self.function_channel = "tint", self.tint_channels[0]
        self.sample_count = self.trigger_count = 1
        self.acquisition = None

    def _conf_totalize(self, a: Mapping[str, str]) -> None:
        """CONFigure:TOTalize:TIMed [<gate>,][(@<ch>)] (53220A/53230A Programmer's
        Reference): edges counted in a gate; DEF 0.1 s (gate range assumed 1e-5 to
        1000 s, unverified). Each reading is the zero marks in one gate."""
        items = split_params(a["raw"])
        chan = 1
        if items and items[-1].startswith("(@"):
            chan = self._channel_list({"channel": items.pop().strip("(@)")})
        if len(items) > 1:
            raise ExecError(-108, "Parameter not allowed")
        gate = ranged_param(items[0], 1e-5, 1000.0, 0.1) if items else 0.1
        self.function, self.function_channel, self.totalize_gate_s = "totals", chan, gate
        self.sample_count = self.trigger_count = 1
        self.acquisition = None

    def _measure_tst(self, a: Mapping[str, str]) -> str | bytes:
        count, _, chan = a["raw"].replace(" ", "").partition("),(")
        self._conf_timestamps({"count": count.strip("()"), "channel": chan.strip("(@)")
                               if chan else "1"})
        return self._read({})

    def _memory(self) -> list[str]:
        """The reading memory not yet removed, as the instrument would print each item.
        For timestamps the prescaler is the first item (count+1 elements, User's Guide
        'Time stamp'), so DATA:POIN? counts it and a removal may take it."""
        acq = self.acquisition
        if acq is None:
            return []
        values = self._available(acq)
        items = self._encode(acq, values).split(",") if values.size else []
        return items[acq.removed:]

    def _remove(self, n: int) -> str | bytes:
        acq = self.acquisition
        assert acq is not None
        items = self._memory()[:n]
        acq.removed += len(items)
        return self._formatted(",".join(items))

    def _r_query(self, a: Mapping[str, str]) -> bytes:
        """R? [<max>]: the readings in memory (at most max), removed, as a definite-length
        block; `#10` when there are none (joewhalen/keysight_53230A counter.py)."""
        raw = a["raw"].strip()
        limit = int(number_param(raw, {"MIN": 1, "MAX": KEYSIGHT_53230A_MEMORY,
                                       "DEF": KEYSIGHT_53230A_MEMORY})) if raw else None
        n = len(self._memory())
        n = n if limit is None else min(n, limit)
        if n == 0:
            return b"#10"
        reply = self._remove(n)
        return reply if isinstance(reply, bytes) else block(reply.encode("ascii"))

    def _data_remove(self, a: Mapping[str, str]) -> str | bytes:
        """DATA:REMove? <n>[,WAIT]: n readings removed; with WAIT, once they exist; without,
        -230 when fewer are in memory (opronningen/53230A-Toolkit R/R.cs)."""
        count, _, wait = a["raw"].replace(" ", "").partition(",")
        n = count_param(count, KEYSIGHT_53230A_MEMORY)
        if self.acquisition is None:
            raise ExecError(-230, "Data corrupt or stale")
        if wait:
            enum_param(wait, ("WAIT",))
            self.wait(lambda: len(self._memory()) >= n)
        elif len(self._memory()) < n:
            raise ExecError(-230, "Data corrupt or stale")
        return self._remove(n)

    def _conf_query(self, a: Mapping[str, str]) -> str:
        """CONFigure?: the function and channel, quoted (unverified layout)."""
        if self.function == "tint":
            start, stop = self.tint_channels
            return f'"TINT (@{start}),(@{stop})"'
        if self.function == "totals":
            return (f'"TOT:TIM {self._nr3_15(self.totalize_gate_s)},'
                    f'(@{self.function_channel})"')
        name = {"timestamps": "TST", "periods": "FREQ" if self.invert else "PER"}.get(
            self.function or "", "FREQ")
        return f'"{name} (@{self.function_channel})"'

    def _set_trigger_count(self, a: Mapping[str, str]) -> None:
        self.trigger_count = _count_set(a["raw"], KEYSIGHT_53230A_COUNT_MAX)

    def _set_sample_count_raw(self, a: Mapping[str, str]) -> None:
        self.sample_count = _count_set(a["raw"], KEYSIGHT_53230A_COUNT_MAX)

    def _set_trigger_delay(self, a: Mapping[str, str]) -> None:
        if count_params(a["raw"]) > 1:
            raise ExecError(-108, "Parameter not allowed")
        self.trigger_delay_s = ranged_param(a["raw"], 0.0, 3600.0, 0.0)

    def _trigger_delay_query(self, a: Mapping[str, str]) -> str:
        """TRIG:DEL? [MIN|MAX|DEF]: 0 to 3600 s, default 0."""
        raw = a["raw"].strip()
        if not raw:
            return self._nr3_15(self.trigger_delay_s)
        if count_params(raw) > 1:
            raise ExecError(-108, "Parameter not allowed")
        which = enum_param(raw, ("MINimum", "MAXimum", "DEFault"))
        return self._nr3_15({"MIN": 0.0, "MAX": 3600.0, "DEF": 0.0}[which])

    def _learn(self, a: Mapping[str, str]) -> str:
        """*LRN?: the settings as the commands that restore them, `;`-separated, as
        opronningen/53230A-Toolkit's LearnConfig splits them."""
        parts = ["*RST", f":TRIG:SOUR {self.trigger_source}",
                 f":TRIG:SLOP {self.trigger_slope}", f":TRIG:COUN +{self.trigger_count}",
                 f":TRIG:DEL {self._nr3_15(self.trigger_delay_s)}",
                 f":SAMP:COUN +{self.sample_count}",
                 "FORM " + (f"ASC,{self.ascii_digits}" if self.data_format == "ASC"
                            else "REAL,64"),
                 f"FORM:BORD {self.byte_order}", f":FREQ:MODE {self.frequency_mode}",
                 f":TST:RATE {self._nr3_15(self.timestamp_rate_hz)}"]
        for ch, inp in sorted(self.inputs.items()):
            parts += [f":INP{ch}:COUP {inp.coupling}", f":INP{ch}:IMP "
                      f"{self._nr3_15(inp.impedance_ohm)}", f":INP{ch}:SLOP {inp.slope}",
                      f":INP{ch}:LEV:AUTO {'ON' if inp.level_auto else 'OFF'}"]
            if not inp.level_auto:
                parts.append(f":INP{ch}:LEV {self._nr3_15(inp.level_v)}")
        return ";".join(parts)


def _count_set(raw: str, high: int) -> int:
    """A count setting: one of 1..high, MIN, MAX, DEF; more than one parameter is -108
    (SCPI-99 vol. 2, 21.8.9), none -109."""
    n = count_params(raw)
    if n == 0:
        raise ExecError(-109, "Missing parameter")
    if n > 1:
        raise ExecError(-108, "Parameter not allowed")
    return count_param(raw, high)


def _count_query(raw: str, current: int, high: int, default: int = 1) -> str:
    """A count's query, `?` alone (the setting) or `? MIN|MAX|DEF` (its limits)."""
    n = count_params(raw)
    if n == 0:
        return f"+{current}"
    if n > 1:
        raise ExecError(-108, "Parameter not allowed")
    which = enum_param(raw, ("MINimum", "MAXimum", "DEFault"))
    return f"+{ {'MIN': 1, 'MAX': high, 'DEF': default}[which] }"
