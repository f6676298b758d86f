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
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import math
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path

from bench.app.register import wire
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

#: a figure's unit by the suffix its U key carries (`rate_error_U_rel`: rel)
UNITS = {"rel": "1", "dps": "deg/s", "dps_per_h": "deg/s/h", "": "1", "deg": "deg",
         "s": "s", "hz": "Hz", "dph": "deg/h"}

#: the as-found error's quantity by the item's place on the stand (the last parts of its
#: `where`): a counter's time base (docs/method.md A1), a drift DMM's gain, the pulse
#: generator's amplitude (docs/method.md B, "The drift kind's instrument corrections")
FOUND_QUANTITY = {"counter": "timebase_offset_rel", "dmm": "gain_error_rel",
                  "awg": "amplitude_error_rel"}


@dataclass(frozen=True)
class Finding:
    """The item's as-found error and the span of runs it touches."""

    serial: str
    model: str
    certificate: str               # the calibration that found it
    issuer: str
    calibrated_on: dt.date | None
    found: str | None
    error: float
    error_u: float | None
    since: dt.date | None          # the last calibration that found it in tolerance
    since_certificate: str | None


@dataclass(frozen=True)
class FigureShift:
    where: str                     # e.g. axes.outer.rates[+50 deg/s]
    name: str
    unit: str
    issued: float
    corrected: float
    shift: float
    u_issued: float                # the issued figure's expanded U
    shift_over_u: float
    marked: bool                   # |shift| > U/3


@dataclass(frozen=True)
class CheckChange:
    axis: str
    set_rate_dps: float | None
    quantity: str
    issued: str
    corrected: str


@dataclass
class RunImpact:
    uid: str
    registered_utc: str
    where: str                     # the item's place on the stand (axes.outer.counter)
    number: str | None             # the certificate number the register issued, if any
    revisions: list[str] = field(default_factory=list)
    folder: str | None = None
    status: str = ""               # re-analysed | raw data not found | not re-analysed: ...
    figures: list[FigureShift] = field(default_factory=list)
    checks_changed: list[CheckChange] = field(default_factory=list)
    #: the customer the run's result names (customer, customer_address, customer_contact)
    customer: dict[str, str] | None = None

    @property
    def reanalysed(self) -> bool:
        return self.status == "re-analysed"

    def largest(self) -> FigureShift | None:
        return max(self.figures, key=lambda f: abs(f.shift_over_u), default=None)


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
                meta = json.loads((p / layout.META).read_text(encoding="utf-8"))
            except (OSError, ValueError):
                continue
            uid = meta.get("run_uid") if isinstance(meta, dict) else None
            if isinstance(uid, str) and uid and uid not in found:
                found[uid] = p
    return found


# -- the re-analysis with the correction --------------------------------------------------

def correction_entry(f: Finding, where: str) -> dict[str, object] | None:
    """The correction the finding makes for the item at `where`, as the corrections file
    states it (None: no correction model for that item yet)."""
    parts = where.split(".")
    if len(parts) == 3 and parts[0] == "axes" and parts[2] == "counter" \
            or len(parts) == 4 and parts[:2] == ["platform", "gyros"] and parts[3] == "dmm" \
            or where == "platform.awg":
        return {"where": where, "serial": f.serial, "model": f.model,
                "quantity": FOUND_QUANTITY[parts[-1]], "value": f.error, "U": f.error_u,
                "source": f"as-found error of calibration {f.certificate} ({f.issuer}"
                          + (f", {f.calibrated_on.isoformat()}" if f.calibrated_on else "")
                          + ")"}
    return None


def reanalyse_corrected(folder: Path, corrections: Sequence[Mapping[str, object]]
                        ) -> tuple[dict[str, object] | None, str]:
    """The run's raw captures analysed again in a copy of its folder whose corrections file
    states `corrections`; (result, "") or (None, why not)."""
    with tempfile.TemporaryDirectory(prefix="ratebench-impact-") as tmp:
        copy = Path(tmp) / folder.name
        shutil.copytree(folder, copy, ignore=shutil.ignore_patterns(
            layout.RESULT, "*.pdf", "*.html", "*.dcc.xml", layout.ISSUED))
        (copy / CORRECTIONS_FILE).write_text(json.dumps(
            {"corrections": list(corrections)}, indent=2) + "\n", encoding="utf-8")
        done = subprocess.run([sys.executable, "-m", "bench.app.reanalyse", str(copy)],
                              capture_output=True, text=True, timeout=3600)
        again = copy / layout.RESULT
        if done.returncode != 0 or not again.is_file():
            why = (done.stderr.strip().splitlines() or ["no result"])[-1]
            return None, f"not re-analysed: {why}"
        return json.loads(again.read_text(encoding="utf-8")), ""


