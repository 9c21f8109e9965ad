"""The table of a design sweep: one flat row per point (CSV or Parquet), and its summary for a person.

Light on imports (no solver, no numpy): the CLI uses it against a server too. Parquet needs pyarrow, the
``parquet`` extra (``pip install 'vibfree[parquet]'``)."""

from __future__ import annotations

import csv
import io
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

COLUMNS = (
    "index",
    "ok",
    "duration_s",
    "settling_time_s",
    "percentage_vibration",
    "residual_amplitude",
    "residual_velocity_amplitude",
    "band_5_percent_low",
    "band_5_percent_high",
    "limits_met",
    "solver_status",
    "solver_iterations",
    "solves",
    "elapsed_s",
    "between",
    "problem_type",
    "reason",
)


def flat_rows(lines: Iterable[dict[str, Any]]) -> list[dict[str, Any]]:
    """One flat dict per ``row`` line, sorted by the axes' values (the grid's order, the first axis varying slowest,
    with the points refinement added in their places): the axes' values, then ``COLUMNS``."""
    rows = sorted(
        (line for line in lines if line.get("line") == "row"), key=lambda r: (tuple(r["values"].values()), r["index"])
    )
    out = []
    for row in rows:
        band = row.get("band_5_percent") or [None, None]
        solver = row.get("solver") or {}
        problem = row.get("problem") or {}
        flat = dict(row["values"])
        flat |= {
            "index": row["index"],
            "ok": row["ok"],
            "duration_s": row.get("duration_s"),
            "settling_time_s": row.get("settling_time_s"),
            "percentage_vibration": row.get("percentage_vibration"),
            "residual_amplitude": row.get("residual_amplitude"),
            "residual_velocity_amplitude": row.get("residual_velocity_amplitude"),
            "band_5_percent_low": band[0],
            "band_5_percent_high": band[1],
            "limits_met": row.get("limits_met"),
            "solver_status": solver.get("status"),
            "solver_iterations": solver.get("iterations"),
            "solves": solver.get("solves"),
            "elapsed_s": row.get("elapsed_s"),
            "between": None if row.get("between") is None else "-".join(str(i) for i in row["between"]),
            "problem_type": problem.get("type"),
            "reason": problem.get("detail"),
        }
        out.append(flat)
    return out


def csv_text(rows: Sequence[dict[str, Any]]) -> str:
    """The rows as CSV: a header, empty cells for nulls."""
    names = [*axis_paths_of(rows), *COLUMNS]
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=names, lineterminator="\n")
    writer.writeheader()
    for row in rows:
        writer.writerow({k: ("" if v is None else v) for k, v in row.items()})
    return buffer.getvalue()


def axis_paths_of(rows: Sequence[dict[str, Any]]) -> list[str]:
    return [k for k in rows[0] if k not in COLUMNS] if rows else []


def write_table(path: str, rows: Sequence[dict[str, Any]]) -> None:
    """CSV (``.csv``, or ``-`` for stdout) or Parquet (``.parquet``, pyarrow)."""
    import sys

    if path == "-":
        sys.stdout.write(csv_text(rows))
    elif path.endswith(".parquet"):
        try:
            import pyarrow as pa
            import pyarrow.parquet as pq
        except ImportError:
            raise ValueError(f"{path}: Parquet needs pyarrow: pip install 'vibfree[parquet]' (or write .csv)") from None
        pq.write_table(pa.Table.from_pylist(list(rows)), path)
    elif path.endswith(".csv"):
        Path(path).write_text(csv_text(rows))
    else:
        raise ValueError(f"{path}: write .csv or .parquet")


def _number(value: Any, unit: str = "") -> str:
    return "-" if value is None else f"{value:.4g}{unit}"


def summary_text(lines: Sequence[dict[str, Any]]) -> str:
    """The sweep and its table check in a few lines."""
    summary = next((line for line in lines if line.get("line") == "summary"), None)
    if summary is None:
        return "sweep: no summary (the stream ended early)"
    checks = [line for line in lines if line.get("line") == "check"]
    out = [
        f"sweep: {summary['points']} points ({summary['failed']} failed, {summary['refined']} added by refinement) "
        f"in {summary['elapsed_s']:.3g} s",
        f"table check (V of each design on its neighbour's plant <= {summary['threshold_percent']:g} %): "
        f"{summary['pairs']} pairs checked, {summary['pairs_failing']} failing, {summary['pairs_unchecked']} unchecked",
    ]
    if summary["interpolable"]:
        out.append("  the table may be interpolated")
    else:
        failing = [c for c in checks if c.get("passes") is False]
        worst = max(failing, key=lambda c: c["worst_percentage_vibration"], default=None)
        out.append("  the table is NOT fine enough to interpolate" + (" (failed points)" if summary["failed"] else ""))
        if worst is not None:
            lo, hi = worst["values"]
            out.append(
                f"  worst: V = {_number(worst['worst_percentage_vibration'], ' %')} between points {worst['pair'][0]} "
                f"and {worst['pair'][1]} ({worst['axis']} {lo:.6g}..{hi:.6g}); ask refine: true, or a finer axis"
            )
    return "\n".join(out)
