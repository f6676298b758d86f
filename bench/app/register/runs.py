"""A run's folder against the register's record of it (issue 54: what is issued is what
was measured).

The register holds each run from its start (store.Register.register_run: the uid, the
bench, the performer, the version, the inputs' SHA-256, the stand's items) and receives
each session's result with every raw capture's digest (`deliver`). An issue is made from
that record: `folder_problems` names every file of the run folder that no longer matches
it (an input, meta.json's performer or items, a raw capture, result.json), and `bench
authorise` refuses while there is one. A run no register saw start has no record and is
never issued.
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable, Mapping
from pathlib import Path

from bench.app.register import wire
from bench.app.register.store import Register, RegisterError, RunRecord, redact
from bench.core import rundir_layout as layout
from bench.core.journal import sha256_file
from bench.core.lab import LabError, load_lab

#: the input files a run copies at its start, as the register records their digests
INPUT_FILES = (layout.PROCEDURE, layout.STAND, layout.LAB)


def input_digests(procedure: Path, stand: Path, lab: Path | None) -> dict[str, str]:
    """The inputs' SHA-256 under the names the run folder gives its copies."""
    files = {layout.PROCEDURE: procedure, layout.STAND: stand, layout.LAB: lab}
    return {name: sha256_file(path) for name, path in files.items() if path is not None}


def raw_digests(run_path: Path) -> dict[str, str]:
    """Every raw capture of every session by its path in the run folder."""
    root = layout.raw_root(run_path)
    if not root.is_dir():
        return {}
    return {p.relative_to(run_path).as_posix(): sha256_file(p)
            for p in sorted(root.rglob("*")) if p.is_file()}


def run_uid_of(run_path: Path) -> str:
    """The uid the run was made with (meta.json), never its folder's name."""
    uid = wire.run_start(run_path / layout.META).run_uid
    if not uid:
        raise RegisterError(f"{run_path / layout.META}: no run_uid: the run was not made by a "
                            "register-aware bench, and no register holds it")
    return uid


def register_url_of(run_path: Path) -> str | None:
    """The register the run's own lab file names (its copy in the run folder)."""
    lab = run_path / layout.LAB
    if not lab.is_file():
        return None
    try:
        return load_lab(lab).register_url
    except LabError:
        return None


def _meta_problems(rec: RunRecord, run_path: Path) -> list[str]:
    meta_file = run_path / layout.META
    try:
        meta = wire.run_start(meta_file)
    except RegisterError as e:
        return [str(e)]
    account = meta.performer.account if meta.performer else None
    out = []
    if account != rec.performer:
        out.append(f"{meta_file}: performer {account or 'none'!s} differs from the register's "
                   f"record of the run's start ({rec.performer or 'none'})")
    if (meta.equipment_status or []) != [dict(i) for i in rec.items]:
        out.append(f"{meta_file}: equipment_status differs from the stand items' status the "
                   "register recorded at the run's start")
    if meta.bench_version != rec.version:
        out.append(f"{meta_file}: bench_version {meta.bench_version!r} differs from "
                   f"the version the register recorded ({rec.version})")
    return out


def folder_problems(rec: RunRecord, run_path: Path) -> list[str]:
    """Every file of the run folder that no longer matches the register's record, named
    (empty: the folder is what the register saw)."""
    out: list[str] = []
    for name in INPUT_FILES:
        path, want = run_path / name, rec.inputs.get(name)
        if want is None:
            if path.exists():
                out.append(f"{path}: not an input the register recorded at the run's start")
            continue
        if not path.is_file():
            out.append(f"{path}: missing (the register recorded it at the run's start)")
        elif sha256_file(path) != want:
            out.append(f"{path}: changed since the run started (the register recorded "
                       f"SHA-256 {want})")
    out += _meta_problems(rec, run_path)
    have = raw_digests(run_path)
    for name, want in sorted(rec.raw.items()):
        if name not in have:
            out.append(f"{run_path / name}: missing (the register holds its digest)")
        elif have[name] != want:
            out.append(f"{run_path / name}: raw capture changed since the register received "
                       f"its digest ({want})")
    out += [f"{run_path / name}: a raw capture the register never received"
            for name in sorted(set(have) - set(rec.raw))]
    out += _corrections_problems(rec, run_path)
    result = run_path / layout.RESULT
    if rec.result_sha256 is None:
        out.append("the register holds no result of this run (its session's end was not "
                   "delivered: `bench records sync` delivers it)")
    elif not result.is_file():
        out.append(f"{result}: missing")
    elif hashlib.sha256(result.read_bytes()).hexdigest() != rec.result_sha256:
        out.append(f"{result}: changed since the register received it (the register holds "
                   f"SHA-256 {rec.result_sha256})")
    elif _simulated(rec) != rec.simulated:
        out.append(f"{result}: says the stand was {'' if _simulated(rec) else 'not '}"
                   f"simulated; the register recorded at the start that it was"
                   f"{'' if rec.simulated else ' not'}")
    return out


#: the run folder's corrections file (issue 58), as the analysis reads it
CORRECTIONS_FILE = "corrections.json"


def _corrections_problems(rec: RunRecord, run_path: Path) -> list[str]:
    """The corrections file must state exactly the corrections the registered result
    applied (issue 58: the analysis reads the file, so a file the result does not state
    would change what the raw captures give)."""
    path = run_path / CORRECTIONS_FILE
    held = wire.result_facts(rec.result).corrections
    if not path.is_file():
        return [] if not held else [f"{path}: missing (the registered result applied "
                                    "corrections it stated)"]
    try:
        have = wire.corrections_file(path).corrections
    except RegisterError as e:
        return [str(e)]
    if have != held:
        return [f"{path}: its corrections differ from those the registered result applied"]
    return []


def _simulated(rec: RunRecord) -> bool:
    """What the registered result says of the stand (twins or instruments)."""
    stand = wire.result_facts(rec.result).stand
    return stand is not None and stand.simulated


def deliver(run_path: Path, kind: str, warn: Callable[[str], None],
            reason: str | None = None, only_if_missing: bool = False) -> RunRecord | None:
    """Send the run's result and raw digests to the register its lab file names (a
    session's end, an analysis, or `bench records sync` catching up after the link was
    down); a run without a register, or one the register does not hold, is left alone.
    Returns the record as delivered (None: nothing delivered). Never raises: the run
    folder keeps everything, a failure is said."""
    url = register_url_of(run_path)
    result = run_path / layout.RESULT
    if url is None or not result.is_file():
        return None
    try:
        uid = run_uid_of(run_path)
        with Register.open(url, migrate=False) as reg:
            rec = reg.run_record(uid)
            if rec is None or (only_if_missing and rec.result_sha256 is not None):
                return None
            return reg.deliver_result(uid, kind, result.read_bytes(), raw_digests(run_path),
                                      reason)
    except RegisterError as e:
        warn(f"the lab register {redact(url)} did not receive this run's result: {e} "
             "(the run folder keeps everything; `bench records sync` delivers it later)")
        return None


def register_start(reg: Register, uid: str, bench: str,
                   performer: Mapping[str, str | None] | None,
                   simulated: bool, inputs: Mapping[str, str],
                   items: list[dict[str, str | None]]) -> RunRecord:
    """The run's record at its start (the gate calls this before anything moves)."""
    import bench as bench_pkg

    account = performer.get("account") if performer else None
    return reg.register_run(uid, bench, str(account) if account else None,
                            bench_pkg.__version__, simulated, inputs, items)