# -- figures and checks -------------------------------------------------------------------

def _num(x: object) -> float | None:
    return float(x) if isinstance(x, int | float) and not isinstance(x, bool) \
        and math.isfinite(float(x)) else None


def figures_of(entry: Mapping[str, object]) -> dict[str, tuple[float, float, str]]:
    """A result entry's figures that state a U beside them: name: (value, U, unit)."""
    out: dict[str, tuple[float, float, str]] = {}
    for key, u in entry.items():
        if "_U_" in key:
            name, unit = key.replace("_U_", "_", 1), key.split("_U_", 1)[1]
        elif key.endswith("_U"):
            name, unit = key[:-2], ""
        else:
            continue
        value, big_u = _num(entry.get(name)), _num(u)
        if value is not None and big_u is not None and big_u > 0:
            out[name] = (value, big_u, UNITS.get(unit, unit))
    return out


def _entries(result: Mapping[str, object]) -> dict[str, Mapping[str, object]]:
    """Each rate and pair entry of a result by where it is."""
    out: dict[str, Mapping[str, object]] = {}
    axes = result.get("axes")
    for axis, a in (axes.items() if isinstance(axes, dict) else ()):
        if not isinstance(a, dict):
            continue
        for r in a.get("rates") or []:
            if isinstance(r, dict):
                out[f"axes.{axis}.rates[{r.get('set_rate_dps'):+g} deg/s]"] = r
        for p in a.get("pairs") or []:
            if isinstance(p, dict):
                out[f"axes.{axis}.pairs[{p.get('rate_dps'):g} deg/s]"] = p
    drift = result.get("drift")     # the drift kind: each gyro's figures, the platform's
    if isinstance(drift, dict):
        gyros = drift.get("axes")
        for gyro, g in (gyros.items() if isinstance(gyros, dict) else ()):
            if isinstance(g, dict):
                out[f"drift.axes.{gyro}"] = g
        out["drift"] = drift
    return out


def shifts(issued: Mapping[str, object], corrected: Mapping[str, object]
           ) -> list[FigureShift]:
    """Each figure's shift, corrected minus issued, in its unit and over its issued U."""
    out = []
    after = _entries(corrected)
    for where, e in _entries(issued).items():
        again = figures_of(after.get(where) or {})
        for name, (value, big_u, unit) in figures_of(e).items():
            if name not in again:
                continue
            shift = again[name][0] - value
            out.append(FigureShift(where, name, unit, value, again[name][0], shift, big_u,
                                   shift / big_u, abs(shift) > MARK_FRACTION_OF_U * big_u))
    return out


def _checks(result: Mapping[str, object]) -> dict[tuple[str, float | None, str], str]:
    checks = result.get("checks")
    return {(str(c.get("axis")), _num(c.get("set_rate_dps")), str(c.get("quantity"))):
            str(c.get("verdict")) for c in (checks if isinstance(checks, list) else [])
            if isinstance(c, dict)}


def check_changes(issued: Mapping[str, object], corrected: Mapping[str, object]
                  ) -> list[CheckChange]:
    before, after = _checks(issued), _checks(corrected)
    return [CheckChange(k[0], k[1], k[2], v, after.get(k, "absent"))
            for k, v in before.items() if after.get(k, "absent") != v]


# -- the assessment -----------------------------------------------------------------------

