"""The certificate's inputs decoded at the boundary (issue 60): the procedure's tolerances,
the certificate settings under the register's issuer, the corrections a result states and
its budgets' places, each checked against the document it was decoded from."""

from __future__ import annotations

import json

import msgspec

from bench.report.budget_codec import budget_sites
from bench.report.result_frame import (
    CertificateSettings,
    MeasuredHalf,
    Tolerance,
    corrections_of,
)


def test_tolerances_keep_bands_in_order_and_absolute_values() -> None:
    doc = json.loads('{"rate_error": [{"below_dps": 1, "rel": 0.001}, "junk", {"rel": 1e-4}],'
                     ' "own_drift_dph": 0.5, "bias": "n/a"}')
    rate, drift, bias = Tolerance.all_of(doc)
    assert rate.quantity == "rate_error" and rate.value is None
    assert [(b.below_dps, b.rel) for b in rate.bands] == [(1.0, 0.001), (None, 1e-4)]
    assert (drift.quantity, drift.value, drift.bands) == ("own_drift_dph", 0.5, ())
    assert (bias.value, bias.bands) == (None, ())
    assert Tolerance.all_of([1, 2]) == ()


def test_issuer_identity_replaces_the_files_and_keeps_the_rest_in_order() -> None:
    files = {"laboratory": "File Lab", "code": "F1", "customer": "ACME", "site": "Hall 2"}
    plain = CertificateSettings.of(files)
    assert (plain.laboratory, plain.customer, plain.site) == ("File Lab", "ACME", "Hall 2")
    issued = CertificateSettings.of(files, (("laboratory", "Register Lab"),))
    assert issued.laboratory == "Register Lab" and issued.address is None
    assert [k for k, _ in issued.entries] == ["customer", "site", "laboratory"]
    assert CertificateSettings.of("no mapping") == CertificateSettings()


def test_corrections_read_as_stated() -> None:
    doc = {"corrections": [{"where": "axes.outer.counter", "serial": "C-1", "quantity":
                            "timebase_offset_rel", "value": 1e-7, "U": 2e-8, "reason": " "},
                           "junk", {"value": True}]}
    first, second = corrections_of(doc)
    assert (first.where, first.serial, first.value, first.value_U, first.reason) == \
        ("axes.outer.counter", "C-1", 1e-7, 2e-8, None)
    assert (second.where, second.quantity, second.value) == ("?", "?", None)
    assert corrections_of({"corrections": None}) == ()


def test_budget_sites_name_axis_rate_and_owner_path() -> None:
    term = {"quantity": "timing", "estimate": None, "ustd": 1e-6, "distribution": "normal",
            "sensitivity": 1.0, "dof": None, "unit": "1"}
    budget = {"quantity": "rate error", "key": "rate_error_rel", "unit": "1", "estimate": 0.0,
              "terms": [term], "U_reported": 2e-6}
    doc = {"axes": {"outer": {"rates": [{"set_rate_dps": -10, "budgets": [budget]}]}},
           "budgets": [budget, {"terms": "broken"}]}
    sites = budget_sites(doc)
    assert [(where, owner) for where, owner, _ in sites] == \
        [("axis outer, -10 °/s", "axes.outer.rates[0]"), ("overall", "")]
    assert sites[0][2].terms[0].ustd == 1e-6 and sites[0][2].reported_U == 2e-6


def test_the_frame_drops_and_names_a_malformed_container_and_keeps_the_rest() -> None:
    """result.json's frame read leniently: a container of the wrong type is dropped and
    named (a mapping's key too, which msgspec does not name), a leaf of the wrong type
    reads "not stated" unnamed, null is absent; strictly, the first container refused."""
    import pytest

    from bench.report.result_frame import MalformedResult, ResultFrame

    doc = {"verdict": 5, "title": "T", "instruments": {"outer": {"fog": "F"}, "inner": "x"},
           "raw_files": [{"path": "a", "bytes": 3}, 7], "conditions": None,
           "checks": [{"axis": "outer", "value_rel": 0.5, "set_rate_dps": 10}, "junk"],
           "conditions_measured": {"fog_temperature": {"axes": {"outer": {
               "min_c": 20, "halves": [{"half": 0, "mean_c": 21.5}]}, "inner": []}}}}
    frame, dropped = ResultFrame.conform(doc)
    assert dropped == ["instruments.inner (expected a mapping, found str)",   # in its order
                       "raw_files[1] (expected a mapping, found int)",
                       "checks[1] (expected a mapping, found str)",
                       "conditions_measured.fog_temperature.axes.inner (expected a mapping, "
                       "found list)"]
    assert (frame.verdict, frame.title, frame.conditions) == (None, "T", None)
    assert frame.instruments == {"outer": {"fog": "F"}}
    assert [(f.path, f.size_bytes) for f in frame.raw_files] == [("a", 3.0)]
    (check,) = frame.checks
    assert (check.axis, check.set_rate_dps, check.figure("value_rel")) == ("outer", 10, 0.5)
    assert type(check.set_rate_dps) is int               # an int stays an int
    assert frame.conditions_measured.fog_axes["outer"].min_c == 20
    assert frame.conditions_measured.fog_halves == {
        "outer": (msgspec.convert({"half": 0, "mean_c": 21.5}, MeasuredHalf),)}
    assert doc["instruments"]["inner"] == "x" and frame.doc["verdict"] == 5  # as read
    with pytest.raises(MalformedResult, match=r"^result.json: instruments.inner expected "
                                              "a mapping, found str$"):
        ResultFrame.from_json(doc)
    assert ResultFrame.from_json({"verdict": 5}).verdict is None
    assert ResultFrame.conform([1]) == (ResultFrame(), ["result.json (expected a mapping)"])
