"""The analysis's typed result and result.json (issue 60): the session writes the file from
the result and hands the result itself to the certificate, the records and the register,
so what they read in memory must be what a reader of the file gets back."""

from __future__ import annotations

import json
import math

import msgspec
import numpy as np
import pytest

from bench.core.journal_codec import encode_document
from bench.report.certificate.sources import Sources
from bench.report.codec import (
    KindResult,
    ProcedureFileRef,
    RawFile,
    ResultHead,
    RunDates,
    encode,
)
from procedures.rate_ladder.codec import ladder_model, ladder_of
from procedures.rate_ladder.result import (
    ConditionsMeasured,
    LadderBody,
    LadderCheck,
    PairEntry,
)
from procedures.rate_ladder.sample import rate_ladder_result


def _head(checks: tuple[LadderCheck, ...] = (), conditions: dict[str, object] | None = None
          ) -> ResultHead:
    return ResultHead(
        schema="bench.result/1", uncertainty_names="U", procedure="rate-ladder",
        verdict="pass", title="t", run_dir="r", procedure_file=ProcedureFileRef("p", "0"),
        stand={"serial": "S-1", "simulated": True}, instruments={"outer": {"fog": "F 1"}},
        dates=RunDates("2026-11-30T00:00:00Z", None, None),
        conditions=conditions or {}, specification=None,  # type: ignore[arg-type]
        certificate={}, sessions=1, aborted=False, ended="completed", run_sessions=[],
        raw_files=[RawFile("raw/s1/a", "ab", 3)], decision_rule="simple",
        decision_rule_text="x", method={"tolerance": {"k_rel": 1e-05}}, checks=checks)


def _body() -> LadderBody:
    return LadderBody(axes=ladder_of(encode(rate_ladder_result())).axes,
                      conditions_measured=ConditionsMeasured(None))


def test_the_document_is_what_the_file_reads_back() -> None:
    checks = (LadderCheck(axis="outer", set_rate_dps=10.0, quantity="rate_error",
                          value_rel=1e-05, u_rel=math.nan, tolerance_rel=1e-4, rule="simple",
                          verdict="pass", reason="r", capability_ratio=0.1,
                          capability_ok=True),)
    result = KindResult(_head(checks, conditions={1: "room"}), _body())  # type: ignore[dict-item]
    text = encode_document(result.document)
    # in memory as on disk: same keys (a YAML number key as text), lists, NaN as null
    assert json.loads(text) == result.document
    assert encode_document(json.loads(text)) == text
    assert result.document["conditions"] == {"1": "room"}
    assert result.document["checks"][0]["U_rel"] is None          # type: ignore[index]
    assert '"value_rel": 1e-05' in text     # json.dumps' float form, not msgspec's 0.00001
    # the frame first in CONTRACT §3's order, then the kind's body in its Struct's order
    keys = list(result.document)
    assert keys[:4] == ["schema", "uncertainty_names", "procedure", "verdict"]
    assert keys[-4:] == ["method", "checks", "axes", "conditions_measured"]
    assert "corrections" not in keys       # unset: absent, the document as before
    assert result.frame.verdict == "pass" and result.frame.stand["serial"] == "S-1"


def test_the_certificate_takes_the_analysed_model_and_decodes_one_that_is_not_as_written(
        ) -> None:
    result = KindResult(_head(), _body())
    src = Sources.analysed(result, None)
    assert ladder_model(src).axes is result.body.axes      # no decode of its encoding
    assert ladder_model(src).axes == ladder_of(result.document).axes
    # a NaN the file cannot hold: the model decoded from the document instead (null)
    axis = result.body.axes["outer"]
    odd = msgspec.structs.replace(axis, pairs=(PairEntry(rate_dps=10.0, k=math.nan),))
    nan = KindResult(_head(), LadderBody(axes={"outer": odd}))
    decoded = ladder_model(Sources.analysed(nan, None))
    assert decoded.axes["outer"].pairs[0].k is None


def test_the_drift_certificate_takes_the_analysed_figures() -> None:
    """The drift kind as the ladder: its certificate and DCC read the analysis's own
    figures (no decode of their encoding) when they hold what result.json holds, and
    result.json's decoded figures otherwise (a NaN: null in the file)."""
    from procedures.drift_pulse.codec import drift_model, drift_of
    from procedures.drift_pulse.result import DriftBody
    from procedures.drift_pulse.sample import drift_figures

    head = msgspec.structs.replace(_head(), procedure="drift-pulse")
    figures = drift_of({"drift": encode(drift_figures())})
    result = KindResult(head, DriftBody(drift=figures))
    src = Sources.analysed(result, None)
    assert src.model(drift_model) is figures                # no decode of its encoding
    assert drift_of(result.document) == figures             # and what the file reads back
    axis = next(iter(figures.axes))
    first = figures.axes[axis]
    field = next(f for f in first.__struct_fields__ if type(getattr(first, f)) is float)
    # a numpy number (what an analysis may leave in): the figures decoded from the file
    np_axis = msgspec.structs.replace(first, **{field: np.float64(getattr(first, field))})
    np_figures = msgspec.structs.replace(figures, axes={**figures.axes, axis: np_axis})
    decoded = Sources.analysed(KindResult(head, DriftBody(drift=np_figures)),
                               None).model(drift_model)
    assert decoded is not np_figures and decoded == figures
    assert type(getattr(decoded.axes[axis], field)) is float


