"""Logging in and signing at the station (issue 42): accounts of the lab register, a
session per login, and the e-signature that issues a run's draft.

- Log in with an account's name and password, checked by the register (which audits a
  refused attempt). The session lives in this process only: the cookie carries a random
  session id signed with a secret made when the server starts (HMAC-SHA256), HttpOnly and
  SameSite=Strict; a session ends at logout, after IDLE_S without a request, or MAX_S
  after the login, and when the server stops.
- Signing is a fresh e-signature, not the login: the signatory re-enters the password at
  the moment of signing (name and password, 21 CFR 11.200(a)); the station checks it with
  the register, then `bench authorise` (bench/app/certificate/authorise.py) issues through
  the same register. STRIKES wrong passwords at signing end the session.
- The server decides what each account may do: the sign form is shown only to an account
  holding the signatory role, and a sign request from any other (or from no session, or
  without the session's CSRF token, or from another origin) is refused with 403 and
  written to the register's audit trail. The role is read again from the register at
  each sign request, so an account disabled since its login cannot sign. The form carries
  the digest of the result.json the page showed: a draft analysed again meanwhile is not
  signed unseen.
- Where a password is taken (settings.password_refusal): over TLS (`bench serve
  --tls-cert/--tls-key`, issue 59) from the lab's password networks (default: this machine
  only); over plain HTTP from this machine alone (the loopback address, a loopback Host,
  nothing forwarded from elsewhere), since a password sent from another host would cross
  the network in clear. Over TLS the session cookie is Secure.
- A draft in another bench's runs folder that the station can read (`--other-runs`) is
  signed the same way, from its bench's run page (app.py): the same `bench authorise`.
- With no register configured the station stays read-only, as before, and says that
  signing needs a register.
"""

from __future__ import annotations

import base64
import contextlib
import dataclasses
import hashlib
import hmac
import io
import re
import secrets
import threading
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING
from urllib.parse import urlsplit

from flask import Flask, abort, redirect, render_template, request, url_for
from werkzeug.wrappers import Response

import bench
from bench.app.station.settings import StationSettings, password_refusal
from bench.core import rundir_layout as layout

if TYPE_CHECKING:
    from bench.app.register import Account, Register
    from bench.app.register.model import AuditDetail
    from drivers.json_types import JsonLike

SESSION_COOKIE = "bench_session"
IDLE_S = 15 * 60.0            # a session ends after this long without a request
MAX_S = 8 * 3600.0            # and this long after its login, whatever happens
LOGIN_FORM_S = 3600.0         # a login form is good for this long
STRIKES = 3                   # wrong passwords at signing before the session ends
SIGN_WAIT_S = 120.0           # how long a sign request waits for another to finish

NO_REGISTER = ("Signing needs a lab register: start the station with `bench serve "
               "--register URL` or `--lab FILE` (a lab file whose register: key names it); "
               "see docs/register.md. Without one the station is read-only.")


def _now() -> float:
    return time.monotonic()


@dataclasses.dataclass
class Session:
    """One login: the account as the register gave it then, and the session's CSRF token."""

    account: Account
    csrf: str
    started: float
    seen: float
    strikes: int = 0

    def has(self, role: str) -> bool:
        return self.account.has(role)


