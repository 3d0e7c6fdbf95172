"""A fleet of drives on Ray: many logs, one table, failures that stay alone.

``evigrid.fleet.run(drives, out=DIR)`` runs every drive as ``evigrid.run`` does, one Ray task per
drive, each drive's usual outputs under ``DIR/<drive name>/``, and writes ``DIR/fleet.parquet``
(one row per drive: status, error, frames, CPU time, the drive's duration, the ego-path share,
moving objects, skipped scans, output folder) with a short report (``fleet.md``, ``fleet.html``,
``fleet.svg``). The same from the shell: ``python -m evigrid.fleet DRIVE... --out DIR``.

Without ``address`` a local Ray instance is started (on the loopback interface only) and stopped
at the end; with one, the fleet joins that cluster; inside a script that already called
``ray.init``, that connection is used and left open.

The one design decision: **a task returns its drive's summary and a few figures, never a grid**.
The grids, pictures and recordings are written by the worker straight into the drive's folder
(the fleet folder must be on storage every node sees), so the object store carries a few
kilobytes per drive and the driver's memory does not grow with the fleet.

Failures stay alone: a drive evigrid refuses is a ``failed`` row naming its error while the
others run; a worker killed during a drive is retried (``retries``, default 2); a drive's folder
appears whole by one rename, never half-written. Rerunning the same call skips the drives whose
folder holds a complete run with the same options (``resumed`` in the table). Ctrl-C asks every
task to stop at its next frame (a stop file each task looks for; never ``ray.cancel``), waits for
them, writes the table of what finished, then raises ``KeyboardInterrupt``.

Example (needs ``pip install "evigrid[fleet]"``)::

    import evigrid.fleet

    table = evigrid.fleet.run(["drives/a", "drives/b.mcap", "drives.txt"], out="fleet-out")
    print(table.to_pandas()[["drive", "status", "frames", "ego_path_share"]])
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
import shutil
import signal
import sys
import threading
import time
import uuid
from typing import Any, Callable, Dict, Iterable, List, Mapping, Optional, Union

import evigrid
from evigrid._errors import InputError
from evigrid.fleet._drives import DRIVE_OPTIONS, DriveArg, DriveSpec, drive_specs, folder_names
from evigrid.fleet._report import write_report
from evigrid.fleet._table import COLUMNS, STATUSES, failed_row, ok_row, write_table
from evigrid.fleet._task import PARTIAL, STAMP, one_line, read_stamp, run_drive, stop_file

__all__ = ["COLUMNS", "DRIVE_OPTIONS", "MARKER", "STAMP", "STATUSES", "run"]

MARKER = ".evigrid-fleet"
"""The file that marks a folder as a fleet's output, so that a rerun may write into it."""

# How long, after Ctrl-C, the driver waits for the tasks to stop before it writes the table
# anyway.
_STOP_WAIT_S = 10.0

# How often the driver looks at Ctrl-C while it waits for the tasks.
_POLL_S = 0.25

Config = Union[str, "os.PathLike[str]", Mapping[str, Any], None]


