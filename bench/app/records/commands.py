"""`bench history`, `bench records import`, `bench records sync`, `bench due`
(CONTRACT §1)."""

from __future__ import annotations

import argparse
import csv
import sys
from collections.abc import Callable
from pathlib import Path

from bench.app import labfile
from bench.app.db import redact
from bench.app.names import DEFAULT_RUNS
from bench.app.records.extract import NotARun, find_runs, record_of
from bench.app.records.hooks import RecordsTarget, target
from bench.app.records.settings import SettingsError, stray_lab_file
from bench.app.records.store import Records, RecordsError, TrendPoint
from bench.core import rundir_layout as layout
from bench.kind import declared_figures
from bench.report.figures import FigureSpec, spec_for

EXIT_OK, EXIT_FAIL, EXIT_INVALID = 0, 1, 2
CSV_COLUMNS = ("serial", "axis", "quantity", "set_rate_dps", "date_utc", "value", "u",
               "unit", "tolerance", "verdict", "certificate_number", "calibration_state",
               "run_uid")


def _err(text: str) -> None:
    print(text, file=sys.stderr, flush=True)


def _guarded(cmd: Callable[[argparse.Namespace], int]) -> Callable[[argparse.Namespace], int]:
    """A bad lab settings file is invalid input (2); an unreachable database exits 1."""
    def run(args: argparse.Namespace) -> int:
        try:
            return cmd(args)
        except (SettingsError, labfile.LabChoiceError) as e:
            _err(str(e))
            return EXIT_INVALID
        except RecordsError as e:
            _err(str(e))
            return EXIT_FAIL
    return run


def _target(runs: str | Path, records: str | None, lab: str | None) -> RecordsTarget:
    """The records a command reads or writes: --records, else the records: of the lab file
    the command chose (bench/app/labfile.py: --lab, else $BENCH_LAB_SETTINGS), else the
    runs folder's records.sqlite."""
    chosen = labfile.for_command(lab)
    stray = stray_lab_file(runs) if chosen is None and not records else None
    if stray:
        raise labfile.LabChoiceError(stray)
    return target(runs, records, lab_file=chosen)


def _runs_target(folder: str, records: str | None, lab: str | None = None
                 ) -> RecordsTarget | None:
    """The records of a runs folder that must exist (None, said, when it does not)."""
    runs_dir = Path(folder)
    if not runs_dir.is_dir():
        _err(f"{runs_dir}: no such folder")
        return None
    return _target(runs_dir, records, lab)


def cmd_import(args: argparse.Namespace) -> int:
    where = _runs_target(args.runs_dir, args.records, args.lab)
    if where is None:
        return EXIT_INVALID
    runs_dir = where.runs_dir
    counts = {"new": 0, "updated": 0, "unchanged": 0, "skipped": 0}
    with Records.open(where.url) as rec:
        for path in find_runs(runs_dir):
            try:
                record = record_of(path)
            except NotARun as e:
                _err(f"skipped: {e}")
                counts["skipped"] += 1
                continue
            outcome = rec.register(record, where.interval_for(record.serial,
                                                              record.interval_days))
            counts[outcome] += 1
            if outcome != "unchanged":
                print(f"{outcome:<9} {record.serial}  {record.certificate_number}  {path}")
    print(f"records {redact(where.url)}: {counts['new']} new, {counts['updated']} updated, "
          f"{counts['unchanged']} already recorded, {counts['skipped']} skipped")
    return EXIT_OK


def _date(p: TrendPoint) -> str:
    return p.date_utc.isoformat(timespec="seconds") if p.date_utc else ""


def _standing_of(lab: str | None) -> Callable[[str], str | None]:
    """What the lab register says of a certificate number (issued, or withdrawn with its
    reason: issue 55), when the lab file names a register; else nothing is said."""
    import re

    from bench.app.register import Register, RegisterError
    from bench.core.lab import LabError, load_lab

    try:
        chosen = labfile.for_command(lab)
        url = load_lab(chosen).register_url if chosen else None
    except (LabError, labfile.LabChoiceError):
        url = None
    if not url:
        return lambda number: None

    def standing(number: str) -> str | None:
        m = re.fullmatch(r"(.+?)(?:-R(\d+))?", number)
        base, revision = (m.group(1), int(m.group(2) or 1)) if m else (number, 1)
        try:
            with Register.open(url, migrate=False) as reg:
                rev = next((x for x in reg.revisions(base) if x.revision == revision), None)
        except RegisterError as e:
            return f"the register cannot be asked ({e})"
        if rev is None:
            return "not in the lab register"
        if rev.withdrawn_reason:
            return (f"WITHDRAWN {rev.withdrawn_utc} by {rev.withdrawn_by}: "
                    f"{rev.withdrawn_reason}")
        return f"{rev.status} (lab register)" if rev.status == "issued" else \
            f"{rev.status.upper()} {rev.withdrawn_utc} (replaced by a later revision)"

    return standing


