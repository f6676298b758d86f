"""The run directory's layout: the name of every file and folder a run directory holds,
spelled here only (issue 45), for every reader and writer of run directories.

    RUN_DIR/
      procedure.yaml, stand.yaml, lab.yaml   the input files as used (lab.yaml if any)
      meta.json                              where they came from, their SHA-256, the version
      events.jsonl                           the run's journal, append-only
      raw/s<session>/                        each session's raw captures (`bench run` is
                                             session 1, each `--resume` the next):
        <axis>-fog.bin                         FOG bytes as received
        <axis>-counter.jsonl                   every SCPI exchange with the counter
        <axis>-drive.jsonl                     drive readings (TPDO), commands, EMCY
        awg.jsonl, <gyro>-dmm.jsonl            a gyro platform's generator and DMMs
      result.json                            the analysis (`bench analyze` writes it again)
      certificate.html, certificate.pdf      the certificate
      certificate.dcc.xml                    its Digital Calibration Certificate
                                             (certificate.dcc.invalid.xml: one that failed
                                             its schema, kept for a look)
      issued/<number>/                       each issued revision's files, kept unchanged

A run directory's paths come from the functions below (or `RunDir`, bench/core/journal.py,
which uses them); tests/test_architecture.py fails on one of these names spelled elsewhere.
This module imports nothing of the bench, so every layer may use it.
"""

from __future__ import annotations

from pathlib import Path

PROCEDURE = "procedure.yaml"
STAND = "stand.yaml"
LAB = "lab.yaml"
META = "meta.json"
EVENTS = "events.jsonl"
RESULT = "result.json"
CERTIFICATE_HTML = "certificate.html"
CERTIFICATE_PDF = "certificate.pdf"
CERTIFICATE_DCC = "certificate.dcc.xml"
CERTIFICATE_DCC_INVALID = "certificate.dcc.invalid.xml"
#: the folder of the issued revisions, one subfolder per certificate number
ISSUED = "issued"
#: the folder of the raw captures, one subfolder per session
RAW = "raw"

#: what each instrument's raw capture of an axis (or a gyro) is named after it
FOG_SUFFIX = "-fog.bin"
COUNTER_SUFFIX = "-counter.jsonl"
DRIVE_SUFFIX = "-drive.jsonl"
DMM_SUFFIX = "-dmm.jsonl"
AWG_LOG = "awg.jsonl"


#: every session's raw folder, as a glob pattern under `raw_root` (`s1`, `s2`, ...)
SESSION_GLOB = "s*"


def session_folder(session: int) -> str:
    """A session's raw folder's name (`s1`, `s2`, ...)."""
    return f"s{session}"


def raw_root(run: Path) -> Path:
    """The folder holding every session's raw captures."""
    return run / RAW


def raw_dir(run: Path, session: int) -> Path:
    """One session's raw folder."""
    return raw_root(run) / session_folder(session)


def raw_file(run: Path, session: int, name: str) -> Path:
    """A raw capture of a session, by its file name (`fog_capture(axis)`, ...)."""
    return raw_dir(run, session) / name


def raw_relpath(session: int, name: str) -> str:
    """A raw capture's path inside the run directory, as result.json lists it."""
    return f"{RAW}/{session_folder(session)}/{name}"


def fog_capture(axis: str) -> str:
    return f"{axis}{FOG_SUFFIX}"


def counter_log(axis: str) -> str:
    return f"{axis}{COUNTER_SUFFIX}"


def drive_log(axis: str) -> str:
    return f"{axis}{DRIVE_SUFFIX}"


def dmm_log(gyro: str) -> str:
    return f"{gyro}{DMM_SUFFIX}"


def fog_capture_of(path: Path) -> tuple[Path, int, str] | None:
    """(run directory, session, axis) of a FOG capture inside a run directory
    (`RUN_DIR/raw/s<k>/<axis>-fog.bin`), else None."""
    session, axis = path.parent.name, path.name.removesuffix(FOG_SUFFIX)
    if path.parent.parent.name != RAW or not session[1:].isdigit() or axis == path.name:
        return None
    try:
        return path.parent.parent.parent, int(session[1:]), axis
    except ValueError:      # a digit int() does not read, e.g. "s²"
        return None
