"""`bench impact SERIAL` (issue 58): what an item found out of tolerance did to the runs
that used it, and to the certificates issued from them.

The register holds every run from its start with each stand item's serial (issue 54) and
each item's calibrations with the as-found error. The runs touched by a finding are those
that named the item and were registered on or after the last calibration that found it in
tolerance (the inventory's first record when none did) and on or before the calibration
with the finding. Each one found in the runs folders, with exactly the raw captures the
register saw, is analysed again in a copy of its folder with the as-found error applied as
a correction (`corrections.json` in the copy: the analysis reads it, never the register),
and each figure is compared with the result the register holds. A run whose raw data is
not found is listed so, never guessed.

Corrections modelled so far: a counter's time-base offset e (docs/method.md A1, "A
counter's time-base correction"): every period it timed is divided by 1 + e.

The report, its audit entry, the copy's corrections file and what is read of a result.json
are typed in bench/app/impact_codec.py (issue 60): this module reads attributes, never JSON.
"""

from __future__ import annotations

import argparse
import datetime as dt
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Iterable, Sequence
from pathlib import Path

import msgspec

from bench.app.impact_codec import (
    AuditRun,
    CheckChange,
    CorrectionEntry,
    FigureShift,
    Finding,
    ImpactAudit,
    ImpactReport,
    MalformedDocument,
    ResultView,
    RunImpact,
    audit_detail,
    encode_corrections,
    encode_report,
    result_view,
    run_meta,
)
from bench.app.register.store import (
    Account,
    Calibration,
    Equipment,
    Register,
    RegisterError,
    RunRecord,
    redact,
)
from bench.core import rundir_layout as layout

EXIT_OK, EXIT_REFUSED = 0, 2

#: a shift is marked when it exceeds this fraction of the figure's U (issue 58)
MARK_FRACTION_OF_U = 1.0 / 3.0

#: the run folder's corrections file, as the rate-ladder analysis reads it
CORRECTIONS_FILE = "corrections.json"

#: a run the register holds that was never issued (issue 58): no certificate to assess;
#: `bench authorise` applies the correction when it issues it
DRAFT_STATUS = ("draft, never issued: not assessed (bench authorise applies the correction "
                "when it issues it)")

#: the as-found error's quantity by the item's place on the stand (the last parts of its
#: `where`): a counter's time base (docs/method.md A1), a drift DMM's gain, the pulse
#: generator's amplitude (docs/method.md B, "The drift kind's instrument corrections")
FOUND_QUANTITY = {"counter": "timebase_offset_rel", "dmm": "gain_error_rel",
                  "awg": "amplitude_error_rel"}


# -- the finding and the runs it touches --------------------------------------------------

def finding_of(item: Equipment) -> Finding:
    """The latest calibration recording an as-found error, and the last one before it that
    found the item in tolerance."""
    cals = list(item.calibrations)
    at = next((i for i in range(len(cals) - 1, -1, -1) if cals[i].found_error is not None),
              None)
    if at is None:
        raise RegisterError(f"equipment {item.serial}: no as-found error is recorded (bench "
                            "register equipment update SERIAL ... --found-error V[,U])")
    cal: Calibration = cals[at]
    assert cal.found_error is not None
    ok = next((c for c in reversed(cals[:at]) if c.found == "in"), None)
    return Finding(item.serial, item.model, cal.certificate, cal.issuer, cal.calibrated_on,
                   cal.found, cal.found_error, cal.found_error_u,
                   ok.calibrated_on if ok else None, ok.certificate if ok else None)


def touched(records: Iterable[RunRecord], f: Finding) -> list[RunRecord]:
    """The runs registered on or after `since` and on or before the finding's calibration."""
    out = []
    for r in records:
        day = dt.date.fromisoformat(r.registered_utc[:10])
        if (f.since is None or day >= f.since) and \
                (f.calibrated_on is None or day <= f.calibrated_on):
            out.append(r)
    return out


def run_folders(roots: Sequence[Path]) -> dict[str, Path]:
    """Run folders under the given folders (the folder itself, its children and their
    children), by the uid their meta.json names."""
    found: dict[str, Path] = {}
    for root in roots:
        candidates = [root, *(p for p in sorted(root.glob("*")) if p.is_dir()),
                      *(p for p in sorted(root.glob("*/*")) if p.is_dir())] \
            if root.is_dir() else []
        for p in candidates:
            try:
                uid = run_meta((p / layout.META).read_bytes()).run_uid
            except (OSError, MalformedDocument):
                continue
            if uid and uid not in found:
                found[uid] = p
    return found


# -- the re-analysis with the correction --------------------------------------------------

def correction_entry(f: Finding, where: str) -> CorrectionEntry | None:
    """The correction the finding makes for the item at `where`, as the corrections file
    states it (None: no correction model for that item yet)."""
    parts = where.split(".")
    if len(parts) == 3 and parts[0] == "axes" and parts[2] == "counter" \
            or len(parts) == 4 and parts[:2] == ["platform", "gyros"] and parts[3] == "dmm" \
            or where == "platform.awg":
        return CorrectionEntry(where, f.serial, f.model, FOUND_QUANTITY[parts[-1]], f.error,
                               f.error_u,
                               f"as-found error of calibration {f.certificate} ({f.issuer}"
                               + (f", {f.calibrated_on.isoformat()}" if f.calibrated_on
                                  else "") + ")")
    return None


