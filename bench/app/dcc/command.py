"""The DCC's part of the command line: the hook after the PDF, `bench dcc`, `bench verify`.

Exit status as everywhere (CONTRACT §1): a run whose DCC does not validate has no
certificate to sign, so it ends 3 like a run whose PDF could not be written.
"""

from __future__ import annotations

import argparse
import sys
import traceback
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from bench.core import rundir_layout as layout

if TYPE_CHECKING:
    from bench.core.config import DccRefs
    from bench.core.lab import Lab
    from bench.core.yamlfile import Problem
    from bench.report.certificate.sources import Sources

EXIT_PASS, EXIT_FAIL, EXIT_INVALID, EXIT_ABORTED = 0, 1, 2, 3


def _err(text: str) -> None:
    print(text, file=sys.stderr, flush=True)


def write_run_dcc(run_path: Path, src: Sources, stand: DccRefs | None,
                  line: Callable[[str], None] = print, lab_file: str | Path | None = None,
                  warn: Callable[[str], None] = _err) -> bool:
    """Write RUN_DIR/certificate.dcc.xml after the PDF; False when the run has no valid DCC
    (the caller then exits 3), True when it was written or the run has no verdict.
    `line` and `warn` are the console's (bench.core.progress): a message, a fault."""
    from bench.app.dcc.output import write_dcc
    from bench.app.dcc.settings import SettingsError

    try:
        outcome = write_dcc(run_path, src, stand, lab_file)
    except SettingsError as e:
        warn(f"the DCC could not be written: {e}; result.json and the PDF are in {run_path}; "
             f"once fixed, `bench dcc {run_path}` writes it")
        return False
    except Exception as e:  # noqa: BLE001 - a bug to report; the PDF and result.json stand
        traceback.print_exc(file=sys.stderr)
        warn(f"the DCC could not be written: {e!r}; once fixed, `bench dcc {run_path}` "
             "writes it")
        return False
    if outcome.skipped:
        line(outcome.message())
        return True
    if outcome.ok:
        line(f"wrote {outcome.path} (valid DCC 3.3.0), a DRAFT, NOT AUTHORISED: "
             "`bench authorise` issues it")
        return True
    warn(outcome.message() + f"\nthe DCC does not validate and was kept as "
         f"{run_path / layout.CERTIFICATE_DCC_INVALID} for diagnosis; once fixed, "
         f"`bench dcc {run_path}` writes it")
    return False


def _stand_of_run(run_path: Path) -> DccRefs | None:
    """The DCC references of the run's stand file (its copy in the run directory), its
    `dcc:` key checked; None when it is malformed (said on stderr)."""
    from bench.app.dcc.settings import STAND_DCC
    from bench.core.config import dcc_refs
    from bench.core.yamlfile import YamlError, load_yaml

    path = run_path / layout.STAND
    if not path.is_file():
        return dcc_refs(None)
    try:
        doc = load_yaml(path)
    except YamlError as e:
        _err(str(e.problem))
        return None
    data = doc.data if isinstance(doc.data, dict) else {}
    problems: list[Problem] = []
    if "dcc" in data:
        STAND_DCC.check(data["dcc"], ("dcc",), doc, problems)
    for p in problems:
        _err(str(p))
    return None if problems else dcc_refs(data)


def cmd_dcc(args: argparse.Namespace) -> int:
    """`bench dcc RUN_DIR [--lab FILE]`: (re)write and validate certificate.dcc.xml."""
    from bench.report.certificate.sources import Sources  # not for the parser (test_cli_imports)

    run_path = Path(args.run_dir)
    result_file = run_path / layout.RESULT
    if not result_file.is_file():
        _err(f"{result_file}: not found; `bench analyze {run_path}` writes it from the raw data")
        return EXIT_INVALID
    try:
        src = Sources.read(result_file)
    except ValueError as e:
        _err(f"{result_file}: not JSON: {e}")
        return EXIT_INVALID
    stand = _stand_of_run(run_path)
    if stand is None:
        return EXIT_INVALID
    if not (run_path / layout.CERTIFICATE_PDF).is_file():
        _err(f"note: {run_path / layout.CERTIFICATE_PDF} is missing, so the DCC carries no "
             f"human-readable document; `bench analyze {run_path}` writes both")
    elif (copied := issued_copy(run_path)) is not None:
        # the PDF beside it is an issued revision's copy (bench authorise put it there);
        # the DCC written now is a draft and must not embed it: the draft's own PDF and
        # HTML replace the copies, the issued files under issued/ stay as they are
        from bench.app.certificate import render_files

        render_files(src, run_path)
        _err(f"note: {run_path / layout.CERTIFICATE_PDF} was the copy of issued certificate "
             f"{copied} (kept unchanged under {run_path / layout.ISSUED / copied}); a DCC written "
             "now is a DRAFT, so the draft's PDF and HTML were written beside it")
    if not write_run_dcc(run_path, src, stand, lab_file=args.lab):
        return EXIT_ABORTED
    verdict = (src.frame.verdict or "").lower()
    return {"pass": EXIT_PASS, "fail": EXIT_FAIL}.get(verdict, EXIT_ABORTED)


