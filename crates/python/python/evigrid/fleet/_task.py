"""One drive, as a Ray task runs it on a worker: the session through ``evigrid.run``, its outputs
staged and moved into place whole, and a few figures back to the driver.

A drive's folder appears by one rename once every output and the stamp are written, so a worker
killed at any moment leaves the folder either complete (from an earlier run) or absent; what it
was writing stays under ``.partial/`` and the next attempt removes it.

A task stops by itself: on Ctrl-C the driver writes the stop file ``.partial/stop-<run>``
(:func:`stop_file`), which the task looks for before it starts and which ``evigrid.run`` asks
about every 50 ms (its ``stop``): the drive stops at its next frame, what it wrote is removed, and
the task returns ``{"interrupted": why}``. No ``ray.cancel`` is needed, so none can race with the
reply of a task that is finishing.
"""

from __future__ import annotations

import json
import os
import shutil
import socket
import sys
import time
from typing import Any, Dict, Optional

__all__ = ["PARTIAL", "STAMP", "one_line", "read_stamp", "run_drive", "stop_file"]

PARTIAL = ".partial"
"""The fleet folder's sub-folder where drives are written before they are moved into place."""

STAMP = "fleet-drive.json"
"""The file in a drive's folder that says it is complete, for which options, with its figures."""

# The size of this worker's shared thread pool (evigrid's rayon pool, started on first use), once
# a task has set it.
_shared_pool: Optional[int] = None


def run_drive(
    path: str,
    name: str,
    fleet_dir: str,
    options: Dict[str, Any],
    key: Dict[str, Any],
    run_id: str,
) -> Dict[str, Any]:
    """Runs one drive into ``fleet_dir/name`` and returns its summary and figures (no grid).

    A drive evigrid refuses (bad input, unreadable file) comes back as ``{"error": message}``:
    trying again would not help, so it is not raised for Ray to retry. A drive stopped by the
    fleet's stop file comes back as ``{"interrupted": why}``, its staged outputs removed.
    Anything else raises, and a dead worker is retried by Ray.
    """
    import evigrid  # in the worker

    stop = stop_file(fleet_dir, run_id)
    staging = os.path.join(fleet_dir, PARTIAL, name)
    attempt = _previous_attempt(staging, run_id) + 1
    shutil.rmtree(staging, ignore_errors=True)
    if os.path.lexists(stop):
        return {"interrupted": "stopped by Ctrl-C before it started", "attempt": attempt}
    os.makedirs(staging)
    _write_json(
        os.path.join(staging, "worker.json"),
        {
            "run": run_id,
            "attempt": attempt,
            "drive": path,
            "host": socket.gethostname(),
            "pid": os.getpid(),
            "niceness": os.nice(0) if hasattr(os, "nice") else None,
            "started": time.time(),
        },
    )
    out = os.path.join(staging, "out")
    options = _sized_threads(options)
    cpu_start, wall_start = time.process_time(), time.perf_counter()
    try:
        summary = evigrid.run(path, out=out, stop=lambda: os.path.lexists(stop), **options)
    except evigrid.Error as error:
        shutil.rmtree(staging, ignore_errors=True)
        return {"error": one_line(error), "attempt": attempt}
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
    run_s = time.perf_counter() - wall_start
    cpu_s = time.process_time() - cpu_start
    if not summary.get("complete", False):
        shutil.rmtree(staging, ignore_errors=True)
        if os.path.lexists(stop):
            frames = summary.get("frames") or 0
            return {"interrupted": f"stopped by Ctrl-C after {frames} frames", "attempt": attempt}
        return {"error": f"stopped: {summary.get('stopped')}", "attempt": attempt}
    duration_s, moving_objects = _frames_figures(os.path.join(out, "frames.jsonl"))
    import ray  # in the worker

    result = {
        "summary": summary,
        "cpu_s": cpu_s,
        "run_s": run_s,
        "duration_s": duration_s,
        "moving_objects": moving_objects,
        "node": ray.get_runtime_context().get_node_id(),
        "attempt": attempt,
        "peak_rss_mb": _peak_rss_mb(),
    }
    _write_json(os.path.join(out, STAMP), {"key": key, "result": result})
    _move_into_place(out, os.path.join(fleet_dir, name), staging)
    shutil.rmtree(staging, ignore_errors=True)
    return result


