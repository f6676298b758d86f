"""`bench authorise RUN_DIR --signatory NAME [--reason TEXT]`: issue the run's draft.

`bench run` and `bench analyze` write a draft (DRAFT, NOT AUTHORISED). Issuing it is a
person's decision (ISO/IEC 17025 7.8.2.1 o): an authorised signatory named in the lab
settings reviews the draft and runs this command, which
1. refuses (exit 2, every reason printed) when the signatory is not one the lab file
   authorises, when a re-issue gives no reason, or when a pre-issue check objects;
2. renders the issue into `issued/<number>/` (PDF, HTML, the DCC naming the authoriser as
   mainSigner, signed with the lab's key where one is configured, and the result.json it
   states), written beside and moved into place only when all of it succeeded;
3. records who, when, why and what changed in the run's register (register.py), marks the
   revision it replaces withdrawn (a WITHDRAWN.txt beside its files, never a change to
   them: 7.8.8), and copies the issue to the run directory's certificate.* files.

Pre-issue checks: `PRE_ISSUE_CHECKS` is a list of functions `check(IssueContext) ->
list[str]`, each returning the reasons to refuse (none: no objection). Other parts of the
bench add theirs with `add_pre_issue_check` (measurement assurance: an instrument out of
statistical control and not reviewed). A check that raises refuses the issue too: an
issue nobody could check is not issued.
"""

from __future__ import annotations

import argparse
import contextlib
import contextvars
import hashlib
import os
import shutil
import sys
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from pathlib import Path

from bench.app.certificate import (
    HTML_NAME,
    PDF_NAME,
    register,
    render_files,
    render_issue,
    result_digest,
)
from bench.app.certificate.build import Sources, stand_of
from bench.app.certificate.revisions import statement_changes
from bench.app.register.runs import folder_problems, run_uid_of
from bench.app.register.store import (
    MEANING_ISSUE,
    SIGNING_SETTING,
    Account,
    Receipt,
    Register,
    RunRecord,
)
from bench.core import rundir_layout as layout
from bench.core.config import dcc_refs
from bench.core.journal_codec import json_leaves
from bench.core.lab import Lab, LabError, Signatory, run_lab
from bench.core.settings_codec import identities, lab_keys
from bench.core.traceability import identity_problems, with_declared_serials
from bench.report.result_frame import ResultFrame

EXIT_ISSUED, EXIT_REFUSED, EXIT_FAILED = 0, 2, 3
ISSUED_DIR = layout.ISSUED
WITHDRAWN_NAME = "WITHDRAWN.txt"
RESULT_NAME = layout.RESULT
DCC_NAME = layout.CERTIFICATE_DCC


@dataclass(frozen=True)
class IssueContext:
    """What a pre-issue check may look at: the run, its result, the lab, who issues."""

    run_path: Path
    src: Sources                              # the run decoded (result.json, meta, stand)
    lab: Lab
    signatory: Signatory
    reason: str | None
    previous: tuple[register.Issue, ...]     # the issues recorded so far, oldest first
    simulated: bool                           # twins, not instruments
    records_url: str | None = None            # the records (None: the run's default)
    lab_register: Register | None = None      # the lab register (bench.app.register)

    @property
    def frame(self) -> ResultFrame:
        """The result's header, checks and verdict, typed (malformed parts dropped)."""
        return self.src.frame


PreIssueCheck = Callable[[IssueContext], list[str]]


def _complete(ctx: IssueContext) -> list[str]:
    verdict = str(ctx.frame.verdict or "incomplete").lower()
    if verdict not in ("pass", "fail"):
        return [f"the run's verdict is {verdict!r}: an incomplete run certifies nothing "
                f"(`bench run --resume {ctx.run_path}` completes it)"]
    return []


def _reason_for_reissue(ctx: IssueContext) -> list[str]:
    if ctx.previous and not (ctx.reason or "").strip():
        return [f"certificate {ctx.previous[-1].number} is already issued: a re-issue "
                "withdraws it and must say why (--reason TEXT; ISO/IEC 17025 7.8.8)"]
    return []


def _identities(ctx: IssueContext) -> list[str]:
    """On a real stand every instrument a value rests on must be uniquely identified; on
    twins the certificate prints what they reported and says it describes no item."""
    if ctx.simulated:
        return []
    found = ctx.frame.instruments
    if not found:
        return ["the run recorded no instrument identities (result.json instruments)"]
    stand = ctx.src.stand_file
    return [f"{p} (ISO/IEC 17025 6.4.13 a)"
            for p in identity_problems(with_declared_serials(identities(found), stand))]