def issued_copy(run_path: Path) -> str | None:
    """The number of the issued revision whose PDF the run directory's certificate.pdf is,
    byte for byte (`bench authorise` copies each issue there), or None (a draft)."""
    from bench.app.certificate import register

    pdf = run_path / layout.CERTIFICATE_PDF
    if not pdf.is_file():
        return None
    data = pdf.read_bytes()
    for issue in reversed(register.issues(run_path)):
        kept = run_path / layout.ISSUED / issue.number / layout.CERTIFICATE_PDF
        if kept.is_file() and kept.read_bytes() == data:
            return issue.number
    return None


def cmd_verify(args: argparse.Namespace) -> int:
    """`bench verify FILE`: schema, signature (if signed), values against result.json."""
    from bench.app.dcc.verify import verify_file

    path = Path(args.file)
    if getattr(args, "reanalyse", False):
        if not path.is_dir():
            _err(f"{path}: --reanalyse takes a run directory")
            return EXIT_INVALID
        from bench.app.reanalyse import reanalyse

        status, lines = reanalyse(path)
        for line in lines:
            print(line)
        return status
    if not path.is_file():
        _err(f"{path}: not found")
        return EXIT_INVALID
    if path.suffix.lower() != ".xml":          # a PDF or HTML: its standing only
        if not args.register:
            _err(f"{path}: not a DCC; give --register URL to look its issue up")
            return EXIT_INVALID
        return _standing(path, args.register)
    cert = Path(args.cert) if args.cert else None
    lab = _lab_of(args.lab, path.parent)
    if cert is None and not args.ca and lab is not None and lab.signing is not None:
        cert = lab.signing.certificate_file
    report = verify_file(path, Path(args.result) if args.result else None, cert,
                         Path(args.ca) if args.ca else None, need_result=not args.no_result,
                         require_signed=bool(lab and lab.require_signed_dcc))
    print(f"{path}:")
    print("\n".join(f"  {line}" for line in report.lines))
    if args.register:
        # the register's word first: a withdrawn or unknown file gets no "OK" (issue 56)
        standing = _standing(path, args.register)
        print("verify: FAILED" if report.failed else "verify: OK" if standing == EXIT_PASS
              else "verify: the file is intact, but the register does not hold it as issued")
        return EXIT_FAIL if report.failed else standing
    print("verify: FAILED" if report.failed else "verify: OK")
    print(f"status: {_local_status(path)} (from the run directory's copy; `--register URL` "
          "asks the lab's register)")
    return EXIT_FAIL if report.failed else EXIT_PASS


def _local_status(path: Path) -> str:
    """What the file itself and the run's copy of the register say, unconfirmed."""
    from bench.app.certificate import register

    data = path.read_bytes()
    if b'id="draftStatus"' in data:
        return "not issued (draft)"
    folder = path.parent
    # an issued revision's folder keeps the copy made when it was issued; the run
    # directory's copy has every revision since
    issues = register.issues(folder.parent.parent if folder.parent.name == layout.ISSUED
                             else folder)

    run_dir = folder.parent.parent if folder.parent.name == layout.ISSUED else folder
    # the revision whose kept file is this one, byte for byte
    mine = next((i for i in issues
                 if (run_dir / layout.ISSUED / i.number / path.name).is_file()
                 and (run_dir / layout.ISSUED / i.number / path.name).read_bytes() == data), None)
    if mine is None:
        return "issued according to the file; no register entry at hand"
    later = [i for i in issues if i.revision > mine.revision]
    return (f"withdrawn (replaced by {later[0].number})" if later else
            f"issued (revision {mine.revision}, {mine.issued_utc})")


