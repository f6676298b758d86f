"""`bench verify RUN --reanalyse` (issue 54): the raw captures analysed again, in a copy of
the run directory and a process of its own, and the result compared with the run's
result.json byte for byte.

A run's numbers depend on its seed and files alone (README), so a result.json that a raw
byte, an edit or another version of the analysis did not touch comes out the same to the
byte. The re-analysis runs under the ratebench version the run was measured with; another
version refuses and names both (its numbers may differ for reasons of its own).
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import bench
from bench.app.impact_codec import MalformedDocument, json_tree, run_meta
from bench.core import rundir_layout as layout
from drivers.json_types import JsonValue

EXIT_EQUAL, EXIT_DIFFERS, EXIT_REFUSED = 0, 1, 2


def reanalyse(run_path: Path) -> tuple[int, list[str]]:
    """(exit status, lines to print)."""
    run_path = Path(run_path)
    stored = run_path / layout.RESULT
    try:
        version = run_meta((run_path / layout.META).read_bytes()).bench_version
    except (OSError, MalformedDocument) as e:
        return EXIT_REFUSED, [f"{run_path}: not a run directory ({layout.META}: {e})"]
    if not stored.is_file():
        return EXIT_REFUSED, [f"{stored}: not found: nothing to compare with"]
    if version != bench.__version__:
        return EXIT_REFUSED, [f"{run_path} was measured with ratebench {version or '?'}; "
                              f"this is ratebench {bench.__version__}: re-analyse it with "
                              f"{version or 'the version it names'}"]
    with tempfile.TemporaryDirectory(prefix="ratebench-reanalyse-") as tmp:
        copy = Path(tmp) / run_path.name
        shutil.copytree(run_path, copy, ignore=shutil.ignore_patterns(
            layout.RESULT, "*.pdf", "*.html", "*.dcc.xml", layout.ISSUED))
        # the run's own environment: its BLAS threads as `bench run` had them (a threaded
        # BLAS sums in blocks that follow the thread count; forcing one thread in a run
        # process changed the last digits by the order scipy's BLAS was loaded: not done)
        done = subprocess.run([sys.executable, "-m", "bench.app.reanalyse", str(copy)],
                              capture_output=True, text=True, env=dict(os.environ),
                              timeout=3600)
        again = copy / layout.RESULT
        if done.returncode != 0 or not again.is_file():
            why = (done.stderr.strip().splitlines() or ["no result"])[-1]
            return EXIT_DIFFERS, [f"{run_path}: the raw captures do not analyse again: {why}"]
        old, new = stored.read_bytes(), again.read_bytes()
    held = _registered(run_path)
    if held is not None and held[0] is not None and held[0] != new:
        return EXIT_DIFFERS, [f"{run_path}: the lab register's record of the run ({held[1]}) "
                              "DIFFERS from the raw captures analysed again:",
                              *_first_differences(held[0].decode(errors="replace"),
                                                  new.decode(errors="replace"))]
    if held is not None and held[0] is not None:
        note = [f"the lab register's record of the run ({held[1]}): equal, byte for byte"]
    elif held is not None:
        note = [f"the lab register {held[1]}: no registered result to compare with"]
    else:
        note = []
    status, lines = _compare(stored, old, new, version)
    return status, [*lines, *note]


def _registered(run_path: Path) -> tuple[bytes | None, str] | None:
    """The result the run's register holds (None: the run names no register, or it cannot
    be asked: said by the caller's other lines)."""
    from bench.app.register.runs import register_url_of, run_uid_of
    from bench.app.register.store import Register, RegisterError, redact

    url = register_url_of(run_path)
    if url is None:
        return None
    try:
        with Register.open(url, migrate=False) as reg:
            rec = reg.run_record(run_uid_of(run_path))
    except RegisterError as e:
        return None if "no such file" in str(e) else (None, f"{redact(url)}: {e}")
    if rec is None:
        return (None, f"{redact(url)}, which never saw this run start")
    return rec.result_bytes, f"{redact(url)}, result SHA-256 {rec.result_sha256}"


def _compare(stored: Path, old: bytes, new: bytes, version: str) -> tuple[int, list[str]]:
    if old == new:
        return EXIT_EQUAL, [f"{stored}: equal, byte for byte, to the raw captures analysed "
                            f"again (ratebench {version}; {len(new)} "
                            f"bytes, SHA-256 {hashlib.sha256(new).hexdigest()})"]
    ulps = _last_digits_only(json_tree(old), json_tree(new))
    if ulps is not None:
        count, most = ulps
        return EXIT_EQUAL, [
            f"{stored}: equal to the raw captures analysed again but for the last digits: "
            f"{count} number(s) differ, by at most {most:.1e} of their value (<= "
            f"{REL_LIMIT:.0e}: numpy's summation order follows the arrays' memory layout); "
            "every other byte the same; NOT byte for byte"]
    return EXIT_DIFFERS, [f"{stored}: DIFFERS from the raw captures analysed again:",
                          *_first_differences(old.decode(errors="replace"),
                                              new.decode(errors="replace"))]


#: what a float64 reduction's order changes in a result, relative: rounding of sums
#: (~1e-16), grown through a Monte Carlo or a square root to ~1e-12 at most; a changed raw
#: byte (a frame lost among millions, a period misread) moves figures by 1e-7 or more
REL_LIMIT = 1e-11


def _last_digits_only(a: JsonValue, b: JsonValue) -> tuple[int, float] | None:
    """(numbers that differ, their largest relative difference), when the two documents
    differ only in the last digits of numbers; None when anything else differs."""
    found: list[float] = [0, 0.0]

    def walk(x: JsonValue, y: JsonValue) -> bool:
        if isinstance(x, dict) and isinstance(y, dict):
            return x.keys() == y.keys() and all(walk(x[k], y[k]) for k in x)
        if isinstance(x, list) and isinstance(y, list):
            return len(x) == len(y) and all(walk(u, v) for u, v in zip(x, y, strict=True))
        if isinstance(x, float) and isinstance(y, float) and x != y:
            rel = abs(x - y) / max(abs(x), abs(y))
            found[0] += 1
            found[1] = max(found[1], rel)
            return rel <= REL_LIMIT
        return x == y and type(x) is type(y)

    return (int(found[0]), found[1]) if walk(a, b) else None


def _first_differences(old: str, new: str, most: int = 6) -> list[str]:
    import difflib

    lines = [ln for ln in difflib.unified_diff(old.splitlines(), new.splitlines(),
                                               "result.json (stored)",
                                               "result.json (analysed again)", n=0, lineterm="")
             if not ln.startswith("@@")]
    return [f"  {ln}" for ln in lines[2:2 + most]] + (
        [f"  ... {len(lines) - 2 - most} more line(s)"] if len(lines) > 2 + most else [])


def _analyse_in_place(run_path: Path) -> None:
    """The child: the kind's analysis of the copy, result.json written as `bench run` does."""
    from bench.core.config import ConfigError
    from bench.core.journal import RunDir
    from bench.core.loader import load_config
    from bench.core.registry import procedure_kind

    run = RunDir(run_path)
    try:
        cfg = load_config(str(run.procedure_file), run.stand_file)
    except ConfigError as e:
        raise SystemExit(f"the run's files do not load: {'; '.join(map(str, e.problems))}") \
            from None
    run.write_json(layout.RESULT, procedure_kind(cfg.kind).analysis.analyze(run, cfg).document)


if __name__ == "__main__":
    _analyse_in_place(Path(sys.argv[1]))