class Sessions:
    """The sessions of this process; a cookie is `<id>.<HMAC of id>` under a secret made
    at start, so a cookie from an earlier server, or a made-up one, names no session."""

    def __init__(self, idle_s: float = IDLE_S, max_s: float = MAX_S,
                 clock: Callable[[], float] = _now) -> None:
        self._secret = secrets.token_bytes(32)
        self._by_id: dict[str, Session] = {}
        self._used_login_tokens: dict[str, float] = {}  # a login form's token works once
        self._lock = threading.Lock()
        self.idle_s, self.max_s, self._clock = idle_s, max_s, clock

    def _mac(self, text: str) -> str:
        digest = hmac.new(self._secret, text.encode(), hashlib.sha256).digest()
        return base64.urlsafe_b64encode(digest).decode().rstrip("=")

    def start(self, account: Account) -> tuple[str, Session]:
        """A new session for the account: its cookie value and the session."""
        sid = secrets.token_urlsafe(32)
        now = self._clock()
        sess = Session(account, secrets.token_urlsafe(32), now, now)
        with self._lock:
            self._expire(now)
            self._by_id[sid] = sess
        return f"{sid}.{self._mac(sid)}", sess

    def get(self, cookie: str | None) -> Session | None:
        """The live session the cookie names (its last use now), or None."""
        sid, _, mac = (cookie or "").partition(".")
        if not sid or not hmac.compare_digest(mac.encode(), self._mac(sid).encode()):
            return None
        now = self._clock()
        with self._lock:
            self._expire(now)
            sess = self._by_id.get(sid)
            if sess is not None:
                sess.seen = now
            return sess

    def end(self, cookie: str | None) -> Session | None:
        sid, _, mac = (cookie or "").partition(".")
        if not sid or not hmac.compare_digest(mac.encode(), self._mac(sid).encode()):
            return None
        with self._lock:
            return self._by_id.pop(sid, None)

    def _expire(self, now: float) -> None:
        gone = [k for k, s in self._by_id.items()
                if now - s.seen > self.idle_s or now - s.started > self.max_s]
        for k in gone:
            del self._by_id[k]

    # a login form's token: no session yet, so a signed time stamp (login CSRF)
    def login_token(self) -> str:
        stamp = f"{int(time.time())}-{secrets.token_urlsafe(12)}"
        return f"{stamp}.{self._mac('login:' + stamp)}"

    def login_token_ok(self, token: str | None) -> bool:
        """A token this server made within LOGIN_FORM_S, not used before (a replayed form
        guesses nothing: issue 53); using it spends it."""
        stamp, _, mac = (token or "").partition(".")
        made = stamp.split("-", 1)[0]
        if not made.isdigit() or not hmac.compare_digest(
                mac.encode(), self._mac("login:" + stamp).encode()):
            return False
        now = time.time()
        with self._lock:
            self._used_login_tokens = {t: at for t, at in self._used_login_tokens.items()
                                       if now - at <= LOGIN_FORM_S}
            if token in self._used_login_tokens:
                return False
            self._used_login_tokens[str(token)] = now
        return 0 <= now - int(made) <= LOGIN_FORM_S


class ClientLimit:
    """Wrong logins per client: past `failures` within `window_s`, that client's logins are
    refused until the window has passed (the register locks the account too)."""

    def __init__(self, failures: int, window_s: float,
                 clock: Callable[[], float] = _now) -> None:
        self.failures, self.window_s, self._clock = failures, window_s, clock
        self._by_client: dict[str, list[float]] = {}
        self._lock = threading.Lock()

    def _recent(self, client: str, now: float) -> list[float]:
        kept = [t for t in self._by_client.get(client, []) if now - t <= self.window_s]
        self._by_client[client] = kept
        return kept

    def blocked(self, client: str) -> bool:
        with self._lock:
            return len(self._recent(client, self._clock())) >= self.failures

    def failed(self, client: str) -> None:
        with self._lock:
            now = self._clock()
            self._recent(client, now).append(now)


class RegisterLink:
    """The register, opened when first needed and kept (a failure is retried next time)."""

    def __init__(self, url: str | None) -> None:
        self.url = url
        self._reg: Register | None = None
        self._lock = threading.Lock()
        self.error: str | None = None

    def get(self) -> Register | None:
        if self.url is None:
            return None
        with self._lock:
            if self._reg is None:
                from bench.app.register import Register, RegisterError

                try:
                    self._reg = Register.open(self.url, migrate=False)
                    self.error = None
                except RegisterError as e:
                    self.error = str(e)
            return self._reg

    def shown(self) -> str:
        from bench.app.register import redact

        return redact(self.url) if self.url else ""