def _standing(path: Path, url: str) -> int:
    """`bench verify FILE --register URL`: issued, withdrawn or not issued, as the lab's
    register holds the file's SHA-256 (issue 42). Exit 0 issued, 1 otherwise."""
    import hashlib

    from bench.app.register import Register, RegisterError, redact

    sha = hashlib.sha256(path.read_bytes()).hexdigest()
    try:
        with Register.open(url, migrate=False) as reg:
            rev = reg.find_revision(sha)
            later = [r for r in reg.revisions(rev.number)
                     if r.revision > rev.revision] if rev else []
    except RegisterError as e:
        print(f"register: cannot be asked: {e}")
        return EXIT_FAIL
    where = redact(url)
    if rev is None:
        draft = b'id="draftStatus"' in path.read_bytes()
        print(f"register {where}: not issued" + (" (draft)" if draft else "") +
              f": no revision in the register has this file's SHA-256 {sha[:16]}...")
        return EXIT_FAIL
    what = (f"certificate {rev.shown_number} (revision {rev.revision}), {rev.meaning} by "
            f"{rev.signatory_name} at {rev.issued_utc}")
    if rev.status == "withdrawn":
        print(f"register {where}: withdrawn: {what}; withdrawn {rev.withdrawn_utc}"
              + (f" by {rev.withdrawn_by}: {rev.withdrawn_reason}" if rev.withdrawn_reason
                 else "")
              + (f", replaced by {later[-1].shown_number}" if later else ""))
        return EXIT_FAIL
    print(f"register {where}: issued: {what}")
    return EXIT_PASS


def _lab_of(lab_file: str | None, folder: Path) -> Lab | None:
    """The lab whose DCC this is: `--lab`, else $BENCH_LAB_SETTINGS, else the lab file
    copied into the run directory the file lies in (or its parent, for an issued
    revision's folder); None when none is found or it is unusable (said on stderr)."""
    import os

    from bench.app.dcc.settings import ENV_LAB, SettingsError, load_lab_file
    from bench.core.lab import RUN_COPY

    chosen = lab_file or os.environ.get(ENV_LAB)
    if not chosen:
        near = [d / RUN_COPY for d in (folder, *folder.parents[:2]) if (d / RUN_COPY).is_file()]
        if not near:
            return None
        chosen = str(near[0])
    try:
        return load_lab_file(chosen)
    except SettingsError as e:
        _err(f"note: {e}; the signer's identity is not checked against the lab's certificate")
        return None


def add_parsers(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """The `dcc` and `verify` subcommands (called by bench/app/cli.py)."""
    dcc = sub.add_parser("dcc", help="(re)write certificate.dcc.xml (PTB DCC 3.3.0) from "
                                     "result.json and validate it offline")
    dcc.add_argument("run_dir")
    dcc.add_argument("--lab", help="lab settings file (contact, persons, signing key); "
                                   "default: the stand's dcc.lab or $BENCH_LAB_SETTINGS")
    ver = sub.add_parser("verify", help="check a DCC: schema, signature, values vs result.json")
    ver.add_argument("file")
    ver.add_argument("--result", help="the run's result.json (default: beside FILE)")
    ver.add_argument("--cert", help="trusted signer certificate, PEM (default: the lab's own "
                                    "from its settings, else the one in the file)")
    ver.add_argument("--ca", help="CA certificates, PEM, to validate the signer's chain")
    ver.add_argument("--lab", help="lab settings file whose signing certificate is trusted")
    ver.add_argument("--no-result", action="store_true",
                     help="check schema and signature only (no result.json at hand)")
    ver.add_argument("--reanalyse", action="store_true",
                     help="FILE is a run directory: analyse its raw captures again (its "
                          "version, BLAS on one thread) and compare with its result.json "
                          "byte for byte; exit 0 equal, 1 differs, 2 refused")
    ver.add_argument("--register", metavar="URL",
                     help="the lab register: states issued, withdrawn or not issued (exit 0 "
                          "only for issued); FILE may then be the PDF too")


COMMANDS = {"dcc": cmd_dcc, "verify": cmd_verify}
