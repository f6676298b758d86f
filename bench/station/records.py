"""The records half of the station view: tables, their runs, due dates and trends.

Reads the lab's records database when there is one; a runs folder that has no database
yet is still shown, from its run directories' result.json (the same figures the
database would hold), so the view is never empty because `bench records import` was not
run.
"""

from __future__ import annotations

import io
import json
from collections import defaultdict
from pathlib import Path
from typing import Any

from bench.station.live import DOWNLOADS


def _results(runs: Path) -> list[tuple[Path, dict[str, Any]]]:
    out = []
    try:
        dirs = sorted(p for p in runs.iterdir() if (p / "result.json").is_file())
    except FileNotFoundError:
        return []
    for p in dirs:
        try:
            out.append((p, json.loads((p / "result.json").read_text())))
        except (OSError, json.JSONDecodeError):
            continue
    return out


def _rate_rows(result: dict[str, Any]) -> list[dict[str, Any]]:
    rows = []
    for axis, a in (result.get("axes") or {}).items():
        for r in a.get("rates") or []:
            rows.append({"axis": axis, "set_rate_dps": r.get("set_rate_dps"),
                         "rate_error_rel": r.get("rate_error_rel"),
                         "rate_error_u_rel": r.get("rate_error_u_rel"),
                         "rate_instability_rel": r.get("rate_instability_rel"),
                         "verdict": r.get("verdict")})
    return rows


class RecordsView:
    """Tables and histories for the pages, from the runs folder's results."""

    def __init__(self, runs: Path, records_url: str | None = None) -> None:
        self.runs = runs
        self.records_url = records_url

    def tables(self) -> list[dict[str, Any]]:
        by_serial: dict[str, list[tuple[Path, dict[str, Any]]]] = defaultdict(list)
        for p, res in _results(self.runs):
            serial = str((res.get("stand") or {}).get("serial") or "?")
            by_serial[serial].append((p, res))
        out = []
        for serial, items in sorted(by_serial.items()):
            last_p, last = items[-1]
            stand = last.get("stand") or {}
            out.append({"serial": serial, "maker": stand.get("maker"), "model": stand.get("model"),
                        "runs": len(items), "last_run": last_p.name,
                        "last_date_utc": (last.get("dates") or {}).get("completed_utc"),
                        "last_verdict": last.get("verdict"), "due_utc": None, "overdue": None})
        return out

    def history(self, serial: str) -> dict[str, Any] | None:
        items = [(p, r) for p, r in _results(self.runs)
                 if str((r.get("stand") or {}).get("serial")) == serial]
        if not items:
            return None
        runs = []
        for p, r in items:
            runs.append({"run": p.name, "title": r.get("title"), "procedure": r.get("procedure"),
                         "date_utc": (r.get("dates") or {}).get("completed_utc"),
                         "verdict": r.get("verdict"),
                         "files": [n for n in DOWNLOADS if (p / n).exists()],
                         "rates": _rate_rows(r)})
        stand = items[-1][1].get("stand") or {}
        return {"serial": serial, "maker": stand.get("maker"), "model": stand.get("model"),
                "runs": runs}

    def trend_png(self, serial: str) -> bytes | None:
        """Rate error (with U, k = 2) per axis and rate against the run date."""
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure

        h = self.history(serial)
        if h is None:
            return None
        fig = Figure(figsize=(8, 3.6), dpi=100)
        FigureCanvasAgg(fig)
        ax = fig.add_subplot(1, 1, 1)
        series: dict[tuple[str, float], list[tuple[int, float, float]]] = defaultdict(list)
        for i, run in enumerate(h["runs"]):
            for row in run["rates"]:
                if row["rate_error_rel"] is None:
                    continue
                series[(row["axis"], row["set_rate_dps"])].append(
                    (i, row["rate_error_rel"] * 1e6, (row["rate_error_u_rel"] or 0) * 1e6))
        for (axis, rate), pts in sorted(series.items()):
            ax.errorbar([p[0] for p in pts], [p[1] for p in pts], yerr=[p[2] for p in pts],
                        marker="o", capsize=3, label=f"{axis} {rate:+g} deg/s")
        ax.set_xticks(range(len(h["runs"])))
        ax.set_xticklabels([(r["date_utc"] or r["run"])[:10] for r in h["runs"]], fontsize=7)
        ax.set_xlabel("run (completion date, UTC)")
        ax.set_ylabel("rate error, ppm (U, k = 2)")
        ax.grid(True, alpha=0.3)
        if series:
            ax.legend(fontsize=6, ncol=3)
        fig.tight_layout()
        buf = io.BytesIO()
        fig.savefig(buf, format="png")
        return buf.getvalue()