def cmd_history(args: argparse.Namespace) -> int:
    where = _target(args.runs or DEFAULT_RUNS, args.records, args.lab)
    with Records.open(where.url) as rec:
        runs = rec.runs(args.serial)
        points = rec.trend(args.serial, runs_of_table=runs)
        table = rec.table(args.serial)
    if not runs:
        _err(f"no run of table {args.serial!r} in {redact(where.url)}"
             + ("" if args.records else f" (run `bench records import "
                                         f"{args.runs or DEFAULT_RUNS}` first?)"))
        return EXIT_FAIL
    assert table is not None
    print(f"table {table.serial}: {table.maker or ''} {table.model or ''}".rstrip())
    print(f"{len(runs)} run(s) in {redact(where.url)}")
    standing = _standing_of(args.lab)
    for r in runs:
        state = f" [{r.calibration_state}]" if r.calibration_state else ""
        when = r.date_utc.strftime("%Y-%m-%d %H:%M") if r.date_utc else "?"
        print(f"  {when}  {r.certificate_number or '-':<24} {r.kind:<11} "
              f"{r.verdict.upper():<10}{state}  {r.run_dir}")
        said = standing(r.certificate_number) if r.certificate_number else None
        if said:
            print(f"      certificate: {said}")
        if r.adjustment_note:
            print(f"      adjustment: {r.adjustment_note}")
    # what each run's procedure kind declares it reports (bench/report/figures.py)
    figures = declared_figures([r.kind for r in runs])
    print("figures with U (k = 2), per axis and rate:")
    groups: dict[tuple[str, float | None, str], list[TrendPoint]] = {}
    listed: dict[str, FigureSpec] = {}
    for p in points:
        spec = spec_for(p.figure.quantity, figures)
        if spec is not None and spec.listed:
            listed[p.figure.quantity] = spec
            groups.setdefault((p.figure.axis, p.figure.set_rate_dps, p.figure.quantity),
                              []).append(p)
    for (axis, rate, quantity), pts in sorted(
            groups.items(), key=lambda kv: (kv[0][0], kv[0][2], kv[0][1] or 0.0)):
        spec = listed[quantity]
        name, scale, unit = spec.name, spec.scale, spec.shown
        where_txt = " ".join(x for x in (axis, f"{rate:+g} deg/s" if rate is not None
                                         else "") if x)
        print(f"  {where_txt + ' ' if where_txt else ''}{name}, {unit}:")
        for p in pts:
            f = p.figure
            u = f"± {f.u * scale:.3g}" if f.u is not None else ""
            tol = f"  (tolerance {f.tolerance * scale:.3g})" if f.tolerance else ""
            shown = (f"< {f.value * scale:.3g} (not resolved)" if f.is_limit
                     else f"{f.value * scale:+.4g} {u}")
            print(f"    {_date(p)}  {shown}  {(f.verdict or '').upper()}{tol}")
    if args.csv:
        with open(args.csv, "w", newline="", encoding="utf-8") as fh:
            w = csv.writer(fh)
            w.writerow(CSV_COLUMNS)
            for p in points:
                f = p.figure
                w.writerow((args.serial, f.axis, f.quantity,
                            "" if f.set_rate_dps is None else repr(f.set_rate_dps), _date(p),
                            repr(f.value), "" if f.u is None else repr(f.u), f.unit,
                            "" if f.tolerance is None else repr(f.tolerance), f.verdict or "",
                            p.certificate_number or "", p.calibration_state or "", p.run_uid))
        print(f"csv: {args.csv}")
    from bench.app.records.trend import trend_png

    png = trend_png(points, f"Table {args.serial}: trend across recertifications", figures)
    if png is not None:
        plot = Path(args.plot) if args.plot else (
            _records_folder(where.url, args.runs or DEFAULT_RUNS)
            / f"history-{_safe(args.serial)}.png")
        plot.write_bytes(png)
        print(f"trend plot: {plot}")
    return EXIT_OK


def _records_folder(url: str, runs: str) -> Path:
    """Where the records are: a SQLite file's folder, else the runs folder (a database
    server has no folder of ours), never the current folder unasked."""
    from sqlalchemy.engine import make_url

    try:
        u = make_url(url)
    except Exception:  # noqa: BLE001 - an odd URL: the runs folder
        return Path(runs)
    if u.drivername.startswith("sqlite") and u.database not in (None, "", ":memory:"):
        return Path(u.database).parent
    return Path(runs)


