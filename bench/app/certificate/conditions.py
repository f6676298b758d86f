"""The conditions of a run, each stated as what it is (issue 43): the procedure's nominal
values as nominal, what the bench measured as measured, "not measured" where nothing
was, and one mains frequency for the stand run (the lab has one grid; where the axes'
fits found different tones, both are stated as found, not one per axis as the lab's).

One list of rows for the PDF's conditions section (build.py) and the DCC's
influenceConditions (bench/app/dcc/used_methods.py).
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass

import msgspec

from bench.analysis.finite import finite_number as num
from bench.report.certificate.parts import Sources, label_of, text_of
from bench.report.result_frame import Node, at, entries

NOT_MEASURED = "not measured"
NONE = "—"


@dataclass(frozen=True)
class ConditionRow:
    """One condition: its nominal value (the procedure file's) and what was measured."""

    key: str              # the procedure's key, or fog_temperature / mains_frequency
    condition: str        # in words
    nominal: str          # NONE when the procedure states none
    measured: str         # NOT_MEASURED when nothing measured it in this run


def _mains_tones(node: Node, axis: str) -> Iterator[tuple[str, float, str]]:
    """Every fitted mains tone under an axis's results (result.json's, or the kind's model
    its analysis has just given): (axis, frequency in Hz, where the frequency came from)."""
    stated = dict(entries(node))
    m = stated.pop("mains", None)
    if isinstance(m, Mapping | msgspec.Struct) and (f := num(at(m, "frequency_hz"))) is not None:
        yield axis, f, str(at(m, "source") or "")
    for v in stated.values():
        yield from _mains_tones(v, axis)


def mains_row(src: Sources) -> ConditionRow | None:
    """The stand run's mains frequency: the one stated (procedure or stand file, the lab's
    grid), or the tones the fits found per axis, stated as found; None when no result
    fitted a mains tone."""
    axes = at(src.walked, "axes")
    tones = [t for axis, ax in entries(axes if isinstance(axes, Mapping) else {})  # walked
             for t in _mains_tones(ax, str(axis))]
    if not tones:
        return None
    stated = [(f, s) for _, f, s in tones if s and "found" not in s]
    found: dict[str, list[float]] = {}
    for axis, f, s in tones:
        if not s or "found" in s:
            found.setdefault(axis, [])
            if f not in found[axis]:
                found[axis].append(f)
    nominal = (f"{stated[0][0]:g} Hz, {stated[0][1]}" if stated else
               "not stated (no mains_hz in the procedure or stand file)")
    if not found:
        measured = f"{NOT_MEASURED} (the stated frequency was fitted, not measured)"
    else:
        every = sorted({f for fs in found.values() for f in fs})
        per_axis = "; ".join(f"axis {a}: " + ", ".join(f"{f:g} Hz" for f in fs)
                             for a, fs in found.items())
        if len(every) == 1:
            measured = (f"{every[0]:g} Hz, found from the data (the more significant of the "
                        f"tones tried; {per_axis})")
        else:
            measured = ("found from the data, NOT one frequency: " + per_axis + ". The "
                        "lab's grid has one frequency, so a tone found at another one is not "
                        "the mains; state mains_hz in the stand file")
    return ConditionRow("mains_frequency", "Mains frequency (the lab's grid)", nominal,
                        measured)


def _fog_temperature(src: Sources) -> ConditionRow | None:
    parts = []
    for axis, ax in src.frame.conditions_measured.fog_axes.items():
        lo, mean, hi = ax.min_c, ax.mean_c, ax.max_c
        if lo is not None and hi is not None:
            parts.append(f"axis {axis}: {lo:g} to {hi:g} °C" +
                         (f" (mean {mean:.2f} °C)" if mean is not None else ""))
    if not parts:
        return None
    return ConditionRow("fog_temperature", "Temperature at the FOG on the table top (not "
                        "the room)", NONE, "; ".join(parts) + ", from the FOG's frames")


#: a procedure key that names a physical condition (by its name or its unit suffix), which
#: the run either measured or did not; any other key (a note) is text, neither
_QUANTITY_WORDS = ("temperature", "humidity", "pressure", "vibration", "mains")
_UNIT_SUFFIXES = ("_c", "_pct", "_hpa", "_hz", "_k", "_pa")


def _quantity(key: str) -> bool:
    k = key.lower()
    return k.startswith(_QUANTITY_WORDS) or k.endswith(_UNIT_SUFFIXES)


def condition_rows(src: Sources) -> list[ConditionRow]:
    """The procedure's conditions (nominal; measured only where the run measured them),
    then what the bench measured that the procedure does not state, then the mains."""
    cond = src.frame.conditions or src.procedure_file.get("conditions") or {}
    room = src.frame.conditions_measured.room or {}
    rows = [ConditionRow(str(k), label_of(k), text_of(v),
                         text_of(room[k]) if room.get(k) is not None else
                         NOT_MEASURED if _quantity(str(k)) else NONE)
            for k, v in (cond.items() if isinstance(cond, Mapping) else ())]
    if not any(str(r.key).startswith("temperature") for r in rows) and not room:
        rows.append(ConditionRow("temperature", "Room temperature", NONE, NOT_MEASURED))
    fog = _fog_temperature(src)
    if fog is not None:
        rows.append(fog)
    mains = mains_row(src)
    if mains is not None:
        rows.append(mains)
    return rows