def same_register(a: str | None, b: str | None) -> bool:
    """Two register URLs name one register (SQLite: the same file)."""
    if not a or not b:
        return False
    prefix = "sqlite:///"
    if a.startswith(prefix) and b.startswith(prefix):
        return Path(a[len(prefix):]).resolve() == Path(b[len(prefix):]).resolve()
    import sqlalchemy as sa

    try:
        return sa.engine.make_url(a) == sa.engine.make_url(b)
    except Exception:  # noqa: BLE001 - a malformed URL names no register we know
        return a == b


def sha256_of(path: Path) -> str | None:
    try:
        return hashlib.sha256(path.read_bytes()).hexdigest()
    except OSError:
        return None


@dataclasses.dataclass(frozen=True)
class Outcome:
    """What a sign request came to, as the result page shows it."""

    status: int                 # the HTTP status
    issued: bool
    title: str
    lines: tuple[str, ...] = ()     # what `bench authorise` printed
    reasons: tuple[str, ...] = ()   # why it was not issued


def refusal_reasons(stderr: str) -> tuple[str, ...]:
    """The reasons in `bench authorise`'s refusal ("  - reason" lines), and any other line
    it wrote to stderr but its heading."""
    out = []
    for raw in stderr.splitlines():
        text = raw.strip()
        if not text or text.startswith("bench authorise: not issued ("):
            continue
        out.append(text[2:] if text.startswith("- ") else text)
    return tuple(out)


@dataclasses.dataclass(frozen=True)
class IssuedRevision:
    """One issued revision of the run, as its certificate section lists it."""

    number: str
    revision: str
    status: str
    by: str
    meaning: str
    utc: str
    reason: str


@dataclasses.dataclass(frozen=True)
class CertificatePanel:
    """A run's certificate section (certificate.html.j2) for this request's account."""

    enabled: bool
    account: Account | None
    csrf: str
    local: bool                     # passwords accepted from this client
    remote_refused: str | None      # why not
    draft: str | None               # the draft's result.json SHA-256 (None: not ended)
    has_pdf: bool
    page: str
    sign_url: str
    pdf_url: str
    no_register: str = NO_REGISTER
    status: str | None = None
    issued: list[IssuedRevision] = dataclasses.field(default_factory=list)
    register_error: str | None = None
    reissue: bool = False


