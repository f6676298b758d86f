"""A lab of many benches on one PostgreSQL server (issue 44; docs/station.md).

Each bench keeps its run directory as the evidence and a small outbox beside it
(`outbox.py`: how far each run's event log has been delivered to which lab database),
and delivers to the lab's database when it can (`sync.py`): in the background while a run
runs, at its end, and by `bench records sync`. Every event line is stored under (bench,
run, line number), so a delivery repeated after an outage, a killed bench or a server
restart adds nothing and loses nothing. The station follows the deliveries through
PostgreSQL's LISTEN/NOTIFY (`CHANNEL`); a bench never opens a port and needs no broker.

Modules: `outbox.py` (the cursors), `journal.py` (reading new event lines), `health.py`
(what the bench samples of its instruments for the station), `sync.py` (the delivery),
`live.py` (the background delivery of a running run).
"""

from __future__ import annotations

#: the PostgreSQL notification channel a delivery signals on; its payload names the bench,
#: the run and the last sequence number delivered (JSON)
CHANNEL = "bench_fleet"