def reanalyse_corrected(folder: Path, corrections: Sequence[CorrectionEntry]
                        ) -> tuple[ResultView | None, str]:
    """The run's raw captures analysed again in a copy of its folder whose corrections file
    states `corrections`; (result, "") or (None, why not)."""
    with tempfile.TemporaryDirectory(prefix="ratebench-impact-") as tmp:
        copy = Path(tmp) / folder.name
        shutil.copytree(folder, copy, ignore=shutil.ignore_patterns(
            layout.RESULT, "*.pdf", "*.html", "*.dcc.xml", layout.ISSUED))
        (copy / CORRECTIONS_FILE).write_text(encode_corrections(tuple(corrections)),
                                             encoding="utf-8")
        done = subprocess.run([sys.executable, "-m", "bench.app.reanalyse", str(copy)],
                              capture_output=True, text=True, timeout=3600)
        again = copy / layout.RESULT
        if done.returncode != 0 or not again.is_file():
            why = (done.stderr.strip().splitlines() or ["no result"])[-1]
            return None, f"not re-analysed: {why}"
        try:
            return result_view(again.read_bytes()), ""
        except MalformedDocument as e:
            return None, f"not re-analysed: {e}"


# -- figures and checks -------------------------------------------------------------------

def shifts(issued: ResultView, corrected: ResultView) -> list[FigureShift]:
    """Each figure's shift, corrected minus issued, in its unit and over its issued U."""
    out = []
    for where, figures in issued.figures.items():
        again = corrected.figures.get(where, {})
        for name, f in figures.items():
            if name not in again:
                continue
            shift = again[name].value - f.value
            out.append(FigureShift(where, name, f.unit, f.value, again[name].value, shift,
                                   f.U, shift / f.U, abs(shift) > MARK_FRACTION_OF_U * f.U))
    return out


def check_changes(issued: ResultView, corrected: ResultView) -> list[CheckChange]:
    before, after = issued.verdicts(), corrected.verdicts()
    return [CheckChange(k[0], k[1], k[2], v, after.get(k, "absent"))
            for k, v in before.items() if after.get(k, "absent") != v]


# -- the assessment -----------------------------------------------------------------------

def assess(reg: Register, serial: str, roots: Sequence[Path]
           ) -> tuple[Finding, list[RunImpact]]:
    item = next(iter(reg.equipment(serial)), None)
    if item is None:
        raise RegisterError(f"equipment {serial!r} is not in the inventory")
    finding = finding_of(item)
    folders = run_folders(roots)
    return finding, [_impact_on(reg, rec, serial, finding, folders.get(rec.uid))
                     for rec in touched(reg.runs_using(serial), finding)]


def _impact_on(reg: Register, rec: RunRecord, serial: str, finding: Finding,
               folder: Path | None) -> RunImpact:
    """What the finding did to one run: analysed again with the correction, or why not."""
    import bench
    from bench.app.register.runs import raw_digests

    where = next((str(i.get("where")) for i in rec.items if i.get("serial") == serial), "?")
    number = reg.number_of_run(rec.uid)
    issued, unreadable = None, ""
    try:
        issued = result_view(rec.result) if rec.result is not None else None
    except MalformedDocument as e:
        unreadable = f"not re-analysed: the register's result: {e}"
    imp = RunImpact(uid=rec.uid, registered_utc=rec.registered_utc, where=where,
                    number=number, revisions=tuple(
                        r.shown_number + ("" if r.status == "issued" else f" ({r.status})")
                        for r in reg.revisions(number)) if number else (),
                    folder=None if folder is None else str(folder),
                    customer=issued.customer if issued else None)

    def status(why: str) -> RunImpact:
        return msgspec.structs.replace(imp, status=why)

    if folder is None:
        return status("raw data not found")
    if number is None:      # nothing was stated to a customer; its issue corrects it
        return status(DRAFT_STATUS)
    if raw_digests(folder) != rec.raw or not rec.raw:
        return status("raw data not found (the raw captures in the folder are not the ones "
                      "the register saw)")
    if issued is None:
        return status(unreadable or "not re-analysed: the register holds no result of the run")
    if rec.version != bench.__version__:
        return status(f"not re-analysed: measured with ratebench {rec.version}, this is "
                      f"{bench.__version__}")
    corr = correction_entry(finding, where)
    if corr is None:
        return status(f"not re-analysed: no correction model for {where} yet")
    again, why = reanalyse_corrected(folder, [corr])
    if again is None:
        return status(why)
    return msgspec.structs.replace(imp, status="re-analysed",
                                   figures=tuple(shifts(issued, again)),
                                   checks_changed=tuple(check_changes(issued, again)))


def report_of(reg_url: str, f: Finding, impacts: Sequence[RunImpact]) -> ImpactReport:
    """The document `bench impact --json` writes and `--report` lays out."""
    return ImpactReport(redact(reg_url), f, MARK_FRACTION_OF_U, tuple(impacts))


