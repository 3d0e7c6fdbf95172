"""The fleet's table: one row per drive, written as ``fleet.parquet``."""

from __future__ import annotations

import os
from typing import Any, Dict, List, Optional

__all__ = ["COLUMNS", "STATUSES", "failed_row", "ok_row", "write_table"]

STATUSES = ("ok", "failed", "interrupted")
"""A drive's status: done (now or by an earlier run), failed (``error`` says why), or not done
because the fleet was interrupted."""

# Column → (pyarrow type name, meaning). The order is the table's.
COLUMNS: Dict[str, "tuple[str, str]"] = {
    "drive": ("string", "the drive's path as given"),
    "name": ("string", "its folder's name in the fleet folder"),
    "status": ("string", "ok, failed or interrupted"),
    "error": ("string", "why it failed, one line; empty when ok"),
    "resumed": ("bool", "done by an earlier run with the same options, and skipped"),
    "frames": ("int64", "frames run"),
    "cpu_s": ("float64", "CPU seconds of the worker process over the drive (all its threads)"),
    "run_s": ("float64", "wall seconds of evigrid.run in the worker"),
    "duration_s": ("float64", "the drive's recorded time span, last scan time - first"),
    "ego_path_share": ("float64", "summary's ego_path.share (occupied or moving on the path)"),
    "moving_objects": ("int64", "distinct objects judged moving over the drive"),
    "skipped_scans": ("int64", "scans skipped as unreadable or refused"),
    "out": ("string", "the drive's output folder; empty when not ok"),
    "node": ("string", "the Ray node that ran it"),
    "attempts": ("int64", "attempts this run took (a killed worker's task is retried)"),
    "peak_rss_mb": ("float64", "the worker's peak resident memory, MiB"),
}


def ok_row(
    drive: str, name: str, out: str, result: Dict[str, Any], resumed: bool
) -> Dict[str, Any]:
    """The row of a drive done, from its task's result (or the stamp of an earlier run)."""
    summary = result["summary"]
    ego_path = summary.get("ego_path") or {}
    return _row(
        drive=drive,
        name=name,
        status="ok",
        error="",
        resumed=resumed,
        frames=summary.get("frames"),
        cpu_s=result.get("cpu_s"),
        run_s=result.get("run_s"),
        duration_s=result.get("duration_s"),
        ego_path_share=ego_path.get("share"),
        moving_objects=result.get("moving_objects"),
        skipped_scans=len(summary.get("skipped_scans") or ()),
        out=out,
        node=result.get("node"),
        attempts=0 if resumed else result.get("attempt"),
        peak_rss_mb=result.get("peak_rss_mb"),
    )


def failed_row(
    drive: str, name: str, status: str, error: str, attempts: Optional[int] = None
) -> Dict[str, Any]:
    """The row of a drive that failed or was interrupted; its figures are null."""
    return _row(
        drive=drive, name=name, status=status, error=error, resumed=False, attempts=attempts
    )


def _row(**values: Any) -> Dict[str, Any]:
    row = {column: None for column in COLUMNS}
    row.update(values)
    return row


def write_table(rows: List[Dict[str, Any]], path: str) -> Any:
    """Writes the rows to ``path`` (Parquet, replaced whole by a rename) and returns the
    ``pyarrow.Table``."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    types = {
        "string": pa.string(),
        "bool": pa.bool_(),
        "int64": pa.int64(),
        "float64": pa.float64(),
    }
    schema = pa.schema(
        [
            pa.field(column, types[kind], metadata={"description": meaning})
            for column, (kind, meaning) in COLUMNS.items()
        ]
    )
    table = pa.Table.from_pylist(rows, schema=schema)
    temporary = path + ".tmp"
    pq.write_table(table, temporary)
    os.replace(temporary, path)
    return table
