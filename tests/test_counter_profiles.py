"""Counter profiles as data: reply formats both ways, and the pyvisa-sim static instruments."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from drivers.counter import Counter, CounterCommandError
from drivers.counter_profiles import (
    PROFILES,
    TIMESTAMP_FORMATS,
    get_profile,
    nr3,
)
from drivers.profiles import PYVISA_SIM_COUNTERS, profile_path
from drivers.scpi import parse_numbers
from sims.clock import VirtualClock


def test_nr3_as_keysight_prints_it():
    assert nr3(1.293838282e-6, 14, 3) == "+1.29383828200000E-006"
    assert nr3(-0.36, 3, 2) == "-3.600E-01"


@settings(max_examples=50, deadline=None)
@given(st.sampled_from(sorted(TIMESTAMP_FORMATS)),
       st.floats(0.0, 3.6e4), st.lists(st.floats(1e-3, 3.6e3), min_size=1, max_size=20))
def test_timestamp_formats_round_trip(name, t0, gaps):
    fmt = TIMESTAMP_FORMATS[name]
    edges = t0 + np.cumsum(gaps)
    t_start = 0.5 * t0
    values = parse_numbers(fmt.encode(edges, t_start, 16, 3))
    assert values.size == fmt.n_values(edges.size)
    # both formats give times since the start event (the time tie places that event)
    np.testing.assert_allclose(fmt.decode(values), edges - t_start, rtol=1e-13, atol=1e-12)


def test_decoders_refuse_what_would_give_wrong_periods():
    with pytest.raises(ValueError, match="prescaler 13"):
        TIMESTAMP_FORMATS["keysight-tst"].decode(np.array([13, 1.0, 2.0]))
    # the X counter counts crossings (CNT-90 Programmer's Handbook p. 8-72), not stamps: a
    # steady step is the counter's way of counting, a step that changes is a missed stamp
    with pytest.raises(ValueError, match="steps by 2 after timestamp 2 .*edges were missed"):
        TIMESTAMP_FORMATS["pendulum-stst"].decode(np.array([1, 1.0, 2, 2.0, 4, 4.0]))
    np.testing.assert_array_equal(
        TIMESTAMP_FORMATS["pendulum-stst"].decode(np.array([7, 1.0, 9, 2.0, 11, 3.0])),
        [1.0, 2.0, 3.0])
    with pytest.raises(ValueError, match="interval 2 is -1"):
        TIMESTAMP_FORMATS["keysight-tst"].decode(np.array([1, 1.0, -1.0]))
    with pytest.raises(ValueError, match="pairs"):
        TIMESTAMP_FORMATS["pendulum-stst"].decode(np.array([1, 1.0, 2]))


def test_profile_lookup_names_the_known_models():
    assert get_profile(" Keysight-53230A ") is PROFILES["keysight-53230a"]
    with pytest.raises(KeyError, match="unknown counter model 'hp-5335a'.*pendulum-cnt-91"):
        get_profile("hp-5335a")


def test_quantise_to_the_resolution():
    p = PROFILES["keysight-53230a"]
    np.testing.assert_allclose(p.quantise(np.array([1.000000000009, 2.0000000000311])),
                               [1.0, 2.00000000004], rtol=0, atol=1e-15)


@pytest.mark.timeout(20)
@pytest.mark.parametrize("model,resource", [
    ("keysight-53230a", "TCPIP0::127.0.0.1::5025::SOCKET"),
    ("pendulum-cnt-91", "GPIB0::10::INSTR"),
    ("generic-scpi-period", "ASRL1::INSTR"),
])
def test_pyvisa_sim_static_counters_open_and_identify(model, resource):
    lib = f"{profile_path(PYVISA_SIM_COUNTERS)}@sim"      # package data, as installed
    with Counter.open(resource, model, VirtualClock(1.0), visa_library=lib) as counter:
        assert counter.identify() == PROFILES[model].idn      # the twin's identity too
        assert counter.drain_errors() == []
        with pytest.raises(CounterCommandError, match=r"'CONF:PERX'.*-113"):
            counter.write("CONF:PERX")


def test_capabilities_name_what_a_model_cannot_do():
    """What `bench validate` needs to name a missing capability (issue 41)."""
    k, c, g = (PROFILES[m] for m in ("keysight-53230a", "pendulum-cnt-91",
                                     "generic-scpi-period"))
    assert (k.supports_timestamps, k.has_reference_source, k.has_reference_check,
            k.has_external_trigger, k.has_measurement_timeout) == (True,) * 5
    assert (c.supports_timestamps, c.has_reference_source, c.has_reference_check,
            c.has_external_trigger, c.has_measurement_timeout) == (True, True, False,
                                                                   True, False)
    assert c.external_trigger == "EXT4" and k.external_trigger == "EXT"
    assert not (g.supports_timestamps or g.has_reference_source or g.has_external_trigger)
    for p in (k, c):
        assert p.missing_capabilities(timestamps=True, reference="external",
                                      time_tie="fog-sync") == []
    missing = g.missing_capabilities(timestamps=True, reference="internal",
                                     time_tie="fog-sync")
    assert [key for key, _ in missing] == ["model", "reference", "time_tie"]
    assert "supports_timestamps" in missing[0][1] and "has_external_trigger" in missing[2][1]
    assert g.missing_capabilities(time_tie="host-clock") == []