def _safe(serial: str) -> str:
    return "".join(c if c.isalnum() or c in "-_." else "_" for c in serial)


def cmd_due(args: argparse.Namespace) -> int:
    where = _target(args.runs, args.records, args.lab)
    with Records.open(where.url) as rec:
        items = rec.due(today=args.today, within_days=args.within,
                        intervals=where.interval_for, everything=args.all)
    if not items:
        print(f"no table due within {args.within} d ({redact(where.url)})")
        return EXIT_OK
    print(f"{'serial':<16} {'table':<34} {'last pass':<11} {'interval':>8}  "
          f"{'due':<11} status")
    for i in items:
        t = i.table
        last = t.last_pass_utc.date().isoformat() if t.last_pass_utc else "-"
        interval = where.interval_for(t.serial, t.interval_days)
        print(f"{t.serial:<16} {((t.maker or '') + ' ' + (t.model or '')).strip()[:34]:<34} "
              f"{last:<11} {interval:>6} d  {str(i.due_date or 'now'):<11} {i.status}")
    return EXIT_OK


def _plot_path(args: argparse.Namespace, url: str, serial: str) -> Path:
    if args.plot:
        return Path(args.plot)
    folder = (Path(url.removeprefix("sqlite:///")).parent if url.startswith("sqlite:///")
              else Path(args.runs or DEFAULT_RUNS))
    return folder / f"control-{_safe(serial)}.png"


def _authenticated_reviewer(args: argparse.Namespace) -> str | None:
    """A review lifts the assurance gate (ISO/IEC 17025 7.7), so it is a decision of an
    account the lab register authenticates (issue 42), never a name typed after --by."""
    from bench.app.register import RegisterError
    from bench.app.register.commands import register_url
    from bench.app.register.credentials import Passwords
    from bench.app.register.store import Register

    if not args.by:
        _err("bench control --review: --by ACCOUNT names the reviewer's account in the lab "
             "register (its password is asked)")
        return None
    try:
        with Register.open(register_url(args), migrate=False) as reg:
            acct = reg.authenticate(args.by, Passwords(args.password_stdin).next(
                f"password of {args.by} (review): "))
            if not (acct.has("reviewer") or acct.has("quality")):
                raise RegisterError(f"{args.by!r} holds neither the reviewer nor the quality "
                                    "role")
            reg.append(acct.name, "control review", str(args.serial),
                       {"text": args.review.strip(), "new_baseline": args.new_baseline})
    except RegisterError as e:
        _err(f"bench control --review: {e}")
        return None
    return f"{acct.full_name} (account {acct.name}, authenticated)"