def run(
    drives: Union[DriveArg, Iterable[DriveArg]],
    *,
    out: Union[str, "os.PathLike[str]"],
    address: Optional[str] = None,
    num_cpus: Optional[int] = None,
    retries: int = 2,
    config: Config = None,
    method: str = "evigrid",
    map: Union[str, "os.PathLike[str]", None] = None,
    cpus_per_drive: int = 1,
    progress: Optional[Callable[[str], None]] = None,
) -> Any:
    """Runs every drive on Ray and returns the fleet's table (a ``pyarrow.Table``, also written
    to ``out/fleet.parquet``).

    ``drives``: paths ``evigrid.open_drive`` reads (KITTI raw folder, scan folder, ROS 2 bag),
    dicts ``{"path": ..., "poses": ..., "times": ...}`` with a drive's own options, or text
    files listing drives one a line (``PATH [--poses FILE] [--times FILE] ...``, paths relative
    to the list file). ``config``, ``method`` and ``map`` are those of ``evigrid.run``, the same
    for every drive. ``address``: a Ray cluster to join (``"auto"``, ``"HOST:PORT"``); without
    it a local instance with ``num_cpus`` CPUs (default all). Each drive's task takes
    ``cpus_per_drive`` CPUs and evigrid's thread pool is sized to them. A killed worker's drive
    is tried again up to ``retries`` times. ``progress`` is called with one line per finished
    drive.

    # Errors
    ``evigrid.InputError`` before any drive runs when the drives, the options or ``out`` cannot
    be used (``out`` must be new, empty, or a fleet folder). A drive's own failure is a row,
    not an exception. ``KeyboardInterrupt`` after the table is written, on Ctrl-C.
    ``ImportError`` without Ray or pyarrow (the ``[fleet]`` extra).
    """
    started = time.perf_counter()
    say = progress or (lambda line: None)
    if retries < 0:
        raise InputError(f"retries {retries}: must be 0 or more")
    if cpus_per_drive < 1:
        raise InputError(f"cpus_per_drive {cpus_per_drive}: must be 1 or more")
    if num_cpus is not None and (address is not None or num_cpus < 1):
        raise InputError(
            f"num_cpus {num_cpus}: must be 1 or more, and only for a local instance (no address)"
        )
    _require_extra()
    specs = drive_specs(drives)
    names = folder_names(specs)
    fleet_dir = _fleet_dir(out)
    options = _run_options(config, method, map)
    common_key = _options_key(options)

    rows: List[Optional[Dict[str, Any]]] = [None] * len(specs)
    todo: List[int] = []
    for i, (spec, name) in enumerate(zip(specs, names)):
        folder = os.path.join(fleet_dir, name)
        if not os.path.lexists(folder):
            todo.append(i)
            continue
        stamp = read_stamp(folder)
        if stamp is None:
            rows[i] = failed_row(
                spec.given,
                name,
                "failed",
                f"{folder}: exists and is not a drive folder of this fleet (no {STAMP}); "
                "move it away",
            )
        elif stamp["key"] == _key(spec, common_key):
            rows[i] = ok_row(spec.given, name, folder, stamp["result"], resumed=True)
        else:
            todo.append(i)
    resumed = sum(row is not None and row["resumed"] for row in rows)
    say(f"evigrid fleet: {len(specs)} drives, {resumed} done before (skipped), {len(todo)} to run")

    interrupted, settled = False, True
    ctrl_c = _CtrlC()
    try:
        if todo:
            interrupted, settled = _run_on_ray(
                specs,
                names,
                todo,
                rows,
                fleet_dir,
                options,
                common_key,
                address=address,
                num_cpus=num_cpus,
                retries=retries,
                cpus_per_drive=cpus_per_drive,
                say=say,
                ctrl_c=ctrl_c,
            )
        final = [
            row
            if row is not None
            else failed_row(specs[i].given, names[i], "interrupted", "not run")
            for i, row in enumerate(rows)
        ]
        table = write_table(final, os.path.join(fleet_dir, "fleet.parquet"))
        write_report(final, fleet_dir, time.perf_counter() - started)
        if settled:
            _remove_partial(fleet_dir)
    finally:
        ctrl_c.uninstall()
    interrupted = interrupted or ctrl_c.pressed
    ok = sum(row["status"] == "ok" for row in final)
    say(f"evigrid fleet: {ok} of {len(final)} drives ok; table {fleet_dir}/fleet.parquet")
    if interrupted:
        raise KeyboardInterrupt
    return table


