"""The station view's web application (Flask): live runs and the lab's records.

Read-only but for two actions: a stop request, which is exactly Ctrl-C: SIGINT to the
bench process that journaled its pid in the run directory, so the engine's own safe stop
runs (ramp to zero, disable, data kept, `--resume` continues); and, with a lab register,
a signatory's e-signature that issues a run's draft (signing.py: log in, re-enter the
password to sign; the server refuses and audits anyone else). Nothing here can move a
table.

Security, in this order: a request from another host than this one needs the operator's
token, but for one over TLS from the lab's password networks (settings.py); a stop
request always needs it; the Host header must name this server (a web page elsewhere
cannot reach it through DNS rebinding); only the download files of run directories
directly inside the runs folders are served. Over TLS every cookie is Secure.
"""

from __future__ import annotations

import hmac
import json
import os
import signal
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TypeVar

from flask import (
    Flask,
    Response,
    abort,
    jsonify,
    render_template,
    request,
    send_from_directory,
    stream_with_context,
    url_for,
)

import bench
from bench.app.db import away_text, redact
from bench.app.fleet.sync import is_lab_server
from bench.app.station.drafts import Draft, find_run
from bench.app.station.fleet import FleetView, Notifications, fleet_json
from bench.app.station.live import DOWNLOADS, list_runs, live_state, pid_alive
from bench.app.station.records import RecordsView, run_figures
from bench.app.station.settings import StationSettings, in_networks, is_loopback
from bench.app.station.signing import install as install_signing
from bench.core import rundir_layout as layout

TOKEN_HEADER = "X-Bench-Token"
TOKEN_COOKIE = "bench_token"
STREAM_PERIOD_S = 1.0           # how often a live page gets the run's state
STREAM_LIFETIME_S = 300.0       # a stream ends then; the browser reconnects by itself
FLEET_REFRESH_S = 2.0           # the lab page's table is rendered again at least this often

T = TypeVar("T")


def _bench_process(pid: int) -> bool:
    """The pid is a bench process still (a reused pid must never get our SIGINT):
    `bench ...` or `python -m bench ...`."""
    try:
        argv = Path(f"/proc/{pid}/cmdline").read_bytes().split(b"\0")
    except OSError:
        return pid_alive(pid)     # no /proc (not Linux): trust the liveness check
    return any(Path(os.fsdecode(a)).name == "bench" for a in argv[:1]) or \
        any(argv[i] == b"-m" and argv[i + 1] == b"bench" for i in range(len(argv) - 1))


class _Station:
    """What the station's routes share, made once by create_app: its settings, the runs
    folder, the records (with a lab server's benches, followed by LISTEN), the hosts it
    answers to, and the signing (signing.py)."""

    def __init__(self, app: Flask, settings: StationSettings) -> None:
        self.settings = settings
        self.runs = settings.runs.resolve()
        self.records = RecordsView(self.runs, settings.records_url)
        # a lab server as the records (bench/app/fleet): every bench's runs, followed by LISTEN
        self.fleet = FleetView(self.records.url, self.runs) \
            if is_lab_server(self.records.url) else None
        self.notifications = Notifications(self.records.url).start() \
            if self.fleet is not None else None
        self.allowed_hosts = {"127.0.0.1", "localhost", "[::1]", settings.host,
                              *(n.lower() for n in settings.server_names)}
        self.signing = install_signing(app, settings, self.run_dir)

    def run_dir(self, name: str) -> Path:
        """A run directory directly inside the runs folder, or 404 (no traversal)."""
        if not name or "/" in name or "\\" in name or name in (".", "..") \
                or name.startswith("."):
            abort(404)
        p = (self.runs / name).resolve()
        if p.parent != self.runs or not (p / layout.EVENTS).is_file():
            abort(404)
        return p

    def has_token(self) -> bool:
        given = (request.headers.get(TOKEN_HEADER) or request.cookies.get(TOKEN_COOKIE)
                 or request.args.get("token") or "")
        return hmac.compare_digest(given.encode(), self.settings.token.encode())


def create_app(settings: StationSettings,
               send_signal: Callable[[int, int], None] = os.kill) -> Flask:
    """The station's app; its routes are added page by page (Flask's application factory,
    the routes registered by functions so each keeps its endpoint name for url_for)."""
    app = Flask(__name__)
    # Flask escapes only templates named *.html; ours are *.html.j2, and what they print
    # comes from files and instruments (a title, a refusal's message), never trusted HTML
    app.jinja_env.autoescape = True
    app.config["station"] = settings
    st = _Station(app, settings)
    _add_guard(app, st)
    _add_index(app, st)
    _add_bench_runs(app, st)
    _add_fleet_api(app, st)
    _add_run_pages(app, st)
    _add_stop(app, st, send_signal)
    _add_records_pages(app, st)
    return app