def _sized_threads(options: Dict[str, Any]) -> Dict[str, Any]:
    """The options of ``evigrid.run`` with the drive's threads sized to the task's CPUs
    (``options["threads"]``): by the worker's shared pool when it is, or can still be, of that
    size (``RAYON_NUM_THREADS``, read when the pool starts, at the first drive), else by a pool
    of that size (``evigrid.run(threads=...)``). The shared pool first: inside a Ray worker a
    drive on a pool of its own measured 25-100 % slower (wall time; the same CPU time), for
    reasons not found."""
    global _shared_pool
    options = dict(options)
    threads = options.pop("threads", None)
    if threads is None:
        return options
    if _shared_pool is None:
        # Set by the user: the pool is of that size (0, or a word: not one we can tell).
        given = os.environ.setdefault("RAYON_NUM_THREADS", str(threads))
        _shared_pool = int(given) if given.isdigit() else 0
    if _shared_pool != threads:
        options["threads"] = threads
    return options


def stop_file(fleet_dir: str, run_id: str) -> str:
    """The file whose presence asks every task of the fleet run ``run_id`` to stop (each run has
    its own, so that one left by an interrupted run stops no later run)."""
    return os.path.join(fleet_dir, PARTIAL, f"stop-{run_id}")


def read_stamp(folder: str) -> Optional[Dict[str, Any]]:
    """The stamp of a drive's folder, or ``None`` when it has none that can be read."""
    try:
        with open(os.path.join(folder, STAMP), encoding="utf-8") as file:
            stamp = json.load(file)
    except (OSError, ValueError):
        return None
    return stamp if isinstance(stamp, dict) and "key" in stamp and "result" in stamp else None


def _peak_rss_mb() -> Optional[float]:
    """The worker's peak resident memory over its life so far, MiB (``None`` where the platform
    does not say: Windows)."""
    try:
        import resource
    except ImportError:
        return None
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    # Kilobytes on Linux, bytes on macOS.
    return peak / (1024.0 * 1024.0) if sys.platform == "darwin" else peak / 1024.0


def _previous_attempt(staging: str, run_id: str) -> int:
    """How many attempts of this fleet run started this drive before (0 for the first)."""
    try:
        with open(os.path.join(staging, "worker.json"), encoding="utf-8") as file:
            worker = json.load(file)
    except (OSError, ValueError):
        return 0
    return int(worker.get("attempt", 0)) if worker.get("run") == run_id else 0


def _move_into_place(out: str, folder: str, staging: str) -> None:
    """Renames the finished ``out`` to ``folder``; a folder there from earlier options (a stamp
    of ours) is moved aside first and removed after, never merged into."""
    if os.path.lexists(folder):
        old = os.path.join(staging, "old")
        os.rename(folder, old)
    os.rename(out, folder)


def _frames_figures(frames_jsonl: str) -> "tuple[Optional[float], int]":
    """The drive's recorded duration (last scan time − first) and its distinct moving objects,
    read from the run's ``frames.jsonl``."""
    first: Optional[float] = None
    last: Optional[float] = None
    objects = set()
    with open(frames_jsonl, encoding="utf-8") as file:
        for line in file:
            if not line.strip():
                continue
            frame = json.loads(line)
            time_s = frame.get("time_s")
            if isinstance(time_s, (int, float)):
                first = time_s if first is None else first
                last = time_s
            for moving in frame.get("moving_objects") or ():
                objects.add(moving.get("id"))
    duration = None if first is None or last is None else last - first
    return duration, len(objects)


def _write_json(path: str, value: Any) -> None:
    temporary = path + ".tmp"
    with open(temporary, "w", encoding="utf-8") as file:
        json.dump(value, file)
    os.replace(temporary, path)


def one_line(error: BaseException) -> str:
    """An exception's message, its first line (Ray's and Python's may run on with details)."""
    text = str(error).strip()
    return text.splitlines()[0] if text else type(error).__name__