class Signing:
    """The station's accounts, sessions and sign requests (installed by `install`)."""

    def __init__(self, settings: StationSettings) -> None:
        self.settings = settings
        self.sessions = Sessions(settings.session_idle_s, settings.session_max_s)
        self.register = RegisterLink(settings.register_url)
        self._sign_lock = threading.Lock()
        self.limit = ClientLimit(settings.login_failures_per_client, settings.login_window_s)

    def client(self) -> str:
        """Who sent the request: the peer, or behind the configured proxy (and only then)
        the last address its X-Forwarded-For adds."""
        peer = request.remote_addr or ""
        forwarded = request.headers.get("X-Forwarded-For", "")
        if self._from_proxy() and forwarded:
            return forwarded.split(",")[-1].strip()
        return peer

    def _from_proxy(self) -> bool:
        return bool(self.settings.trusted_proxy) and \
            request.remote_addr == self.settings.trusted_proxy

    def over_tls(self) -> bool:
        """The request reached the station over TLS: its own (`--tls-cert`), or the
        trusted proxy's, which says so in X-Forwarded-Proto (from no one else)."""
        return request.scheme == "https" or (
            self._from_proxy() and request.headers.get("X-Forwarded-Proto", "") == "https")

    def password_refusal(self) -> str | None:
        """Why this request may not carry a password (None: it may)."""
        forwarded = [a.strip() for a in request.headers.get("X-Forwarded-For", "").split(",")]
        forwarded += [part.split("=", 1)[1].strip().strip('"')
                      for part in request.headers.get("Forwarded", "").replace(",", ";")
                      .split(";") if part.strip().lower().startswith("for=")]
        return password_refusal(self.settings, tls=self.over_tls(), client=self.client(),
                                peer=request.remote_addr or "", host=request.host,
                                forwarded=forwarded)

    def set_session_cookie(self, resp: Response, value: str) -> None:
        resp.set_cookie(SESSION_COOKIE, value, httponly=True, samesite="Strict", path="/",
                        secure=self.over_tls())

    @property
    def enabled(self) -> bool:
        return self.settings.register_url is not None

    def issued_of(self, uids: list[str]) -> set[str]:
        """Those of the runs `uids` the register holds a certificate number for (none
        known without a register, or while it cannot be read)."""
        reg = self.register.get()
        if reg is None or not uids:
            return set()
        try:
            return {u for u in uids if reg.number_of_run(u)}
        except Exception:  # noqa: BLE001 - the list stays the records' word; pages say why
            return set()

    # -- the request's session ------------------------------------------------------------

    def session(self) -> Session | None:
        return self.sessions.get(request.cookies.get(SESSION_COOKIE))

    def audit(self, actor: str, action: str, obj: str, detail: AuditDetail) -> None:
        """An audit entry in the register; a register that cannot take it is logged, and
        the request is refused all the same."""
        from bench.app.register import RegisterError

        reg = self.register.get()
        if reg is None:
            return
        try:
            reg.append(actor, action, obj, {**detail, "at": "station",
                                            "remote": request.remote_addr or ""})
        except RegisterError as e:
            from flask import current_app

            current_app.logger.error("audit entry not written (%s %s): %s", action, obj, e)

    # -- the run page's certificate section -----------------------------------------------

    def panel(self, run_path: Path, state: Mapping[str, JsonLike], *, page: str,
              sign_url: str, pdf_url: str) -> CertificatePanel:
        """What the run's certificate section shows this request's account: `page` is the
        page's own path (back there after logging in), `sign_url` where the form posts and
        `pdf_url` the draft certificate."""
        sess = self.session()
        result = run_path / layout.RESULT
        ended = bool(state.get("ended")) and state.get("status") != "refused"
        refusal = self.password_refusal()
        out = CertificatePanel(
            enabled=self.enabled, account=sess.account if sess else None,
            csrf=sess.csrf if sess else "", local=refusal is None, remote_refused=refusal,
            draft=sha256_of(result) if ended else None,
            has_pdf=(run_path / layout.CERTIFICATE_PDF).is_file(), page=page,
            sign_url=sign_url, pdf_url=pdf_url)
        if not self.enabled:
            return dataclasses.replace(out, status=(
                "The station has no register to ask; the run's own record says: "
                f"{_local_record(run_path)}"))
        reg = self.register.get()
        if reg is None:
            return dataclasses.replace(out, register_error=self.register.error)
        issued: list[IssuedRevision] = []
        try:
            issued = _register_revisions(reg, run_path)
        except Exception as e:  # noqa: BLE001 - the page shows what failed, not a 500
            from bench.app.db import away_text

            out = dataclasses.replace(out, register_error=away_text(
                self.register.url or "", e, "lab register"))
        last = issued[-1] if issued else None
        status = (f"Withdrawn: certificate {last.number}, {last.meaning} by "
                  f"{last.by} at {last.utc}, is {last.status}"
                  if last and last.status.startswith("withdrawn ") else
                  f"Issued: certificate {last.number} ({last.status}), "
                  f"{last.meaning} by {last.by} at {last.utc}"
                  if last else "Draft, not authorised: the register holds no issue "
                  "of this run")
        return dataclasses.replace(out, issued=issued, status=status, reissue=last is not None)

    # -- the sign request -----------------------------------------------------------------

    def sign(self, name: str, run_dir: Callable[[str], Path]) -> tuple[Outcome, Session | None]:
        """The sign request for run `name`: refused (403, audited) unless it comes from a
        signatory's live session, with its CSRF token, from this origin; then the
        password is checked and the draft issued through `bench authorise`."""
        reg = self.register.get()
        if not self.enabled or reg is None:
            return Outcome(403, False, "Not issued: signing needs a register",
                           reasons=(self.register.error or NO_REGISTER,)), None
        sess = self.session()
        actor = sess.account.name if sess else "(no session)"
        why = None
        if sess is None:
            why = "no session: log in first"
        elif not _same_origin():
            why = "the request came from another origin"
        elif not hmac.compare_digest((request.form.get("csrf") or "").encode(),
                                     sess.csrf.encode()):
            why = "the request did not carry this session's CSRF token"
        elif (refusal := self.password_refusal()) is not None:
            why = refusal
        else:
            now = reg.account(sess.account.name)
            if now is None or not now.has("signatory"):
                why = (f"account {sess.account.name} does not hold the signatory role "
                       f"(roles: {', '.join(now.roles if now else ()) or 'none'}"
                       f"{'' if now is None or now.active else ', disabled'})")
        if why is not None:
            self.audit(actor, "station sign refused", name, {"why": why})
            return Outcome(403, False, "Refused: nothing was signed",
                           reasons=(why,)), sess
        assert sess is not None
        return self._issue(reg, sess, run_dir(name)), sess

    def sign_page(self, name: str, run_dir: Callable[[str], Path], back: str,
                  file_url: Callable[[str], str]) -> tuple[str, int]:
        """The sign request for run `name` (`run_dir(name)` its folder), answered with the
        page saying what came of it; `back` is the run's page, `file_url(name)` a file of
        the run's."""
        outcome, sess = self.sign(name, run_dir)
        still = self.session() is not None
        return render_template("signed.html.j2", run=name, outcome=outcome,
                               version=bench.__version__, back=back,
                               pdf_url=file_url(layout.CERTIFICATE_PDF),
                               dcc_url=file_url(layout.CERTIFICATE_DCC),
                               logged_out=sess is not None and not still), outcome.status

    def _issue(self, reg: Register, sess: Session, run_path: Path) -> Outcome:
        from bench.app.certificate.authorise import EXIT_ISSUED, authorise, register_of
        from bench.app.register import AuthError, RegisterError
        from bench.core.lab import LabError

        lab_file = self.settings.lab_file
        try:
            run_reg = register_of(run_path, lab_file)
        except LabError as e:
            return Outcome(422, False, "Not issued", reasons=(str(e),))
        if not same_register(run_reg, reg.url):
            where = (f"the lab file {lab_file}" if lab_file else
                     f"the run's own lab file ({run_path / layout.LAB})")
            said = f"names register {_shown_of(run_reg)}" if run_reg else "names no register"
            return Outcome(422, False, "Not issued", reasons=(
                f"{where} {said}, not this station's ({self.register.shown()}): a "
                "certificate is issued through the register the station authenticates "
                "against; start the station with --lab FILE naming it",))
        draft = request.form.get("draft") or ""
        if not draft or draft != sha256_of(run_path / layout.RESULT):
            return Outcome(409, False, "Not issued: the draft changed", reasons=(
                "result.json is not the one the page showed when it was opened (analysed "
                "again, or issued meanwhile): open the run's page again and review it",))
        password = request.form.get("password") or ""
        reason = (request.form.get("reason") or "").strip() or None
        try:
            reg.authenticate(sess.account.name, password, "signatory")  # audits a refusal
        except AuthError:
            sess.strikes += 1
            left = STRIKES - sess.strikes
            if left <= 0:
                self.sessions.end(request.cookies.get(SESSION_COOKIE))
                self.audit(sess.account.name, "station session ended", sess.account.name,
                           {"why": f"{STRIKES} wrong passwords at signing"})
            return Outcome(422, False, "Not issued: the password was not accepted", reasons=(
                f"the password is not {sess.account.name}'s: nothing was signed or issued"
                + (f" ({left} more attempt{'s' if left != 1 else ''} before this "
                   "session ends)" if left > 0 else "; the session has ended: log in again"),))
        except RegisterError as e:
            return Outcome(422, False, "Not issued", reasons=(str(e),))
        if not self._sign_lock.acquire(timeout=SIGN_WAIT_S):
            return Outcome(409, False, "Not issued: another signing is under way",
                           reasons=("try again in a minute",))
        lines: list[str] = []
        err, out = io.StringIO(), io.StringIO()
        try:
            # authorise writes its refusal to stderr; the lock keeps this the only writer
            with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
                try:
                    code = authorise(run_path, sess.account.name, reason, lab_file=lab_file,
                                     line=lines.append, password=lambda _prompt: password)
                except RegisterError as e:
                    print(f"  - {e}", file=err)
                    code = 2
        finally:
            self._sign_lock.release()
        lines += [x for x in out.getvalue().splitlines() if x.strip()]
        if code == EXIT_ISSUED:
            return Outcome(200, True, "Issued", tuple(lines))
        return Outcome(422 if code == 2 else 500, False,
                       "Not issued" if code == 2 else "Not issued: the issue failed",
                       tuple(lines), refusal_reasons(err.getvalue()))