def cmd_control(args: argparse.Namespace) -> int:
    """`bench control [SERIAL] [--review TEXT]` (docs/method.md C)."""
    import socket

    from bench.app.records.control import OUT_OF_CONTROL, all_statuses, instrument_status
    from bench.app.records.control_plot import control_png

    where = _target(args.runs or DEFAULT_RUNS, args.records, args.lab)
    if args.new_baseline and args.review is None:
        _err("bench control --new-baseline: only with --review TEXT (who decided it, and why)")
        return EXIT_INVALID
    if args.review is not None and not args.serial:
        _err("bench control --review: name the instrument: bench control SERIAL --review TEXT")
        return EXIT_INVALID
    if args.review is not None and not args.review.strip():
        _err("bench control --review: say why the instrument may be used (TEXT is empty)")
        return EXIT_INVALID
    reviewer = None
    if args.review is not None:
        reviewer = _authenticated_reviewer(args)
        if reviewer is None:
            return EXIT_INVALID
    with Records.open(where.url) as rec:
        if not args.serial:
            statuses = all_statuses(rec)
            if not statuses:
                _err(f"no instrument check values in {redact(where.url)}")
                return EXIT_FAIL
            print(f"{len(statuses)} instrument(s) in {redact(where.url)}:")
            for st in statuses:
                print(f"  {st.line}")
            return EXIT_FAIL if any(st.state == OUT_OF_CONTROL for st in statuses) else EXIT_OK
        status = instrument_status(rec, args.serial)
        if status is None:
            _err(f"no instrument {args.serial!r} in {redact(where.url)} (`bench control` "
                 f"lists them)")
            return EXIT_FAIL
        if args.review is not None and reviewer is not None:
            who = reviewer
            last = max((p.date_utc for s in status.series for p in s.points if p.date_utc),
                       default=None)
            r = rec.add_review(args.serial, who, args.review.strip(), status.line, last,
                               socket.gethostname(), new_baseline=args.new_baseline)
            print(f"review recorded: {r.reviewer}, {r.utc:%Y-%m-%d %H:%M:%S UTC}, covering "
                  f"the runs up to {last:%Y-%m-%d %H:%M:%S UTC}: {r.text}"
                  if last else f"review recorded: {r.reviewer}: {r.text}")
            status = instrument_status(rec, args.serial)
            assert status is not None
    print(status.line)
    for s in status.series:
        print(f"\n{s.label}")
        print(f"  {s.baseline_text}")
        if s.centre is not None and s.sigma is not None:
            print(f"  centre {s.centre:.9g}, sigma {s.sigma:.3g} ({s.sigma_source}); limits "
                  f"{s.centre - 3 * s.sigma:.9g} .. {s.centre + 3 * s.sigma:.9g}")
        print(f"  {'#':>3} {'date (UTC)':<17} {'value':>16} {'U (k=2)':>10} {'z':>7} "
              f"{'EWMA':>16}  {'signal':<8} run")
        signals: dict[str, list[str]] = {}
        for g in s.signals:
            signals.setdefault(g.run_uid, []).append(g.rule)
        for i, p in enumerate(s.points):
            c = p.check
            z = (f"{(c.value - s.centre) / s.sigma:+7.2f}" if s.centre is not None and s.sigma
                 else f"{'':>7}")
            ew = s.ewma[i] if i < len(s.ewma) else None
            when = p.date_utc.strftime("%Y-%m-%d %H:%M") if p.date_utc else "?"
            rules = signals.get(p.run_uid)
            print(f"  {i + 1:>3} {when:<17} {c.value:>16.9g} "
                  f"{'' if c.u is None else format(c.u, '.2g'):>10} {z} "
                  f"{'' if ew is None else format(ew, '.9g'):>16}  "
                  f"{'+'.join(rules) if rules else '':<8} {p.run_dir}")
    for r in status.reviews:
        print(f"\nreview {r.utc:%Y-%m-%d %H:%M UTC} by {r.reviewer}: {r.text}")
    png = control_png(status)
    if png is not None:
        plot = _plot_path(args, where.url, args.serial)
        plot.parent.mkdir(parents=True, exist_ok=True)
        plot.write_bytes(png)
        print(f"control charts: {plot}")
    return EXIT_FAIL if status.state == OUT_OF_CONTROL else EXIT_OK


def cmd_sync(args: argparse.Namespace) -> int:
    """`bench records sync`: this bench's runs to the lab database (bench/app/fleet)."""
    from bench.app.fleet.sync import SyncError, is_lab_server, run_dirs, sync_folder

    where = _runs_target(args.runs, args.records, args.lab)
    if where is None:
        return EXIT_INVALID
    # a run's own command: each run to the records of the lab file it copied (else the
    # command's: --records, --lab, $BENCH_LAB_SETTINGS)
    urls = {p: _run_records(p, args.records, where.url) for p in run_dirs(where.runs_dir)}
    for url in dict.fromkeys(urls.values()) if urls else [where.url]:
        if not is_lab_server(url):
            _err(f"bench records sync: {redact(url)} is not a lab server: name its "
                 "PostgreSQL database (--records postgresql://ROLE@HOST/DB, or records: in "
                 "the lab file)")
            return EXIT_INVALID
    if args.batch < 1:
        _err("bench records sync: --batch: expected at least 1 line")
        return EXIT_INVALID
    from bench.app.fleet.lost import mark_lost_runs

    for found in mark_lost_runs(where.runs_dir, "bench records sync"):
        print(found.line)
    done = []
    try:
        for url in dict.fromkeys(urls.values()):
            done += sync_folder(where.runs_dir, url, batch_lines=args.batch,
                                interval_for=where.interval_for,
                                only=[p for p, u in urls.items() if u == url])
    except SyncError as e:
        _err(f"{e}; nothing is lost: the run directories keep everything, sync again later")
        return EXIT_FAIL
    for d in done:
        if d.events or d.result or d.registered not in (None, "unchanged"):
            print(f"{d.run}: {d.events} new event(s)"
                  + (", result" if d.result else "")
                  + (f", records {d.registered}" if d.registered else ""))
    from bench.app.register.runs import deliver

    for p in urls:      # a session's end the lab register did not receive (link down)
        rec = deliver(p, "session", _err, "delivered by bench records sync after the "
                      "session's end", only_if_missing=True)
        if rec is not None:
            print(f"{p.name}: result delivered to the lab register (it first saw the run "
                  f"at {rec.registered_utc})")
    shown = ", ".join(redact(u) for u in dict.fromkeys(urls.values())) or redact(where.url)
    print(f"lab database {shown}: {len(done)} run(s), "
          f"{sum(d.events for d in done)} new event(s), "
          f"{sum(1 for d in done if d.result)} result(s), "
          f"{sum(1 for d in done if d.registered in ('new', 'updated'))} registered")
    return EXIT_OK