def _assurance(ctx: IssueContext) -> list[str]:
    """ISO/IEC 17025 7.7: no issue resting on an instrument out of statistical control
    until a review is recorded (`bench control SERIAL --review TEXT --by NAME`). Also
    refreshes the run's assurance.json, so the issued certificate states each
    instrument's status and the review."""
    from bench.app.records.assurance import assurance_refusals

    return assurance_refusals(ctx.run_path, ctx.records_url)


#: the checks every issue passes; extend with add_pre_issue_check
PRE_ISSUE_CHECKS: list[PreIssueCheck] = [_complete, _reason_for_reissue, _identities,
                                         _assurance]


def add_pre_issue_check(check: PreIssueCheck) -> PreIssueCheck:
    """Register a check run before every issue (usable as a decorator)."""
    if check not in PRE_ISSUE_CHECKS:
        PRE_ISSUE_CHECKS.append(check)
    return check


def refusals(ctx: IssueContext, checks: list[PreIssueCheck] | None = None) -> list[str]:
    """Every reason not to issue, from every check (a check that fails refuses)."""
    out: list[str] = []
    for check in PRE_ISSUE_CHECKS if checks is None else checks:
        try:
            out += [str(r) for r in check(ctx) or ()]
        except Exception as e:  # noqa: BLE001 - an issue nobody could check is not issued
            out.append(f"pre-issue check {getattr(check, '__name__', check)!r} could not "
                       f"run: {type(e).__name__}: {e}")
    return out


# -- what changed between two issued revisions -------------------------------------------

def changes_between(old: bytes | None, new: bytes, old_html: str | None = None, new_html: str | None = None,
                    limit: int = 12) -> tuple[str, ...]:
    """What differs between the revision replaced and this one, as facts: the values of
    result.json, then every statement of the certificate (assurance, traceability,
    conformity text, conditions...: bench/app/certificate/revisions.py) when both
    revisions' HTML are given (issue 43: a changed assurance statement is a change).
    `old` and `new` are the revisions' result.json as stored."""
    if old is None:
        values = ["the replaced revision's result.json is not kept; differences not stated"]
    else:
        before, after = json_leaves(old), json_leaves(new)
        values = [f"{k}: {before.get(k, 'absent')!r} -> {after.get(k, 'absent')!r}"
                  for k in dict.fromkeys([*before, *after]) if before.get(k) != after.get(k)]
    said = None if new_html is None else statement_changes(old_html, new_html)
    if new_html is not None and said is None:
        said = ("the replaced revision's certificate.html is not kept; its statements are "
                "not compared",)
    if not values and not said:
        return ("results unchanged (result.json equal to the replaced revision's)"
                + ("" if said is None else "; every statement unchanged (the replaced "
                   "revision's certificate.html compared)"),)
    shown = [*values[:limit], *(said or ())[:max(limit - len(values), 0)]]
    if len(values) > limit:
        shown.append(f"and {len(values) - limit} more value(s) of result.json")
    rest = len(said or ()) - max(limit - len(values), 0)
    if rest > 0:
        shown.append(f"and {rest} more statement(s) of the certificate")
    return tuple(shown)


# -- the command ----------------------------------------------------------------------------

def _err(text: str) -> None:
    print(text, file=sys.stderr, flush=True)


#: where `authorise_collecting` gathers the reasons of a refusal (per thread and task)
_REASONS: contextvars.ContextVar[list[str] | None] = contextvars.ContextVar(
    "authorise_reasons", default=None)


def authorise_collecting(run_path: Path, signatory_name: str, reason: str | None = None,
                         lab_file: str | None = None, line: Callable[[str], None] = print,
                         password: Callable[[str], str] | None = None) -> tuple[int, list[str]]:
    """`authorise`, with the reasons of a refusal returned as well as printed (the
    station shows them on the page)."""
    reasons: list[str] = []
    token = _REASONS.set(reasons)
    try:
        return authorise(run_path, signatory_name, reason, lab_file, line, password), reasons
    finally:
        _REASONS.reset(token)