def _shown_of(url: str | None) -> str:
    from bench.app.register import redact

    return redact(url) if url else "none"


def _same_origin() -> bool:
    """A POST's Origin (browsers send one) names this server; none given: not a browser's
    cross-site request (SameSite=Strict keeps the cookie from those anyway)."""
    origin = request.headers.get("Origin")
    if origin is None:
        return True
    parts = urlsplit(origin)
    return parts.scheme in ("http", "https") and parts.netloc == request.host


def _safe_next(target: str | None) -> str:
    """Where to go after logging in: a path on this server only."""
    if not target or not target.startswith("/") or target.startswith("//") or "\\" in target:
        return "/"
    return target


def _local_record(run_path: Path) -> str:
    from bench.app.certificate import register as cert_register

    try:
        issues = cert_register.issues(run_path)
    except (OSError, ValueError):
        return "unreadable"
    if not issues:
        return "draft"
    last = issues[-1]
    return f"certificate {last.number}, authorised by {last.signatory or 'nobody'}"


def _register_revisions(reg: Register, run_path: Path) -> list[IssuedRevision]:
    """The run's issued revisions as the register holds them."""
    from bench.app.register import RegisterError
    from bench.app.register.runs import run_uid_of

    try:
        number = reg.number_of_run(run_uid_of(run_path))
    except RegisterError:       # no readable meta.json, or a run from before its uid
        return []
    if not number:
        return []
    return [IssuedRevision(r.shown_number, str(r.revision),
                           (f"withdrawn {r.withdrawn_utc} by {r.withdrawn_by}: "
                            f"{r.withdrawn_reason}" if r.withdrawn_reason else r.status),
                           r.signatory_name, r.meaning, r.issued_utc, r.reason or "")
            for r in reg.revisions(number)]