def _run_on_ray(
    specs: List[DriveSpec],
    names: List[str],
    todo: List[int],
    rows: List[Optional[Dict[str, Any]]],
    fleet_dir: str,
    options: Dict[str, Any],
    common_key: Dict[str, Any],
    *,
    address: Optional[str],
    num_cpus: Optional[int],
    retries: int,
    cpus_per_drive: int,
    say: Callable[[str], None],
    ctrl_c: "_CtrlC",
) -> "tuple[bool, bool]":
    """Runs the drives ``todo`` as Ray tasks, filling their rows. Returns whether Ctrl-C
    stopped it, and whether every task has ended (else one may still write under ``.partial``).
    ``ctrl_c`` takes Ctrl-C from the moment Ray is connected (until the caller uninstalls it)."""
    ray = _import_ray(local=address is None)
    try:
        # Ctrl-C stays KeyboardInterrupt here: joining a cluster that does not answer can take
        # a minute.
        started_ray = _connect(ray, address, num_cpus)
    except KeyboardInterrupt:
        # While Ray started: no drive ran.
        if address is None and ray.is_initialized():
            ray.shutdown()
        return True, True
    ctrl_c.install()
    run_id = uuid.uuid4().hex
    task = ray.remote(run_drive)
    # evigrid's threads are sized to the task's CPUs in the worker (`_task._sized_threads`), not
    # by a runtime environment (RAYON_NUM_THREADS): Ray starts workers of their own for a task
    # with one, even of environment variables alone, so the workers it had already started
    # would sit idle while new ones start (seconds each on a loaded machine).
    task_options = {"num_cpus": cpus_per_drive, "max_retries": retries, "retry_exceptions": False}
    pending: Dict[Any, int] = {}
    done_count = len(specs) - len(todo)

    def collect(ready: List[Any]) -> None:
        nonlocal done_count
        for ref in ready:
            i = pending[ref]
            rows[i] = _collect(ray, ref, specs[i], names[i], fleet_dir, retries)
            # Only once its row is filled: a KeyboardInterrupt raised meanwhile leaves the
            # task pending, to be collected again.
            del pending[ref]
            done_count += 1
            say(_progress_line(done_count, len(specs), rows[i]))

    try:
        try:
            for i in todo:
                if ctrl_c.pressed:
                    break
                spec = specs[i]
                ref = task.options(name=f"evigrid-fleet {names[i]}", **task_options).remote(
                    spec.path,
                    names[i],
                    fleet_dir,
                    {**options, **spec.options, "threads": cpus_per_drive},
                    _key(spec, common_key),
                    run_id,
                )
                pending[ref] = i
            while pending and not ctrl_c.pressed:
                ready, _ = ray.wait(list(pending), num_returns=1, timeout=_POLL_S)
                collect(ready)
        except KeyboardInterrupt:
            # Raised here when this is not the main thread, or the caller's own SIGINT handler
            # raised it (else `_CtrlC` takes the signal).
            ctrl_c.count += 1
        if not ctrl_c.pressed:
            return False, True
        say(f"evigrid fleet: interrupted; stopping {len(pending)} drives")
        why = _stop(
            ray, pending, collect, fleet_dir, run_id, ctrl_c, wait_s=_STOP_WAIT_S, say=say
        )
        for i in pending.values():
            rows[i] = failed_row(specs[i].given, names[i], "interrupted", why)
        return True, not pending
    finally:
        if started_ray:
            ray.shutdown()


class _CtrlC:
    """Ctrl-C as a count the fleet looks at between its waits, rather than ``KeyboardInterrupt``
    raised wherever the driver is (in the middle of collecting a result, or inside Ray).

    Installed only in the main thread, over Python's default SIGINT handler; elsewhere, or over
    the caller's own handler, Ctrl-C stays ``KeyboardInterrupt``, which the fleet counts here.
    """

    def __init__(self) -> None:
        self.count = 0
        self._previous: Any = None

    @property
    def pressed(self) -> bool:
        """Whether Ctrl-C was pressed."""
        return self.count > 0

    def install(self) -> None:
        """Takes SIGINT, where it may (the main thread, Python's default handler)."""
        if (
            self._previous is None
            and threading.current_thread() is threading.main_thread()
            and signal.getsignal(signal.SIGINT) is signal.default_int_handler
        ):
            self._previous = signal.signal(signal.SIGINT, self._handle)

    def uninstall(self) -> None:
        """Gives SIGINT back to the handler before :meth:`install`."""
        if self._previous is not None:
            signal.signal(signal.SIGINT, self._previous)
            self._previous = None

    def _handle(self, _signum: int, _frame: Any) -> None:
        self.count += 1