def _refuse(reasons: list[str], run_path: Path) -> int:
    gathered = _REASONS.get()
    if gathered is not None:
        gathered += reasons
    _err(f"bench authorise: not issued ({run_path}):")
    for r in reasons:
        _err(f"  - {r}")
    return EXIT_REFUSED


def issue_dir(run_path: Path, number: str) -> Path:
    return Path(run_path) / ISSUED_DIR / number


def register_of(run_path: Path, lab_file: str | None) -> str | None:
    """The register the lab file names, by the one rule for a run's own command
    (bench/app/labfile.py): the run's copy, a --lab that differs from it refused; a run
    that copied none, --lab, else $BENCH_LAB_SETTINGS. Never the procedure's
    `certificate:` block, which the operator edits."""
    from bench.app import labfile
    from bench.core.lab import load_lab

    try:
        path = labfile.for_run(Path(run_path), lab_file)
    except labfile.LabChoiceError as e:
        raise LabError(str(e)) from None
    return load_lab(path).register_url if path is not None and path.is_file() else None


def _files_sha256(folder: Path) -> dict[str, str]:
    """The digests of the files as stored (what `bench verify --register` compares)."""
    return {name: hashlib.sha256((folder / name).read_bytes()).hexdigest()
            for name in (RESULT_NAME, PDF_NAME, DCC_NAME, HTML_NAME)}


def authorise(run_path: Path, signatory_name: str, reason: str | None = None,
              lab_file: str | None = None, line: Callable[[str], None] = print,
              password: Callable[[str], str] | None = None) -> int:
    """Issue the run's draft through the lab register; returns the exit status (0 issued,
    2 refused, 3 failed). `password(prompt)` gives the signatory's password."""
    from bench.app.register import Register, RegisterError, redact

    run_path = Path(run_path)
    inputs = _run_inputs(run_path, lab_file)
    if isinstance(inputs, list):
        return _refuse(inputs, run_path)
    result_bytes, src, lab, url = inputs
    try:
        reg = Register.open(url, migrate=False)
    except RegisterError as e:
        return _refuse([f"the register cannot be reached: {e}"], run_path)
    with reg:
        try:
            acct = reg.authenticate(signatory_name, (password or _ask)(
                f"password of {signatory_name} (e-signature, register {redact(url)}): "),
                "signatory")
            uid = run_uid_of(run_path)
            record = reg.run_record(uid)
            number = reg.number_of_run(uid)
            issued = reg.revisions(number) if number else []
        except (RegisterError, OSError, ValueError) as e:
            return _refuse([str(e)], run_path)
        if record is None:      # issue 54: no register, no issue
            return _refuse([f"the lab register {redact(url)} holds no record of this run "
                            f"(uid {uid}): it was not registered when it started (no "
                            "register was named, or another one), and a run the register "
                            "did not see start is never issued; the draft stays a draft "
                            "(measure again under the lab's register)"], run_path)
        changed = folder_problems(record, run_path)
        if changed:
            return _refuse(["the run folder no longer matches the lab register's record of "
                            "the run (what is issued is what was measured):", *changed],
                           run_path)
        again = _corrected_record(reg, record, run_path, reason, bool(issued), line)
        if isinstance(again, list):
            return _refuse(again, run_path)
        if again is not record:     # issue 58: issued from the corrected, registered result
            record = again
            src = Sources.decode(record.result_bytes or b"{}", run_path)
        result_bytes = record.result_bytes or result_bytes     # the register's, checked equal
        who = Signatory(acct.full_name, acct.function or "", True)
        previous = tuple(register.Issue(r.shown_number, r.revision, r.issued_utc,
                                        signatory=r.signatory_name) for r in issued)
        ctx = IssueContext(run_path, src, lab, who, reason, previous,
                           bool(stand_of(src).simulated), lab.records_url, reg)
        refused = refusals(ctx)
        held = reg.issuer()
        if "issuer.name" not in held:
            refused.append("the lab register holds no issuer identity: an admin sets it "
                           "(bench register settings set issuer.name TEXT, and issuer."
                           "address, issuer.code, issuer.accreditation, issuer.prefix); a "
                           "certificate names its issuer from the register, not from a file")
        if refused:
            return _refuse(refused, run_path)
        lab = issuer_lab(lab, held)
        try:
            number = number or reg.allocate(uid, lab.prefix, acct.name)
        except RegisterError as e:
            return _refuse([str(e)], run_path)
        return _issue(run_path, result_bytes, lab, reg, acct, who, number, previous, reason,
                      line, record)