# -- the routes -------------------------------------------------------------------------------

def install(app: Flask, settings: StationSettings, run_dir: Callable[[str], Path]) -> Signing:
    """Add login, logout, the sign request and the audit page to the station's app."""
    signing = Signing(settings)
    _add_session_routes(app, signing)

    @app.post("/run/<name>/sign")
    def sign(name: str) -> tuple[str, int]:
        return signing.sign_page(name, run_dir, url_for("run_page", name=name),
                                 lambda f: url_for("files", name=name, filename=f))

    @app.get("/audit")
    def audit_page() -> tuple[str, int]:
        sess = signing.session()
        if sess is None or not (sess.has("quality") or sess.has("admin")):
            abort(403, "the audit trail is shown to quality and admin accounts")
        reg = signing.register.get()
        if reg is None:
            abort(503, signing.register.error or NO_REGISTER)
        rows = reg.audit_rows()[-200:][::-1]
        check = reg.audit_check()
        return render_template("audit.html.j2", rows=rows, check=check,
                               register=signing.register.shown(),
                               version=bench.__version__), 200

    return signing


def _add_session_routes(app: Flask, signing: Signing) -> None:
    """Log in (name and password, from this host or the lab's password networks), log
    out, and what every page shows of the session."""

    @app.context_processor
    def who() -> dict[str, Account | str | bool | None]:
        sess = signing.session()
        return {"account": sess.account if sess else None,
                "session_csrf": sess.csrf if sess else "",
                "signing_enabled": signing.enabled,
                "sees_audit": bool(sess and (sess.has("quality") or sess.has("admin")))}

    def login_page(status: int = 200, error: str | None = None) -> tuple[str, int]:
        refusal = signing.password_refusal()
        return render_template(
            "login.html.j2", version=bench.__version__, enabled=signing.enabled,
            no_register=NO_REGISTER, register=signing.register.shown(),
            register_error=signing.register.error, local=refusal is None,
            remote_refused=refusal, token=signing.sessions.login_token(),
            next=_safe_next(request.values.get("next")), error=error), status

    @app.get("/login")
    def login() -> tuple[str, int]:
        if signing.enabled:
            signing.register.get()          # so the page can say it cannot be reached
        return login_page()

    @app.post("/login")
    def login_post() -> Response | tuple[str, int]:
        from bench.app.register import AuthError, RegisterError

        if not signing.enabled:
            return login_page(403, NO_REGISTER)
        if (refusal := signing.password_refusal()) is not None:
            return login_page(403, refusal)
        if not _same_origin() or not signing.sessions.login_token_ok(request.form.get("token")):
            return login_page(403, "The login form has expired or came from elsewhere: "
                                   "log in again from this page.")
        client = signing.client()
        if signing.limit.blocked(client):
            return login_page(429, "Too many wrong logins from this address: try again in "
                                   f"{signing.limit.window_s / 60:.0f} minutes.")
        reg = signing.register.get()
        if reg is None:
            return login_page(503, f"The register cannot be reached: {signing.register.error}")
        name = (request.form.get("name") or "").strip()
        try:
            acct = reg.authenticate(name, request.form.get("password") or "")  # audits refusal
        except AuthError as e:
            signing.limit.failed(client)
            said = re.sub(r" \(register [^)]*\)", "", str(e))   # the URL is the station's
            return login_page(401, said if "locked" in said or "change it first" in said
                              else "Name or password not accepted.")
        except RegisterError as e:
            return login_page(503, f"The register cannot be used: {e}")
        signing.sessions.end(request.cookies.get(SESSION_COOKIE))   # never two at once
        cookie, _ = signing.sessions.start(acct)
        signing.audit(acct.name, "station login", acct.name, {"roles": list(acct.roles)})
        resp = redirect(_safe_next(request.form.get("next")), code=303)
        signing.set_session_cookie(resp, cookie)
        return resp

    @app.post("/logout")
    def logout() -> Response:
        sess = signing.session()
        if sess is not None and _same_origin() and hmac.compare_digest(
                (request.form.get("csrf") or "").encode(), sess.csrf.encode()):
            signing.sessions.end(request.cookies.get(SESSION_COOKIE))
            signing.audit(sess.account.name, "station logout", sess.account.name, {})
        elif sess is not None:
            abort(403, "the logout request did not carry this session's token")
        resp = redirect("/", code=303)
        resp.delete_cookie(SESSION_COOKIE, path="/", httponly=True, samesite="Strict",
                           secure=signing.over_tls())
        return resp
