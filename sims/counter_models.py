"""What the counter twin of each model does where the models differ beyond the words,
limits and reply formats of their CounterProfile (drivers/counter_profiles.py): a table,
read by the twin as data, so no line of the twin asks a model's name.

A model with no entry here behaves as the generic SCPI counter does (`TwinProfile()`).
"""

from __future__ import annotations

from dataclasses import dataclass

from drivers.counter_profiles import KEYSIGHT_53230A_MEMORY, CounterProfile


@dataclass(frozen=True)
class TwinProfile:
    """One model's behaviour in the twin, each field with the manual it follows."""

    #: SYSTem:ERRor? code as the model prints it (53220A/53230A Programmer's Reference:
    #: `+0,"No error"`)
    error_code_format: str = "{:d}"
    #: the *RST function (53230A: FREQ 1, the twin's "periods" read as 1 / period)
    rst_function: str | None = None
    rst_invert: bool = False
    #: the reading memory: at most this many readings a measurement (None: the
    #: profile's max_count)
    reading_memory: int | None = None
    #: the start event is the arming source (CNT-90 series Programmer's Handbook,
    #: :ARM:SOURce): the profile's `trigger_source` word sets and reports ARM:SOUR
    start_by_arming: bool = False
    #: ASCII replies carry FORMat ASCii,<digits> (less the one before the point), not the
    #: profile's reply_digits (53230A Programmer's Reference, FORMat[:DATA])
    digits_from_format: bool = False
    #: FORMat REAL as the 53230A writes it: FORM:BORD honoured, and FETC?/READ? answer an
    #: indefinite-length block `#0` (else big-endian doubles, definite-length, CNT-91)
    real_as_53230a: bool = False
    #: SENS:ROSC:SOUR choices; `reference_checked_on_select`: EXT with no valid signal
    #: at the reference input is the selection's own error (-241; CNT-91, unverified)
    reference_sources: tuple[str, ...] = ("INTernal", "EXTernal")
    reference_checked_on_select: bool = False
    #: the words users' own scripts send beyond the profile's (sims/counter_twin.py
    #: SCRIPT_WORDS: the 53230A's public clients', PyMeasure's CNT-91 driver's)
    script_words: str | None = None


KEYSIGHT_53230A_TWIN = TwinProfile(
    error_code_format="{:+d}", rst_function="periods", rst_invert=True,
    reading_memory=KEYSIGHT_53230A_MEMORY, digits_from_format=True, real_as_53230a=True,
    script_words="keysight-53230a")

TWIN_PROFILES: dict[str, TwinProfile] = {
    "keysight-53230a": KEYSIGHT_53230A_TWIN,
    # the 53230A's words, answered as the generic counter answers them but for its errors
    "keysight-53220a": TwinProfile(error_code_format="{:+d}"),
    "pendulum-cnt-91": TwinProfile(
        start_by_arming=True, reference_sources=("INTernal", "EXTernal", "AUTO"),
        reference_checked_on_select=True, script_words="pendulum-cnt-91"),
}


def twin_profile(profile: CounterProfile) -> TwinProfile:
    """The twin's behaviour for `profile`'s model (the generic counter's if it has none)."""
    return TWIN_PROFILES.get(profile.model, TwinProfile())
