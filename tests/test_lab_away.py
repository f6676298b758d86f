"""While the lab database is away (issue 57, item 6) the station and the bench say so in
words, never a driver's exception text: the lab page says what it cannot know ("Unknown
while the lab database is away", not "No draft waiting"), a run's page answers 503 with
the reason, and a bench's console says when the link goes down and when it is back. A real
PostgreSQL server (tests/pg_server.py) whose database is made unreachable and back."""

from __future__ import annotations

import json
from pathlib import Path

from bench.app.fleet.courier import Courier
from bench.app.fleet.outbox import Outbox
from bench.app.fleet.sync import LabLink
from bench.core.journal import RunDir
from tests.pg_server import PgServer
from tests.test_fleet import RECORDED, _lab, _recorded_run

RAW_WORDS = ("OperationalError", "psycopg", "sqlalche", "Traceback")


def test_the_lab_page_and_a_bench_say_in_words_that_the_lab_database_is_away(
        pg: PgServer, tmp_path: Path) -> None:
    from bench.app.station.app import StationSettings, create_app

    name = "away_lab"
    url = _lab(pg, name)
    runs = tmp_path / "runs"
    run = _recorded_run(runs, events=(RECORDED / "events.jsonl").read_bytes())
    with LabLink(url) as link:
        link.deliver(run, Outbox(runs, url), "bench-w")
    app = create_app(StationSettings(runs=tmp_path / "none", token="t", records_url=url))
    client = app.test_client()
    (shown,) = client.get("/api/fleet").get_json()
    page = client.get("/").get_data(as_text=True)
    assert "No draft waiting." in page and "Unknown while" not in page
    said: list[str] = []
    courier = Courier(RunDir(run), url, "bench-w", said.append)
    try:
        pg.block(name)
        page = client.get("/").get_data(as_text=True)
        assert "Unknown while the lab database is away." in page, page
        assert "No draft waiting" not in page
        assert f"the lab database {url} is away: the server accepts no connections to " \
               "this database now" in page, page
        assert not any(w in page for w in RAW_WORDS), page
        gone = client.get(f"/bench/bench-w/{shown['uid']}")
        text = gone.get_data(as_text=True)
        assert gone.status_code == 503 and "Unknown while the lab database is away" in text
        assert not any(w in text for w in RAW_WORDS), text
        assert courier.deliver(register=False) is False
        assert len(said) == 1 and said[0].startswith(f"WARNING: the lab database {url} is away")
        assert not any(w in said[0] for w in RAW_WORDS), said
        assert courier.deliver(register=False) is False and len(said) == 1   # warned once
    finally:
        pg.unblock(name)
    assert courier.deliver(register=False) is True
    assert said[-1] == "lab database: link back; what the outage held back is delivered"
    page = client.get("/").get_data(as_text=True)
    assert "No draft waiting." in page and "is away" not in page
    assert json.loads(json.dumps(client.get("/api/fleet").get_json()))[0]["uid"] == shown["uid"]
    courier.link.close()