def _stop(
    ray: Any,
    pending: Dict[Any, int],
    collect: Callable[[List[Any]], None],
    fleet_dir: str,
    run_id: str,
    ctrl_c: _CtrlC,
    *,
    wait_s: float,
    say: Callable[[str], None] = lambda line: None,
) -> str:
    """Asks every task to stop (the stop file each looks for between frames), then collects
    the tasks as they end, for up to ``wait_s`` seconds or until Ctrl-C is pressed again.
    Returns the error of the rows of the tasks still running then.

    No task is cancelled: Ray 2.60's owner aborts the driver when a cancel races with the reply
    of a task that is finishing ("Tried to complete task that was not pending",
    task_manager.cc), also without ``force``. Each task ends by itself, with its result (a drive
    that finished meanwhile is ok) or ``interrupted``; one that does not end in time (a worker
    stuck in a long read) stays in ``pending``, left to Ray's shutdown.
    """
    stop = stop_file(fleet_dir, run_id)
    try:
        os.makedirs(os.path.dirname(stop), exist_ok=True)
        with open(stop, "w", encoding="utf-8") as file:
            file.write("Ctrl-C: every task of this fleet run stops at its next frame\n")
    except OSError as error:
        # The tasks will not stop; the table is still written, after the wait.
        say(f"evigrid fleet: {stop}: cannot be written ({error.strerror}); the drives run on")
    presses = ctrl_c.count
    deadline = time.monotonic() + wait_s
    try:
        while pending and time.monotonic() < deadline and ctrl_c.count == presses:
            timeout = max(0.0, min(_POLL_S, deadline - time.monotonic()))
            ready, _ = ray.wait(list(pending), num_returns=len(pending), timeout=timeout)
            collect(ready)
    except KeyboardInterrupt:
        # Ctrl-C again, where `_CtrlC` could not take it.
        ctrl_c.count += 1
    if ctrl_c.count > presses:
        return "still running at the second Ctrl-C (left to Ray's shutdown)"
    return f"did not stop within {wait_s:g} s of Ctrl-C (left to Ray's shutdown)"


def _collect(
    ray: Any, ref: Any, spec: DriveSpec, name: str, fleet_dir: str, retries: int
) -> Dict[str, Any]:
    """The row of a finished task."""
    from ray import exceptions

    try:
        result = ray.get(ref)
    except exceptions.TaskCancelledError:
        # Cancelled by the caller's own `ray.cancel`: the fleet never cancels.
        return failed_row(spec.given, name, "interrupted", "cancelled")
    except exceptions.RayTaskError as error:
        cause = error.cause
        if isinstance(cause, KeyboardInterrupt):
            return failed_row(spec.given, name, "interrupted", "interrupted in its worker")
        return failed_row(spec.given, name, "failed", f"{type(cause).__name__}: {one_line(cause)}")
    except exceptions.WorkerCrashedError:
        return failed_row(
            spec.given,
            name,
            "failed",
            f"its worker died on each of {retries + 1} attempts (killed, or out of memory)",
            attempts=retries + 1,
        )
    except exceptions.RayError as error:
        return failed_row(spec.given, name, "failed", f"{type(error).__name__}: {one_line(error)}")
    if "error" in result:
        return failed_row(spec.given, name, "failed", result["error"], result.get("attempt"))
    if "interrupted" in result:
        return failed_row(
            spec.given, name, "interrupted", result["interrupted"], result.get("attempt")
        )
    return ok_row(spec.given, name, os.path.join(fleet_dir, name), result, resumed=False)


def _progress_line(done: int, total: int, row: Dict[str, Any]) -> str:
    if row["status"] == "ok":
        what = f"ok, {row['frames']} frames in {row['run_s']:.1f} s"
        if (row["attempts"] or 1) > 1:
            what += f" ({row['attempts']} attempts)"
    else:
        what = f"{row['status']}: {row['error']}"
    return f"evigrid fleet: [{done}/{total}] {row['name']}: {what}"


def _require_extra() -> None:
    """Ray and pyarrow are the ``[fleet]`` extra's: without them, say how to get them."""
    import importlib.util

    missing = [name for name in ("ray", "pyarrow") if importlib.util.find_spec(name) is None]
    if missing:
        raise ImportError(
            f'evigrid.fleet needs {" and ".join(missing)}: pip install "evigrid[fleet]"'
        )