def _add_guard(app: Flask, st: _Station) -> None:
    """Who may ask (module docstring, "Security"), and the headers every answer carries."""
    settings, signing, has_token = st.settings, st.signing, st.has_token
    allowed_hosts = st.allowed_hosts

    @app.before_request
    def guard() -> Response | None:
        host = request.host.rsplit(":", 1)[0] if not request.host.endswith("]") \
            else request.host
        if host.lower() not in allowed_hosts:
            abort(403, f"unknown Host header {host!r}: this station answers to "
                       f"{', '.join(sorted(allowed_hosts))} (bench serve --server-name)")
        if not is_loopback(request.remote_addr) and not has_token() and not (
                signing.over_tls() and in_networks(signing.client(),
                                                   settings.password_networks)):
            abort(403, "a token is needed from another host")
        return None

    @app.after_request
    def remember_token(resp: Response) -> Response:
        # a token given once in the URL (?token=) is kept for the page's own requests
        if request.args.get("token") and has_token():
            resp.set_cookie(TOKEN_COOKIE, settings.token, httponly=True, samesite="Strict",
                            secure=signing.over_tls())
        resp.headers["X-Content-Type-Options"] = "nosniff"
        resp.headers["Content-Security-Policy"] = "default-src 'self'; img-src 'self' data:"
        return resp


def _add_index(app: Flask, st: _Station) -> None:
    """The first page: this station's runs and tables, or with a lab server the lab's."""
    settings, runs, records, signing = st.settings, st.runs, st.records, st.signing
    fleet, notifications = st.fleet, st.notifications

    @app.get("/")
    def index() -> str:
        if fleet is not None:
            return lab_page()
        return render_template("index.html.j2", runs=list_runs(runs), version=bench.__version__,
                               tables=records.tables(), records_error=records.error)

    def lab_page() -> str:
        """Every bench of the lab, the tables due, the drafts waiting for a signatory and
        the instruments' status (a lab server as the records)."""
        assert fleet is not None and notifications is not None
        instruments, notes = records.lab_instruments(settings.register_url,
                                                     fleet.instrument_serials())
        return render_template("lab.html.j2", fleet=fleet.benches(),
                               lab_url=redact(records.url), due=records.due_list(),
                               drafts=drafts_shown(False), sim_drafts=drafts_shown(True),
                               instruments=instruments,
                               notes=notes, runs=list_runs(runs), version=bench.__version__)

    def drafts_shown(simulated: bool) -> list[dict[str, str | None]] | None:
        """Every bench's drafts for the lab page: each with its page, and its draft
        certificate when one of the station's runs folders holds the run; a run the
        register has issued meanwhile (the records not told yet) is left out."""
        found = records.lab_drafts(simulated=simulated)
        if found is None:
            return None
        issued = signing.issued_of([d.uid for d in found])
        out: list[dict[str, str | None]] = []
        for d in found:
            if d.uid in issued:
                continue
            folder = find_run(settings.runs_folders, d.run_dir, d.uid)
            page = (url_for("bench_run_page", bench_name=d.bench, uid=d.uid) if d.bench
                    else None)
            has_pdf = folder is not None and (folder / layout.CERTIFICATE_PDF).is_file()
            out.append({"bench": d.bench, "serial": d.serial, "run": d.run_dir,
                        "uid": d.uid, "verdict": d.verdict, "operator": d.operator,
                        "date_utc": d.date_utc.strftime("%Y-%m-%d %H:%M")
                        if d.date_utc else "-", "page": page,
                        "pdf": url_for("bench_run_file", bench_name=d.bench, uid=d.uid,
                                       filename=layout.CERTIFICATE_PDF)
                        if has_pdf and d.bench else None,
                        "where": _where(d, folder, settings)})
        return out


