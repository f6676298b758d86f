"""result.json's `instruments` and `certificate` blocks decoded into the core's types
(bench/core/settings_codec.py): what is there is read as written, a wrong type is refused
naming its key path in result.json's terms, and the lab comes out as the lab file said.

Truth: the demo run's `certificate` block (configs/procedures/demo.yaml's lab settings as
its result.json carries them), written out here."""

from __future__ import annotations

from pathlib import Path

import pytest

from bench.core.lab import LabError, run_lab
from bench.core.settings_codec import identities, lab_keys
from bench.core.traceability import identity_problems, with_declared_serials

CERTIFICATE = {
    "laboratory": "Rate Table Metrology Lab (demo)",
    "address": "1 Example Street, 00000 Demo City, Nowhere",
    "accreditation": "not accredited (demonstration laboratory)",
    "signatories": [
        {"name": "A. Ivanova", "function": "Calibration engineer (performed the calibration)"},
        {"name": "P. Petrov", "function": "Technical manager (authorised signatory)",
         "authorises": True}],
    "customer": "Demo customer", "lab": "lab.yaml"}


def test_the_certificate_block_gives_the_lab_it_names(tmp_path: Path) -> None:
    lab = run_lab(tmp_path, lab_keys(CERTIFICATE))
    assert lab.name == "Rate Table Metrology Lab (demo)"
    assert lab.address == "1 Example Street, 00000 Demo City, Nowhere"
    assert [s.name for s in lab.authorisers()] == ["P. Petrov"]
    assert lab.signatories[0].function == "Calibration engineer (performed the calibration)"
    assert lab.prefix == "RT" and lab.performance_location == "laboratory"
    assert not lab.require_signed_dcc and lab.signing is None
    # a choice the DCC does not list is read as written: the DCC's schema refuses it
    moon = run_lab(tmp_path, lab_keys({**CERTIFICATE, "performance_location": "on the moon"}))
    assert moon.performance_location == "on the moon"
    # no laboratory named: the run's lab file copy is the run's (none here: the defaults)
    assert lab_keys({"customer": "Demo customer"}) is None
    assert run_lab(tmp_path, None).name is None


def test_a_wrong_type_in_the_certificate_block_is_named_by_its_key_path() -> None:
    bad = {**CERTIFICATE, "signatories": [{"name": 7}]}
    with pytest.raises(LabError, match=r"result\.json: certificate\.signatories\[0\]\.name: "
                                       r"Expected `str`, got `int`"):
        lab_keys(bad)


def test_identities_are_read_as_reported_and_checked_for_serials() -> None:
    found = identities({"outer": {
        "counter": "Keysight Technologies,53230A,MY62000117,03.02",
        "fog": "KVH DSP-1760; format kvh-a"}})
    assert found == {"outer": {"counter": "Keysight Technologies,53230A,MY62000117,03.02",
                               "fog": "KVH DSP-1760; format kvh-a"}}
    assert identity_problems(found) == ["the fog of outer reported no serial number"]
    stand = {"axes": {"outer": {"fog": {"serial": "1760-20231"}}}}
    declared = with_declared_serials(found, stand)
    assert "serial 1760-20231 (as the stand file states" in declared["outer"]["fog"]
    assert identity_problems(declared) == []
    with pytest.raises(ValueError, match=r"result\.json: instruments.*Expected `str`"):
        identities({"outer": {"counter": None}})