def cmd_check(args: argparse.Namespace) -> int:
    """`bench records check RUN...`: the lab database against the run directories."""
    from bench.app.fleet.check import check_run
    from bench.app.fleet.sync import LabLink, SyncError, is_lab_server

    paths = [Path(r) for r in args.runs]
    for p in paths:
        if not (p / layout.EVENTS).is_file():
            _err(f"bench records check: {p} is not a run directory (no events.jsonl)")
            return EXIT_INVALID
    urls = {p: _run_records(p, args.records, _target(p.parent, None, args.lab).url)
            for p in paths}
    for p, url in urls.items():
        if not is_lab_server(url):
            _err(f"bench records check: {p.name}: {redact(url)} is not a lab server: name "
                 "its PostgreSQL database (--records postgresql://ROLE@HOST/DB, or records: "
                 "in the lab file)")
            return EXIT_INVALID
    differ = False
    try:
        for url in dict.fromkeys(urls.values()):
            with LabLink(url) as link:
                for p in (p for p, u in urls.items() if u == url):
                    found = check_run(link, p)
                    differ = differ or not found.equal
                    print("\n".join(found.lines()))
    except SyncError as e:
        _err(f"bench records check: {e}")
        return EXIT_FAIL
    return EXIT_FAIL if differ else EXIT_OK


def _run_records(run_path: Path, records: str | None, otherwise: str) -> str:
    """A run's own records (a run's own command, bench/app/labfile.py): --records, else the
    records: of the lab file the run copied when it started, else `otherwise` (the
    command's)."""
    if records:
        return records
    copy = run_path / layout.LAB
    if copy.is_file():
        from bench.core.lab import load_lab
        url = load_lab(copy).records_url
        if url:
            return url
    return otherwise


def cmd_init(args: argparse.Namespace) -> int:
    """`bench records init URL`: the lab database's schema and its roles' grants."""
    import sqlalchemy as sa

    from bench.app.fleet.roles import bench_grants, station_grants
    from bench.app.fleet.sync import is_lab_server

    if not is_lab_server(args.url):
        _err(f"bench records init: {redact(args.url)}: the lab database is a PostgreSQL URL "
             "(a bench's own SQLite records are created when first used)")
        return EXIT_INVALID
    with Records.open(args.url) as rec, rec.engine.begin() as conn:
        for role in args.bench_role:
            for q in bench_grants(role):
                conn.execute(sa.text(q))
        for role in args.station_role:
            for q in station_grants(role):
                conn.execute(sa.text(q))
        revision = rec.revision()
    print(f"lab records {redact(args.url)} at revision {revision}; benches' role(s): "
          f"{', '.join(args.bench_role) or 'none granted'}; station's role(s): "
          f"{', '.join(args.station_role) or 'none granted'}")
    return EXIT_OK


def cmd_bench(args: argparse.Namespace) -> int:
    """`bench records bench add NAME --role ROLE`: the bench's rows become the role's."""
    from bench.app.fleet.roles import bind_bench
    from bench.app.fleet.sync import is_lab_server

    if not is_lab_server(args.records):
        _err(f"bench records bench: {redact(args.records)}: a bench's role is bound on the "
             "lab's PostgreSQL database")
        return EXIT_INVALID
    with Records.open(args.records) as rec, rec.engine.begin() as conn:
        bind_bench(conn, args.name, args.role)
    print(f"bench {args.name}: its fleet rows and registered runs are written by the "
          f"database role {args.role} alone")
    return EXIT_OK


def cmd_records(args: argparse.Namespace) -> int:
    """`bench records import` / `sync` / `init`."""
    chosen = {"sync": cmd_sync, "init": cmd_init, "check": cmd_check,
              "bench": cmd_bench}.get(
        args.records_command, cmd_import)
    return chosen(args)


#: command name -> handler, for bench/app/cli.py (their options: bench/app/parsers.py)
RECORDS_COMMANDS: dict[str, Callable[[argparse.Namespace], int]] = {
    "history": _guarded(cmd_history), "records": _guarded(cmd_records),
    "due": _guarded(cmd_due), "control": _guarded(cmd_control)}