def _import_ray(local: bool) -> Any:
    """Imports Ray; for a local instance, first makes it listen on the loopback interface only.

    On Linux Ray takes the machine's network address as its node address and its servers listen
    on every interface; ``RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER=0`` is Ray's own switch to the
    loopback address (its default on Windows and macOS), read once when Ray is imported.
    """
    if local and "ray" not in sys.modules:
        os.environ.setdefault("RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER", "0")
    import ray

    return ray


def _connect(ray: Any, address: Optional[str], num_cpus: Optional[int]) -> bool:
    """Connects to Ray unless this process already is; True when this call started it."""
    if ray.is_initialized():
        return False
    quiet = {"log_to_driver": False, "logging_level": logging.WARNING}
    if address is None:
        # Ray makes its workers 15 nicer than the raylet this call starts (a `nice(15)` in each
        # worker, an increment); the drives of a local fleet run at the caller's own priority,
        # as `evigrid run` would: no increment, the workers inherit this process's niceness.
        os.environ.setdefault("RAY_worker_niceness", "0")
        ray.init(num_cpus=num_cpus, include_dashboard=False, **quiet)
    else:
        ray.init(address=address, **quiet)
    return True


def _fleet_dir(out: Union[str, "os.PathLike[str]"]) -> str:
    """The fleet folder, created, or refused when it holds someone else's files."""
    fleet_dir = os.path.abspath(os.fspath(out))
    if os.path.exists(fleet_dir):
        if not os.path.isdir(fleet_dir):
            raise InputError(f"{fleet_dir}: exists and is not a folder")
        if os.listdir(fleet_dir) and not os.path.exists(os.path.join(fleet_dir, MARKER)):
            raise InputError(
                f"{fleet_dir}: not empty and not a fleet folder (no {MARKER}); "
                "choose a new or empty folder"
            )
    try:
        os.makedirs(fleet_dir, exist_ok=True)
        with open(os.path.join(fleet_dir, MARKER), "a", encoding="utf-8"):
            pass
    except OSError as error:
        raise evigrid.FileError(f"{fleet_dir}: cannot be written: {error.strerror}") from None
    return fleet_dir


def _run_options(config: Config, method: str, map: Any) -> Dict[str, Any]:
    """The options of ``evigrid.run`` common to every drive, paths made absolute (the workers do
    not share the driver's working folder), checked once here rather than failing every drive."""
    if config is not None and not isinstance(config, Mapping):
        config = os.path.abspath(os.fspath(config))
    if map is not None:
        map = os.path.abspath(os.fspath(map))
        if not os.path.isfile(map):
            raise InputError(f"{map}: the map is not a file")
    # The configuration and the method, checked by building a session (no map: that can be big).
    evigrid.Session(dict(config) if isinstance(config, Mapping) else config, method=method)
    return {
        "config": dict(config) if isinstance(config, Mapping) else config,
        "method": method,
        "map": map,
    }


def _options_key(options: Dict[str, Any]) -> Dict[str, Any]:
    """What a complete drive folder must have been run with to be skipped: the evigrid version,
    the method, the configuration's content, the map's size and time of change."""
    config = options["config"]
    if config is None:
        config_key = None
    elif isinstance(config, dict):
        config_key = _digest(json.dumps(config, sort_keys=True).encode())
    else:
        with open(config, "rb") as file:
            config_key = _digest(file.read())
    map_key = None
    if options["map"] is not None:
        status = os.stat(options["map"])
        map_key = {"path": options["map"], "size": status.st_size, "mtime_ns": status.st_mtime_ns}
    return {
        "evigrid": evigrid.__version__,
        "method": options["method"],
        "config": config_key,
        "map": map_key,
    }


def _key(spec: DriveSpec, common: Dict[str, Any]) -> Dict[str, Any]:
    key = {**common, "drive": spec.path, "drive_options": spec.options}
    # As a stamp read back holds it.
    return json.loads(json.dumps(key, sort_keys=True))


def _digest(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def _remove_partial(fleet_dir: str) -> None:
    """Removes what killed or stopped tasks left half-written (and the stop file), once no task
    is alive."""
    shutil.rmtree(os.path.join(fleet_dir, PARTIAL), ignore_errors=True)
