"""The journal's typed events (bench/core/events.py, issue 61): one declaration per kind,
the line on disk as it was before the records were typed, older and unknown lines kept."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from bench.core import events as ev
from bench.core.journal import RunDir
from procedures.drift_pulse.events import Cycle, DmmSetup
from procedures.rate_ladder.events import HalfAcquired, PairLooked, Settled

ROOT = Path(__file__).resolve().parents[1]

#: lines as bench 0.1.0 wrote them before the records were typed (the demo of 29 Nov 2026,
#: shortened), each with the record class it must read back as
WRITTEN = [
    ('{"utc":"2026-11-29T12:38:14.101+00:00","t_s":0.0,"session":1,"event":"session_start",'
     '"resume":false,"sim":true,"done_units":[],"clock_speed":100.0,"argv":["run","d.yaml"],'
     '"version":"0.1.0","prompts":"--yes","pid":4242,"performer":null,"os_user":"op"}',
     ev.SessionStarted),
    ('{"utc":"2026-11-29T12:38:15.000+00:00","t_s":1.5,"session":1,"event":"identity",'
     '"axis":"outer","counter":"Keysight,53230A,MY1,1.0","fog":"KVH,DSP-1760,F1,2",'
     '"counter_reference":"EXT 10 MHz"}', ev.Identity),
    ('{"utc":"2026-11-29T12:38:20.000+00:00","t_s":40.25,"session":1,"event":"settled",'
     '"axis":"outer","unit":"outer/10dps","rate_dps":-10.000001}', Settled),
    ('{"utc":"2026-11-29T12:38:30.000+00:00","t_s":90.0,"session":1,"event":"pair",'
     '"axis":"outer","unit":"outer/10dps","k":1.0003,"k_u":4e-06,"w0_dps":0.002,'
     '"w0_u_dps":4e-05,"rate_error_rel+":-1e-07,"rate_error_u_rel+":3e-08,'
     '"rate_error_rel-":2e-07,"rate_error_u_rel-":3e-08,"directions":[{"set_rate_dps":10.0,'
     '"turns":4,"rate_error_rel":-1e-07,"rate_error_U_rel":6e-08,'
     '"rate_instability_rel":3e-08,"verdict":"pass"}]}', PairLooked),
    ('{"utc":"2026-11-29T12:39:00.000+00:00","t_s":120.0,"session":1,"event":"dmm_setup",'
     '"gyro":"x","range_v":10.0,"aperture_s":0.001,"interval_s":0.01,"count":5,'
     '"trigger_delay_s":0.0,"slope":"POS"}', DmmSetup),
    ('{"utc":"2026-11-29T12:39:10.000+00:00","t_s":130.0,"session":2,"event":"exit",'
     '"status":3,"cause":"interrupted by SIGINT","later":["drive outer: no answer"]}',
     ev.Exited),
]


@pytest.mark.parametrize("line,cls", WRITTEN, ids=[c.__name__ for _, c in WRITTEN])
def test_a_written_line_reads_as_its_record_and_writes_back_byte_for_byte(
        line: str, cls: type[ev.Event]) -> None:
    record = ev.decode(json.loads(line))
    assert type(record) is cls
    # the journal writes with these separators (bench/core/journal.py JsonLines.write)
    assert json.dumps(ev.encode(record), separators=(",", ":")) == line


def test_fields_are_typed_as_declared() -> None:
    pair = ev.decode(json.loads(WRITTEN[3][0]))
    assert isinstance(pair, PairLooked)
    assert (pair.k, pair.k_U, pair.rate_error_minus_rel) == (1.0003, 4e-06, 2e-07)
    assert pair.directions[0].rate_error_U_rel == 6e-08 and pair.session == 1
    ident = ev.decode(json.loads(WRITTEN[1][0]))
    assert isinstance(ident, ev.Identity)
    assert ident.instruments == {"counter": "Keysight,53230A,MY1,1.0",
                                 "fog": "KVH,DSP-1760,F1,2",
                                 "counter_reference": "EXT 10 MHz"}


def test_an_unknown_kind_is_kept_as_written_and_a_malformed_one_names_its_field() -> None:
    line = {"utc": "2026-11-29T12:00:00+00:00", "t_s": 3.0, "session": 2,
            "event": "from_a_newer_bench", "x": [1, 2]}
    unknown = ev.decode(line)
    assert isinstance(unknown, ev.Unrecognised) and unknown.name == "from_a_newer_bench"
    assert ev.plain(unknown) == line and (unknown.session, unknown.t_s) == (2, 3.0)
    bad = ev.decode({"event": "settled", "session": 1, "axis": "outer",
                     "unit": "outer/10dps", "rate_dps": "ten"})
    assert isinstance(bad, ev.Malformed) and bad.name == "settled"
    assert "rate_dps" in bad.problem and bad.session == 1
    assert ev.of_kind([unknown, bad], Settled) == []


def test_a_run_journals_typed_records_and_reads_them_back(tmp_path: Path) -> None:
    cfg = ROOT / "configs" / "procedures" / "demo.yaml"
    stand = ROOT / "configs" / "stands" / "sim-two-axis.yaml"
    run = RunDir.create(tmp_path, cfg, stand)
    run.begin_session(lambda: 12.5)
    run.write(ev.StepStarted(index=0, action="settle", axis="outer", unit="outer/10dps"))
    run.write(Cycle(unit="c1", position_deg=0.0, actual_deg=0.001, timing=False,
                    amplitude_v=1.0, t_trigger_s=3.0, fetch={"x": 1}, samples=5,
                    interval_s=0.01, first_sample_s=0.0, tc_s=0.5))
    run.close()
    got = RunDir(run.path).events()
    assert [type(e) for e in got] == [ev.StepStarted, Cycle]
    assert all(e.session == 1 and e.t_s == 12.5 and e.utc for e in got)
    line = json.loads((run.path / "events.jsonl").read_text().splitlines()[0])
    assert list(line)[:4] == ["utc", "t_s", "session", "event"]
    assert ev.of_kind(got, HalfAcquired) == []


def test_every_kind_is_declared_once() -> None:
    ev.declared("load every kind")          # imports each installed kind's events module
    tags = [ev.kind_of(c) for c in _all(ev.Event) if ev.kind_of(c) != c.__name__]
    assert len(tags) == len(set(tags)), sorted(tags)
    assert {"session_start", "pair", "acquire", "cycle", "dmm_setup"} <= set(tags)


def _all(cls: type[ev.Event]) -> list[type[ev.Event]]:
    return [c for sub in cls.__subclasses__() for c in (sub, *_all(sub))]


def test_no_journal_reader_outside_the_codec_tests_a_kind_by_its_name() -> None:
    """`e.get("event") == "x"` gone from bench/ and procedures/: a reader tests the record's
    class, so a renamed field or kind fails mypy, not a page at run time."""
    pattern = re.compile(r"""(\.get\(\s*["']event["']|\[\s*["']event["']\s*\])""")
    found = [f"{p.relative_to(ROOT)}:{n}" for base in ("bench", "procedures")
             for p in sorted((ROOT / base).rglob("*.py")) if p.name != "events.py"
             or p.parent.name != "core"
             for n, text in enumerate(p.read_text(encoding="utf-8").splitlines(), 1)
             if pattern.search(text)]
    assert found == []


def test_the_station_shows_the_events_each_kind_flags_a_plugin_kinds_too(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """Which events the station's log shows is read off the declarations
    (`Event.STATION_LOG`), not listed in bench/: tests/plugin_kind (a third kind, loaded as
    an installed kind's events are) flags its `dwelt`, and the live page's filter and the
    fleet's query take it in with no change to bench/."""
    from bench.app.station import fleet
    monkeypatch.setattr(ev, "registered", lambda: {"dwell": "tests.plugin_kind:KIND"})
    monkeypatch.setattr(ev, "_PLUGINS_LOADED", False)
    assert "dwelt" in ev.station_log_kinds()
    assert "dwelt" in fleet.log_kinds() and "dwelt" in fleet.kinds_read()
    assert ev.decode({"event": "dwelt", "waited_s": 1.0}).STATION_LOG
    # the ladder's flagged and unflagged records, and the kind-neutral ones, as before
    assert {"pair", "pair_failed", "settled", "exit", "abort"} <= set(fleet.log_kinds())
    assert not {"acquire", "static", "cycle", "plan"} & set(fleet.log_kinds())
    assert {"plan", "step_start", "step_done", "session_lost"} <= set(fleet.kinds_read())