def report_text(f: Finding, impacts: Sequence[RunImpact]) -> list[str]:
    """The summary table first, then each re-analysed run's figures; * marks |shift| > U/3."""
    done = [i for i in impacts if i.reanalysed]
    missing = [i for i in impacts if i.status.startswith("raw data not found")]
    drafts = [i for i in impacts if i.status == DRAFT_STATUS]
    lines = [f"Impact of {f.model} serial {f.serial}: as-found error {f.error:g}"
             + ("" if f.error_u is None else f" (U {f.error_u:g})")
             + f", calibration {f.certificate} ({f.issuer}"
             + (f", {f.calibrated_on.isoformat()}" if f.calibrated_on else "") + ")",
             "runs that used it since "
             + (f"its last calibration found in tolerance ({f.since_certificate}, "
                f"{f.since.isoformat()})" if f.since else "the inventory's first record")
             + f": {len(impacts)}; re-analysed with the correction: {len(done)}; raw data "
             f"not found: {len(missing)}; drafts never issued: {len(drafts)}",
             "",
             f"{'run':<34} {'certificate':<16} {'largest shift/U':>15} {'checks changed':>14}"
             "  status"]
    for i in impacts:
        lg = i.largest()
        big = "" if lg is None else f"{lg.shift_over_u:+.3f}" + (" *" if lg.marked else "  ")
        lines.append(f"{i.uid:<34} {', '.join(i.revisions) or i.number or 'not issued':<16} "
                     f"{big:>15} {len(i.checks_changed) if i.reanalysed else '':>14}"
                     f"  {i.status}")
    lines.append(f"(* a shift over {MARK_FRACTION_OF_U:.2g} of the figure's U)")
    for i in done:
        lines += ["", f"run {i.uid}" + (f", certificate {i.number}" if i.number else "")
                  + f" ({i.where}), each figure corrected minus issued:",
                  f"  {'where':<30} {'figure':<38} {'unit':<8} {'issued':>14} "
                  f"{'corrected':>14} {'shift':>11} {'U':>10} {'shift/U':>9}"]
        for s in i.figures:
            lines.append(f"  {s.where:<30} {s.name:<38} {s.unit:<8} {s.issued:>14.7g} "
                         f"{s.corrected:>14.7g} {s.shift:>11.3g} {s.u_issued:>10.3g} "
                         f"{s.shift_over_u:>+9.3f}" + (" *" if s.marked else ""))
        for c in i.checks_changed:
            at = "" if c.set_rate_dps is None else f" {c.set_rate_dps:g} deg/s"
            lines.append(f"  conformity CHANGES: {c.axis}{at} "
                         f"{c.quantity}: issued {c.issued}, corrected {c.corrected}")
        if not i.checks_changed:
            lines.append("  conformity: no outcome changes")
    return lines


def _write_report(args: argparse.Namespace, reg: Register, report: ImpactReport
                  ) -> dict[str, str]:
    """`--report DIR`: the report as JSON, PDF and HTML and the per-customer drafts
    (bench/app/impact_report.py); each file's SHA-256 for the audit entry."""
    if not getattr(args, "report", None):
        return {}
    from bench.app.impact_report import digests, write_report

    paths = write_report(Path(args.report), report, encode_report(report),
                         reg.setting("issuer.name") or "the laboratory",
                         dt.datetime.now(dt.UTC).date().isoformat())
    for p in paths:
        print(f"wrote {p}", file=sys.stderr)
    return digests(paths)


def audit_of(report: ImpactReport, written: dict[str, str]) -> ImpactAudit:
    """The audit entry of the assessment: the finding, each run's outcome, the
    certificates touched and the report's files."""
    return ImpactAudit(
        nonconforming_work="ISO/IEC 17025 7.10: the item found out of tolerance",
        report=written or None, finding=report.finding,
        runs=tuple(AuditRun(i.uid, i.number, i.status, i.largest_shift_over_U,
                            len(i.checks_changed)) for i in report.runs),
        certificates=tuple(sorted({i.number for i in report.runs if i.number})))


def cmd_impact(args: argparse.Namespace) -> int:
    from bench.app.register.commands import register_url
    from bench.app.register.credentials import Passwords

    try:
        url = register_url(args)
        remote = url.startswith(("http:", "https:"))
        with Register.open(url, migrate=not remote, create=False) as reg:
            acting: Account = reg.authenticate(
                args.as_account, Passwords(args.password_stdin).next(
                    f"password of {args.as_account}: "), "quality")
            finding, impacts = assess(reg, args.serial, [Path(p) for p in args.runs or []])
            report = report_of(url, finding, impacts)
            written = _write_report(args, reg, report)
            reg.impact_assessed(acting, args.serial, audit_detail(audit_of(report, written)))
    except RegisterError as e:
        print(f"bench impact: {e}", file=sys.stderr)
        return EXIT_REFUSED
    if args.json:
        Path(args.json).write_text(encode_report(report), encoding="utf-8")
    print("\n".join(report_text(finding, impacts)))
    return EXIT_OK