def _add_bench_runs(app: Flask, st: _Station) -> None:
    """Another bench's run (a lab server as the records): its page, its sign request and
    its files, from the station's runs folders."""
    settings, signing, fleet = st.settings, st.signing, st.fleet

    def bench_folder(bench_name: str, uid: str) -> Path:
        """The folder of the run `uid` a bench delivered, from the station's runs folders,
        or 404 (the lab database's run directory name, checked by the uid in its
        meta.json)."""
        if fleet is None:
            abort(404)
        try:
            found = fleet.run(bench_name, uid)
        except Exception as e:  # noqa: BLE001 - the server away: say so
            abort(503, away_text(fleet.url, e))
        if found is None:
            abort(404)
        folder = find_run(settings.runs_folders, str(found["run"]), uid)
        if folder is None:
            abort(404, f"run {uid} of bench {bench_name} is in none of this station's runs "
                       "folders (bench serve --runs, --other-runs)")
        return folder

    @app.get("/bench/<bench_name>/<uid>")
    def bench_run_page(bench_name: str, uid: str) -> str | tuple[str, int]:
        if fleet is None:
            abort(404)
        try:
            found = fleet.run(bench_name, uid)
        except Exception as e:  # noqa: BLE001 - the server away: the page says so in words
            return render_template("away.html.j2", title=f"{bench_name}: run {uid}",
                                   text=away_text(fleet.url, e),
                                   version=bench.__version__), 503
        row = _found(found)         # the lab database's row of the run, not a result
        folder = find_run(settings.runs_folders, str(row["run"]), uid)
        cert = None
        if folder is not None:
            page = url_for("bench_run_page", bench_name=bench_name, uid=uid)
            cert = signing.panel(
                folder, live_state(folder), page=page,
                sign_url=url_for("bench_run_sign", bench_name=bench_name, uid=uid),
                pdf_url=url_for("bench_run_file", bench_name=bench_name, uid=uid,
                                filename=layout.CERTIFICATE_PDF))
        return render_template("bench_run.html.j2", r=row, cert=cert,
                               folder=str(folder) if folder else None,
                               folders=[str(f) for f in settings.runs_folders],
                               version=bench.__version__)

    @app.post("/bench/<bench_name>/<uid>/sign")
    def bench_run_sign(bench_name: str, uid: str) -> tuple[str, int]:
        """Another bench's draft signed here: the same sign request as a run of the
        station's own folder (signing.py), on the folder the uid names."""
        folder = bench_folder(bench_name, uid)
        return signing.sign_page(
            f"{bench_name}/{folder.name}", lambda _name: folder,
            url_for("bench_run_page", bench_name=bench_name, uid=uid),
            lambda f: url_for("bench_run_file", bench_name=bench_name, uid=uid, filename=f))

    @app.get("/bench/<bench_name>/<uid>/files/<path:filename>")
    def bench_run_file(bench_name: str, uid: str, filename: str) -> Response:
        if filename not in DOWNLOADS:
            abort(404)
        return send_from_directory(bench_folder(bench_name, uid), filename,
                                   as_attachment=filename.endswith(".xml"))


def _add_fleet_api(app: Flask, st: _Station) -> None:
    """The lab's benches as JSON, and as a stream the lab page follows."""
    fleet, notifications = st.fleet, st.notifications

    @app.get("/api/fleet")
    def api_fleet() -> Response:
        if fleet is None or notifications is None:
            abort(404)
        return jsonify(fleet_json(fleet.benches()))

    @app.get("/api/fleet/stream")
    def api_fleet_stream() -> Response:
        """The benches' table, rendered again whenever a bench delivers (NOTIFY), and at
        least every FLEET_REFRESH_S (ages grow; a silent bench is noticed)."""
        if fleet is None or notifications is None:
            abort(404)

        def events() -> Iterator[str]:
            t_end = time.monotonic() + STREAM_LIFETIME_S
            yield "retry: 2000\n\n"
            seen = -1
            while time.monotonic() < t_end:
                version = notifications.wait(seen, FLEET_REFRESH_S)
                seen = version
                state = fleet.benches(version)
                html = render_template("fleet_benches.html.j2", fleet=state)
                text = json.dumps({"html": html, "benches": fleet_json(state)},
                                  separators=(",", ":"), allow_nan=False)
                yield f"event: fleet\ndata: {text}\n\n"
        return Response(stream_with_context(events()), mimetype="text/event-stream",
                        headers={"Cache-Control": "no-cache", "X-Accel-Buffering": "no"})