def _run_inputs(run_path: Path, lab_file: str | None
                ) -> tuple[bytes, Sources, Lab, str] | list[str]:
    """What an issue starts from: the run's result.json (as bytes and decoded with the
    run's meta, stand and events), the laboratory and the register's URL; a list: the
    reasons to refuse."""
    from bench.app.dcc.settings import resolve_settings

    result_file = run_path / RESULT_NAME
    if not result_file.is_file():
        return [f"{result_file}: not found (`bench analyze {run_path}` writes it)"]
    result_bytes = result_file.read_bytes()
    try:
        src = Sources.decode(result_bytes, run_path)
    except ValueError as e:
        return [f"{result_file}: not JSON: {e}"]
    try:
        own = run_lab(run_path, lab_keys(src.frame.certificate))
        lab = resolve_settings(dcc_refs(src.stand_file), lab_file, base=own)
        if own.name and not lab.name:   # a lab file that names only the register and
            lab = replace(own, signing=lab.signing,     # key: the run's laboratory, as the
                          require_signed_dcc=lab.require_signed_dcc)   # PDF prints it
        url = register_of(run_path, lab_file)
    except LabError as e:
        return [str(e)]
    if not url:
        return [f"the lab file ({lab_file or run_path / layout.LAB}) names no register "
                "(register: URL): a certificate is issued only through the lab's "
                "register, which authenticates the signatory and allocates the number "
                "(docs/register.md); the draft stays a draft"]
    return result_bytes, src, lab, url


def _corrected_record(reg: Register, record: RunRecord, run_path: Path, reason: str | None,
                      reissue: bool, line: Callable[[str], None]) -> RunRecord | list[str]:
    """Issue 58: the record to issue from. When an item the run used carries an as-found
    error whose span touches the run and the registered result does not apply it yet, the
    run is analysed again with the correction (the run folder's corrections file, then a
    registered analysis, bench/app/certificate/corrected.py) and the new record returned;
    a list: the reasons to refuse."""
    from bench.app.certificate import corrected

    due, refused = corrected.corrections_due(reg, record)
    if refused or not due:
        return refused or record
    if corrected.already_applied(record.result, due):
        return record
    serials = ", ".join(sorted({corr.serial for corr in due}))
    if reissue and not (reason or "").strip():
        return [f"the register holds an as-found error of {serials} that touches this run: a "
                "corrected re-issue analyses it again with the correction and must say why "
                "(--reason TEXT; ISO/IEC 17025 7.8.8)"]
    path = corrected.write_corrections(run_path, due, reason)
    said = (reason or "").strip()
    why_again = f"corrected re-issue, as-found error of {serials}" + (f": {said}" if said
                                                                      else "")
    ok, why = corrected.analyse_corrected(run_path, why_again)
    again = corrected.registered_again(reg, record.uid, run_path) if ok else None
    if again is None:
        path.unlink(missing_ok=True)        # the folder as the register holds it
        why = why or "the lab register did not receive the new result"
        return [f"the run could not be analysed again with the correction ({why}): not "
                "issued"]
    line(f"analysed again with the as-found error of {serials} as a correction ({path}); "
         f"the lab register holds it as a new analysis of run {record.uid} (result SHA-256 "
         f"{again.result_sha256})")
    return again


def issuer_lab(lab: Lab, held: Mapping[str, str]) -> Lab:
    """The lab as the register names the issuer (issue 54): its name, address, code,
    accreditation and number prefix from the register's settings; what the register does
    not hold is not printed, whatever a file says."""
    return replace(lab, name=held.get("issuer.name"), address=held.get("issuer.address"),
                   code=held.get("issuer.code"), accreditation=held.get("issuer.accreditation"),
                   prefix=held.get("issuer.prefix") or lab.prefix)


def _ask(prompt: str) -> str:
    from bench.app.register.credentials import Passwords

    return Passwords(False).next(prompt)