def test_the_frame_in_memory_is_the_files() -> None:
    """An analysis's frame is its head's and body's own attributes (no encoding in
    between): field for field the frame a reader of result.json gets, with the same
    records' figures; a head the file cannot hold as it is (a number key) is read from
    its encoding instead."""
    from bench.app.records.extract import figures_of
    from bench.report.result_frame import ResultFrame
    from procedures.drift_pulse.codec import drift_in, drift_of
    from procedures.drift_pulse.result import DriftBody
    from procedures.drift_pulse.sample import drift_figures
    from procedures.rate_ladder.codec import axes_in

    def bare(frame: ResultFrame) -> ResultFrame:
        return msgspec.structs.replace(frame, doc={}, body=None, checks=tuple(
            msgspec.structs.replace(c, doc={}) for c in frame.checks))

    check = LadderCheck(axis="outer", set_rate_dps=10.0, quantity="rate_error",
                        value_rel=1e-05, u_rel=2e-06, tolerance_rel=1e-4, rule="simple",
                        verdict="pass", reason="r", capability_ratio=0.1, capability_ok=True)
    ladder = KindResult(_head((check,), conditions={"room": "lab"}), _body())
    drift_head = msgspec.structs.replace(_head(), procedure="drift-pulse")
    drift = KindResult(drift_head, DriftBody(drift=drift_of({"drift": encode(
        drift_figures())})))
    for result, kind in ((ladder, "rate-ladder"), (drift, "drift-pulse")):
        typed = result.frame
        assert typed.body is result.body                  # not decoded from the document
        read = ResultFrame.of(json.loads(encode_document(result.document)))
        assert read.body is None and bare(typed) == bare(read)
        assert figures_of(typed, kind) == figures_of(read, kind) != []
        for c, d in zip(typed.checks, read.checks, strict=True):
            assert [(k, c.figure(k)) for k in c.doc] == [(k, d.figure(k)) for k in d.doc]
            assert c.tolerance == d.tolerance == 1e-4
    assert axes_in(ladder.frame) is ladder.body.axes
    assert drift_in(drift.frame) is drift.body.drift
    assert bare(ladder.frame).checks[0].set_rate_dps == 10.0
    odd = KindResult(_head(conditions={1: "room"}), _body())  # type: ignore[dict-item]
    assert odd.frame.body is None and odd.frame.conditions == {"1": "room"}


def test_the_certificate_in_memory_is_the_files(monkeypatch: pytest.MonkeyPatch) -> None:
    """The certificate of a result as its analysis gave it (its frame, body and budgets
    read by attributes, nothing decoded: every decoder refuses to run) is the certificate
    of its result.json, page for page, for both kinds; its budgets the same, read from the
    model or the file."""
    import datetime as dt

    import bench.report.budget_codec
    import bench.report.result_frame
    import procedures.drift_pulse.codec
    import procedures.rate_ladder.codec
    from bench.app.certificate.build import build_document
    from bench.app.certificate.html import render_html
    from bench.report.budget import Budget, Term
    from bench.report.budget_codec import budget_sites
    from procedures.drift_pulse.codec import drift_of
    from procedures.drift_pulse.result import DriftBody
    from procedures.drift_pulse.sample import drift_pulse_result

    ladder, drift = rate_ladder_result(), drift_pulse_result()
    budget = Budget("rate error", "rate_error_rel", "1", 0.0, (
        Term("timing", None, 1e-6, "normal", 1.0, 8, "1"),
        Term("timebase", 2e-7, 5e-7, "rectangular", 1.0)), 2.1e-6, "n", ((0, 1, 0.5),))
    axes = _body().axes
    outer = axes["outer"]
    first = msgspec.structs.replace(outer.rates[0], budgets=(budget.record(),))
    body = LadderBody(axes={**axes, "outer": msgspec.structs.replace(
        outer, rates=(first, *outer.rates[1:]))})
    results = (KindResult(msgspec.structs.replace(_head(), method=ladder.method,
                                                  checks=ladder.checks), body),
               KindResult(msgspec.structs.replace(_head(), procedure="drift-pulse",
                                                  method=drift.method),
                          DriftBody(drift=drift_of({"drift": encode(drift.drift)}))))
    decoders = ((bench.report.result_frame, "decode"), (procedures.rate_ladder.codec, "decode"),
                (procedures.rate_ladder.codec, "ladder_of"),
                (procedures.drift_pulse.codec, "drift_of"),
                (bench.report.budget_codec, "budget_from_json"))

    def refused(*args: object, **kwargs: object) -> None:
        raise AssertionError("decoded between the analysis and the certificate")

    issued = dt.date(2025, 3, 6)
    for result in results:
        with monkeypatch.context() as m:
            for module, name in decoders:
                m.setattr(module, name, refused)
            src = Sources.analysed(result, None)
            assert src.frame is result.frame and src.walked is result.body
            in_memory = render_html(build_document(src, issued))
        read = Sources.load(json.loads(encode_document(result.document)), None)
        assert read.walked is read.result and read.frame.body is None
        assert budget_sites(result.body) == budget_sites(read.result)
        assert in_memory == render_html(build_document(read, issued))
    (site,) = budget_sites(results[0].body)
    assert site[:2] == ("axis outer, +10 °/s", "axes.outer.rates[0]") and site[2] == budget