def _add_run_pages(app: Flask, st: _Station) -> None:
    """A run of the runs folder: its live page, its state (once and streamed), its
    figures and its files."""
    runs, signing, run_dir = st.runs, st.signing, st.run_dir

    @app.get("/run/<name>")
    def run_page(name: str) -> str:
        p = run_dir(name)
        state = live_state(p)
        cert = signing.panel(p, state, page=url_for("run_page", name=p.name),
                             sign_url=url_for("sign", name=p.name),
                             pdf_url=url_for("files", name=p.name,
                                             filename=layout.CERTIFICATE_PDF))
        return render_template("run.html.j2", run=p.name, state=state, cert=cert,
                               version=bench.__version__)

    @app.get("/api/runs")
    def api_runs() -> Response:
        return jsonify(list_runs(runs))

    @app.get("/api/runs/<name>/state")
    def api_state(name: str) -> Response:
        return jsonify(live_state(run_dir(name)))

    @app.get("/api/runs/<name>/stream")
    def api_stream(name: str) -> Response:
        p = run_dir(name)

        def events() -> Iterator[str]:
            last = None
            t_end = time.monotonic() + STREAM_LIFETIME_S
            yield "retry: 2000\n\n"
            while time.monotonic() < t_end:
                text = json.dumps(live_state(p), separators=(",", ":"), allow_nan=False)
                if text != last:
                    last = text
                    yield f"event: state\ndata: {text}\n\n"
                else:
                    yield ": keep-alive\n\n"
                time.sleep(STREAM_PERIOD_S)
        return Response(events(), mimetype="text/event-stream",
                        headers={"Cache-Control": "no-cache", "X-Accel-Buffering": "no"})

    @app.get("/api/runs/<name>/figures")
    def api_figures(name: str) -> Response:
        """The run's figures as its procedure kind declares them (bench/report/figures.py):
        the same rows the records keep, with the kind's words and units."""
        return jsonify(run_figures(run_dir(name)))

    @app.get("/files/<name>/<path:filename>")
    def files(name: str, filename: str) -> Response:
        p = run_dir(name)
        if filename not in DOWNLOADS:
            abort(404)
        return send_from_directory(p, filename, as_attachment=filename.endswith(".xml"))


def _add_stop(app: Flask, st: _Station, send_signal: Callable[[int, int], None]) -> None:
    """The stop request: exactly Ctrl-C to the run's bench process (module docstring)."""
    run_dir, has_token = st.run_dir, st.has_token

    @app.post("/api/runs/<name>/stop")
    def api_stop(name: str) -> tuple[Response, int]:
        if not has_token():
            return jsonify(ok=False, error="the stop request needs the station's token"), 403
        p = run_dir(name)
        state = live_state(p)
        pid = state.get("pid")
        if (state["status"] != "running" or not isinstance(pid, int) or not pid
                or not _bench_process(pid)):
            return jsonify(ok=False, error=f"run {name} is not running ({state['status']})"), 409
        send_signal(pid, signal.SIGINT)   # exactly Ctrl-C: the engine's safe stop
        app.logger.warning("stop requested for %s (pid %s) from %s", name, pid,
                           request.remote_addr)
        return jsonify(ok=True, pid=pid, message="stop requested: the bench ramps every axis "
                       "to zero and disables it; `bench run --resume` continues"), 202


def _add_records_pages(app: Flask, st: _Station) -> None:
    """The lab's records: the tables, an instrument's control charts, a table's history."""
    records = st.records

    @app.get("/records")
    def records_page() -> str:
        tables = records.tables()
        error = records.error
        return render_template("records.html.j2", tables=tables, records_error=error,
                               instruments=records.instruments(), version=bench.__version__)

    @app.get("/instrument/<path:serial>")
    def instrument_page(serial: str) -> str:
        return render_template("instrument.html.j2", serial=serial,
                               control=_found(records.control(serial)),
                               version=bench.__version__)

    @app.get("/api/instrument/<path:serial>/control.png")
    def control_png(serial: str) -> Response:
        return Response(_found(records.control_png(serial)), mimetype="image/png")

    @app.get("/records/<serial>")
    def table_page(serial: str) -> str:
        return render_template("table.html.j2", serial=serial,
                               history=_found(records.history(serial)),
                               version=bench.__version__)

    @app.get("/api/records/<serial>/trend.png")
    def trend_png(serial: str) -> Response:
        return Response(_found(records.trend_png(serial)), mimetype="image/png")

def _where(d: Draft, folder: Path | None, settings: StationSettings) -> str:
    """Where a draft's files are, in words, for the drafts list."""
    if folder is not None:
        return f"runs folder {folder.parent}"
    at = f" ({d.run_path})" if d.run_path else ""
    return (f"at its bench{at}: in none of this station's runs folders "
            f"({', '.join(str(f) for f in settings.runs_folders)}; bench serve --other-runs)")


def _found(value: T | None) -> T:
    """What a records route shows, or 404 when the records hold nothing under that serial
    (flask's abort raises)."""
    if value is None:
        abort(404)
    return value