def _issue(run_path: Path, result_bytes: bytes, lab: Lab, reg: Register, acct: Account, who: Signatory, number: str,
           previous: tuple[register.Issue, ...], reason: str | None,
           line: Callable[[str], None], record: RunRecord) -> int:
    """Render the issue, record it in the register (which may still refuse: a concurrent
    issue of the same revision), then move it into place."""
    from bench.app.dcc.output import write_dcc
    from bench.app.fleet.sync import bench_name
    from bench.app.register import RegisterError, redact

    old, old_html = _replaced_revision(run_path, previous)
    revision = len(previous) + 1
    try:    # the trail's entry first; its time is the register's clock, not ours
        begun = reg.begin_issue(acct, number, revision, result_digest(result_bytes))
    except RegisterError as e:
        return _refuse([f"the register refused the issue: {e}"], run_path)
    issue = _new_issue(number, revision, begun, previous, result_bytes, who, reason,
                       redact(reg.url), lab, record)
    uid = record.uid
    final = issue_dir(run_path, issue.number)
    if final.exists():
        return _refuse([f"{final} exists: an issued revision's files are never "
                        "overwritten"], run_path)
    work = final.with_name(f".{issue.number}.partial")
    shutil.rmtree(work, ignore_errors=True)
    work.mkdir(parents=True)
    (work / RESULT_NAME).write_bytes(result_bytes)          # what this issue states
    # the run decoded afresh for the certificate (the pre-issue checks refreshed the
    # run's assurance.json)
    src = Sources.decode(result_bytes, run_path)
    if previous:
        # every statement compared with the replaced revision's as issued (its HTML)
        issue = render_issue(src, work, issue, lambda html: changes_between(
            old, result_bytes, old_html, html))
    else:
        render_files(src, work, issue=issue)
    signer = reg.dcc_signer(acct)
    if reg.remote:      # a lab server: its register service alone holds the key (issue 53)
        signing_lab = replace(lab, signing=None, require_signed_dcc=False)
        signing_note = ("signed by the register service" if signer else
                        "the register service holds no signing key")
    else:
        signing_lab, signing_note = designated_signing(lab, reg)
    try:
        outcome = write_dcc(run_path, src, dcc_refs(src.stand_file), lab=signing_lab, issue=issue,
                            out_dir=work, signer=signer)
    except (LabError, RegisterError) as e:
        _discard(work)
        return _refuse([f"the DCC could not be signed: {e}"], run_path)
    if not outcome.ok:
        _err(outcome.message())
        _discard(work)
        _err(f"bench authorise: not issued: the DCC does not validate ({run_path})")
        return EXIT_FAILED
    try:
        rev = reg.issue(number, revision, acct, _files_sha256(work), issue.reason,
                        {"run_dir": run_path.name, "signatory": acct.name,
                         "run_uid": uid, "bench": bench_name(run_path)})
    except RegisterError as e:
        _discard(work)
        return _refuse([f"the register refused the issue: {e}"], run_path)
    issue = replace(issue, audit_digest=rev.audit_digest)
    _publish(run_path, work, final, issue, previous)
    line(f"issued certificate {issue.number} (revision {issue.revision}), {MEANING_ISSUE} by "
         f"{who.name}" + (f", {who.function}" if who.function else "") +
         f" (account {acct.name}, authenticated by the register) at {issue.issued_utc}"
         + ("; DCC signed (XAdES)" if outcome.signed else f"; DCC not signed ({signing_note})"))
    if issue.replaces:
        line(f"withdrawn: {issue.replaces} (its files kept unchanged under "
             f"{issue_dir(run_path, issue.replaces)})")
    for name in (PDF_NAME, HTML_NAME, DCC_NAME):
        line(f"wrote {final / name}")
    _update_records(run_path, lab, src, line)
    return EXIT_ISSUED


def _replaced_revision(run_path: Path, previous: tuple[register.Issue, ...]
                       ) -> tuple[bytes | None, str | None]:
    """The revision a re-issue replaces, as issued (its result.json and HTML, kept under
    issued/): what the new revision's statements are compared with."""
    old = None
    if previous:
        kept = issue_dir(run_path, previous[-1].number) / RESULT_NAME
        old = kept.read_bytes() if kept.is_file() else None
    old_html = None
    if previous:
        kept_html = issue_dir(run_path, previous[-1].number) / HTML_NAME
        old_html = kept_html.read_text(encoding="utf-8") if kept_html.is_file() else None
    return old, old_html


