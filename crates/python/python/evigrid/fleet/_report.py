"""The fleet's short report for people: ``fleet.md`` and ``fleet.html`` with totals, the slowest
and the failed drives, and the per-drive figures as a plot (``fleet.svg``, drawn here: no
plotting library is needed)."""

from __future__ import annotations

import html
import math
import os
from typing import Any, Dict, List

__all__ = ["write_report"]

# Okabe–Ito colours, as the evigrid figures use them: ok, failed, interrupted.
_COLOURS = {"ok": "#009E73", "failed": "#D55E00", "interrupted": "#E69F00"}
_SLOWEST = 5


def write_report(rows: List[Dict[str, Any]], fleet_dir: str, wall_s: float) -> None:
    """Writes ``fleet.md``, ``fleet.html`` and ``fleet.svg`` into ``fleet_dir``."""
    svg = _plot(rows)
    _write(os.path.join(fleet_dir, "fleet.svg"), svg)
    _write(os.path.join(fleet_dir, "fleet.md"), _markdown(rows, wall_s))
    _write(os.path.join(fleet_dir, "fleet.html"), _html(rows, wall_s, svg))


def _totals(rows: List[Dict[str, Any]], wall_s: float) -> List["tuple[str, str]"]:
    ok = [row for row in rows if row["status"] == "ok"]
    count = {status: sum(row["status"] == status for row in rows) for status in _COLOURS}
    resumed = sum(bool(row["resumed"]) for row in rows)
    frames = sum(row["frames"] or 0 for row in ok)
    cpu_s = sum(row["cpu_s"] or 0.0 for row in ok if not row["resumed"])
    duration_s = sum(row["duration_s"] or 0.0 for row in ok)
    return [
        (
            "drives",
            f"{len(rows)}: {count['ok']} ok ({resumed} done before), "
            f"{count['failed']} failed, {count['interrupted']} interrupted",
        ),
        ("frames", f"{frames}"),
        ("recorded time", f"{duration_s:.1f} s"),
        ("CPU time of this run", f"{cpu_s:.1f} s"),
        ("wall time of this run", f"{wall_s:.1f} s"),
        ("moving objects", f"{sum(row['moving_objects'] or 0 for row in ok)}"),
        ("skipped scans", f"{sum(row['skipped_scans'] or 0 for row in ok)}"),
    ]


def _slowest(rows: List[Dict[str, Any]]) -> List[Dict[str, Any]]:
    done = [row for row in rows if row["status"] == "ok" and row["run_s"] is not None]
    return sorted(done, key=lambda row: row["run_s"], reverse=True)[:_SLOWEST]


def _markdown(rows: List[Dict[str, Any]], wall_s: float) -> str:
    lines = ["# evigrid fleet", "", "| | |", "| --- | --- |"]
    lines += [f"| {what} | {value} |" for what, value in _totals(rows, wall_s)]
    lines += [
        "",
        "## Slowest drives",
        "",
        "| drive | frames | s | s / frame |",
        "| --- | --- | --- | --- |",
    ]
    for row in _slowest(rows):
        per_frame = row["run_s"] / row["frames"] if row["frames"] else math.nan
        lines.append(f"| {row['name']} | {row['frames']} | {row['run_s']:.2f} | {per_frame:.3f} |")
    failed = [row for row in rows if row["status"] != "ok"]
    lines += ["", "## Failed and interrupted drives", ""]
    if failed:
        lines += ["| drive | status | error |", "| --- | --- | --- |"]
        lines += [
            f"| {row['drive']} | {row['status']} | {row['error'].replace('|', '/')} |"
            for row in failed
        ]
    else:
        lines.append("None.")
    lines += ["", "## Per drive", "", "![run time per drive](fleet.svg)", ""]
    lines.append("The table with every figure is `fleet.parquet`.")
    return "\n".join(lines) + "\n"


def _html(rows: List[Dict[str, Any]], wall_s: float, svg: str) -> str:
    def table(header: List[str], body: List[List[Any]]) -> str:
        head = "".join(f"<th>{html.escape(h)}</th>" for h in header)
        cells = "".join(
            "<tr>" + "".join(f"<td>{html.escape(str(v))}</td>" for v in line) + "</tr>"
            for line in body
        )
        return f"<table><tr>{head}</tr>{cells}</table>"

    failed = [[r["drive"], r["status"], r["error"]] for r in rows if r["status"] != "ok"]
    slowest = [[r["name"], r["frames"], f"{r['run_s']:.2f}"] for r in _slowest(rows)]
    parts = [
        "<!doctype html><html><head><meta charset='utf-8'><title>evigrid fleet</title>",
        "<style>body{font-family:sans-serif}td,th{padding:2px 8px;text-align:left}</style>",
        "</head><body><h1>evigrid fleet</h1>",
        table(["", ""], [list(t) for t in _totals(rows, wall_s)]),
        "<h2>Slowest drives</h2>",
        table(["drive", "frames", "s"], slowest),
        "<h2>Failed and interrupted drives</h2>",
        table(["drive", "status", "error"], failed) if failed else "<p>None.</p>",
        "<h2>Per drive</h2>",
        svg,
        "<p>The table with every figure is <code>fleet.parquet</code>.</p></body></html>",
    ]
    return "\n".join(parts) + "\n"


def _plot(rows: List[Dict[str, Any]]) -> str:
    """Horizontal bars, one per drive: the run time of a drive run now, the time of the earlier
    run for one done before (lighter), a marker for a failed or interrupted drive; frames
    written beside each bar."""
    bar_h, gap, label_w, plot_w, top = 16, 6, 220, 420, 28
    longest = max([row["run_s"] or 0.0 for row in rows] + [1e-9])
    height = top + len(rows) * (bar_h + gap) + 24
    out = [
        f"<svg xmlns='http://www.w3.org/2000/svg' width='{label_w + plot_w + 120}' "
        f"height='{height}' font-family='sans-serif' font-size='12'>",
        f"<text x='{label_w}' y='16'>run time per drive, s (longest {longest:.1f} s)</text>",
    ]
    for i, row in enumerate(rows):
        y = top + i * (bar_h + gap)
        name = html.escape(row["name"])
        out.append(f"<text x='{label_w - 6}' y='{y + 12}' text-anchor='end'>{name}</text>")
        colour = _COLOURS[row["status"]]
        if row["status"] == "ok" and row["run_s"] is not None:
            width = max(1.0, plot_w * row["run_s"] / longest)
            opacity = "0.45" if row["resumed"] else "1"
            out.append(
                f"<rect x='{label_w}' y='{y}' width='{width:.1f}' height='{bar_h}' "
                f"fill='{colour}' fill-opacity='{opacity}'/>"
            )
            note = f"{row['frames']} frames" + (", done before" if row["resumed"] else "")
            out.append(f"<text x='{label_w + width + 4:.1f}' y='{y + 12}'>{note}</text>")
        else:
            out.append(
                f"<rect x='{label_w}' y='{y}' width='{bar_h}' height='{bar_h}' fill='{colour}'/>"
            )
            out.append(f"<text x='{label_w + bar_h + 4}' y='{y + 12}'>{row['status']}</text>")
    out.append("</svg>")
    return "\n".join(out) + "\n"


def _write(path: str, text: str) -> None:
    temporary = path + ".tmp"
    with open(temporary, "w", encoding="utf-8") as file:
        file.write(text)
    os.replace(temporary, path)