def assess(reg: Register, serial: str, roots: Sequence[Path]
           ) -> tuple[Finding, list[RunImpact]]:
    import bench
    from bench.app.register.runs import raw_digests

    item = next(iter(reg.equipment(serial)), None)
    if item is None:
        raise RegisterError(f"equipment {serial!r} is not in the inventory")
    finding = finding_of(item)
    folders = run_folders(roots)
    impacts = []
    for rec in touched(reg.runs_using(serial), finding):
        where = next((str(i.get("where")) for i in rec.items if i.get("serial") == serial),
                     "?")
        number = reg.number_of_run(rec.uid)
        imp = RunImpact(rec.uid, rec.registered_utc, where, number,
                        [r.shown_number + ("" if r.status == "issued" else f" ({r.status})")
                         for r in reg.revisions(number)] if number else [])
        impacts.append(imp)
        imp.customer = _customer(rec.result)
        folder = folders.get(rec.uid)
        if folder is None:
            imp.status = "raw data not found"
            continue
        imp.folder = str(folder)
        if number is None:      # nothing was stated to a customer; its issue corrects it
            imp.status = DRAFT_STATUS
            continue
        if raw_digests(folder) != rec.raw or not rec.raw:
            imp.status = ("raw data not found (the raw captures in the folder are not the "
                          "ones the register saw)")
            continue
        if rec.result is None:
            imp.status = "not re-analysed: the register holds no result of the run"
            continue
        if rec.version != bench.__version__:
            imp.status = (f"not re-analysed: measured with ratebench {rec.version}, this is "
                          f"{bench.__version__}")
            continue
        corr = correction_entry(finding, where)
        if corr is None:
            imp.status = f"not re-analysed: no correction model for {where} yet"
            continue
        again, why = reanalyse_corrected(folder, [corr])
        if again is None:
            imp.status = why
            continue
        issued = json.loads(rec.result)
        imp.status = "re-analysed"
        imp.figures = shifts(issued, again)
        imp.checks_changed = check_changes(issued, again)
    return finding, impacts


def _customer(result: str | None) -> dict[str, str] | None:
    """The customer block of the result the register holds (the certificate's)."""
    try:
        cert = json.loads(result).get("certificate") if result else None
    except ValueError:
        return None
    got = {k: str(cert[k]) for k in ("customer", "customer_address", "customer_contact")
           if isinstance(cert, dict) and cert.get(k)}
    return got or None


def report_json(reg_url: str, f: Finding, impacts: Sequence[RunImpact]) -> dict[str, object]:
    def plain(x: object) -> object:
        if isinstance(x, dt.date):
            return x.isoformat()
        if isinstance(x, dict):
            return {k: plain(v) for k, v in x.items()}
        if isinstance(x, list):
            return [plain(v) for v in x]
        return x

    return {"register": redact(reg_url), "finding": plain(asdict(f)),
            "mark_fraction_of_U": MARK_FRACTION_OF_U,
            "runs": [plain({**asdict(i), "largest_shift_over_U":
                            (lg.shift_over_u if (lg := i.largest()) else None)})
                     for i in impacts]}


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


def _write_report(args: argparse.Namespace, reg: Register, doc: dict[str, object]
                  ) -> dict[str, str]:
    """`--report DIR`: the report as JSON, PDF and HTML and the per-customer drafts
    (bench/app/impact_report.py); each file's SHA-256 for the audit entry."""
    if not getattr(args, "report", None):
        return {}
    from bench.app.impact_report import digests, write_report

    paths = write_report(Path(args.report), doc, json.dumps(doc, indent=2) + "\n",
                         reg.setting("issuer.name") or "the laboratory",
                         dt.datetime.now(dt.UTC).date().isoformat())
    for p in paths:
        print(f"wrote {p}", file=sys.stderr)
    return digests(paths)


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
            doc = report_json(url, finding, impacts)
            written = _write_report(args, reg, doc)
            reg.impact_assessed(acting, args.serial, {
                "nonconforming_work": "ISO/IEC 17025 7.10: the item found out of tolerance",
                **({"report": written} if written else {}),
                "finding": wire.builtins(doc["finding"]),
                "runs": [{"uid": i.uid, "number": i.number, "status": i.status,
                          "largest_shift_over_U": (lg.shift_over_u if (lg := i.largest())
                                                   else None),
                          "checks_changed": len(i.checks_changed)} for i in impacts],
                "certificates": sorted({i.number for i in impacts if i.number})})
    except RegisterError as e:
        print(f"bench impact: {e}", file=sys.stderr)
        return EXIT_REFUSED
    if args.json:
        Path(args.json).write_text(json.dumps(doc, indent=2) + "\n", encoding="utf-8")
    print("\n".join(report_text(finding, impacts)))
    return EXIT_OK