def _new_issue(number: str, revision: int, begun: Receipt,
               previous: tuple[register.Issue, ...], result_bytes: bytes, who: Signatory,
               reason: str | None, register_url: str, lab: Lab,
               record: RunRecord) -> register.Issue:
    """The issue as the certificate states it, its time and trail entry the register's
    (`begun`), its issuer the register's (issuer_lab)."""
    return register.Issue(
        register.numbered(number, revision), revision, begun.issued_utc,
        previous[-1].number if previous else None, result_digest(result_bytes),
        signatory=who.name, function=who.function or None,
        reason=(reason or "").strip() or None, meaning=MEANING_ISSUE,
        register=register_url, audit_seq=begun.audit_seq, audit_entry=begun.audit_digest,
        issuer=tuple((k, v) for k, v in (("laboratory", lab.name), ("address", lab.address),
                                         ("code", lab.code),
                                         ("accreditation", lab.accreditation)) if v),
        run_uid=record.uid, run_registered_utc=record.registered_utc)


def _publish(run_path: Path, work: Path, final: Path, issue: register.Issue,
             previous: tuple[register.Issue, ...]) -> None:
    """The issue recorded in the run folder and moved into place: its files under
    issued/<number>/ (renamed whole), the replaced revision marked withdrawn, and the
    run's own PDF, HTML and DCC replaced by the issued ones."""
    register.record(run_path, issue)
    # the folder is self-contained: `bench verify issued/<n>/certificate.dcc.xml` reads
    # result.json and the register's copy beside it
    (work / register.REGISTER_NAME).write_bytes((run_path / register.REGISTER_NAME)
                                                .read_bytes())
    os.replace(work, final)
    if previous:
        _mark_withdrawn(run_path, previous[-1], issue)
    for name in (PDF_NAME, HTML_NAME, DCC_NAME):
        tmp = run_path / f"{name}.tmp"
        shutil.copyfile(final / name, tmp)
        os.replace(tmp, run_path / name)


def _update_records(run_path: Path, lab: Lab, src: Sources,
                    line: Callable[[str], None]) -> None:
    """The records cite the issued revision (number and the digests of its files as
    stored) from now on; a records database out of reach is said, not fatal: the issue
    stands in the register, and `bench records import` catches up."""
    from bench.app.records.hooks import register_run, target

    register_run(run_path, target(run_path.parent, lab.records_url), line,
                 ResultFrame.of(src.written))




def designated_signing(lab: Lab, reg: Register) -> tuple[Lab, str]:
    """The lab with the signing key only when the register designates its certificate:
    the key that signs for the lab is the register's decision, not a file's."""
    want = reg.setting(SIGNING_SETTING)
    if lab.signing is None:
        return lab, "the lab configured no key"
    try:
        have = hashlib.sha256(Path(lab.signing.certificate_file).read_bytes()).hexdigest()
    except OSError as e:
        raise LabError(f"{lab.source}: signing.certificate: {e}") from None
    if want and have == want:
        return lab, ""
    why = ("the register designates no signing certificate" if not want else
           "the lab file's signing certificate is not the one the register designates")
    return replace(lab, signing=None, require_signed_dcc=False), why


def _discard(work: Path) -> None:
    """Remove what a refused issue began to write (and `issued/` if it is left empty)."""
    shutil.rmtree(work, ignore_errors=True)
    with contextlib.suppress(OSError):
        work.parent.rmdir()


def _mark_withdrawn(run_path: Path, old: register.Issue, new: register.Issue) -> None:
    """A note beside the withdrawn revision's files; the files themselves stay as issued."""
    folder = issue_dir(run_path, old.number)
    if not folder.is_dir():
        return
    (folder / WITHDRAWN_NAME).write_text(
        f"Certificate {old.number} was WITHDRAWN on {new.issued_utc}: replaced by "
        f"certificate {new.number}, authorised by {new.signatory}.\n"
        f"Reason: {new.reason}\n" + "".join(f"Changed: {c}\n" for c in new.changes),
        encoding="utf-8")


def cmd_authorise(args: argparse.Namespace) -> int:
    from bench.app.register import RegisterError
    from bench.app.register.credentials import Passwords

    run_path = Path(args.run_dir)
    if not run_path.is_dir():
        _err(f"bench authorise: {run_path}: no such run directory")
        return EXIT_REFUSED
    try:
        pw = Passwords(args.password_stdin)
    except RegisterError as e:
        return _refuse([str(e)], run_path)

    def password(prompt: str) -> str:
        return pw.next(prompt)

    try:
        return authorise(run_path, args.signatory, args.reason, args.lab, password=password)
    except RegisterError as e:
        return _refuse([str(e)], run_path)

