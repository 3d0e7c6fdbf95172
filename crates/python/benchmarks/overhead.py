"""How much a session stepped from Python costs over the same session run in Rust.

Over the shared KITTI raw drive (drive 0013, 40 frames), in interleaved rounds:

- Rust: ``evigrid.run(drive, out=None)``, the session crate's frame loop (open, place, read every
  scan, step it) with no Python between frames and no output written;
- Python: ``evigrid.open_drive(drive)`` and ``Session.step(frame)`` for each frame from a Python
  loop (the same opening, placing, reading and stepping, the frame loop in Python);
- per step, over frames read beforehand: the wall time of the ``Session.step`` call from Python
  against the pipeline's own time inside it (``record["process_ms"]``, measured in Rust): what
  the binding and the session's bookkeeping (the ego-path check, the frame's record) add;
- two sessions stepped from Python in two threads against the same two one after the other.

It prints each round and the medians, and the ratios: Python / Rust (the issue's target is at
most 1.05) and two threads / serial (below 1 when the GIL is released and a core is free).

    EVIGRID_SHARED=../shared python crates/python/benchmarks/overhead.py --rounds 5
"""

from __future__ import annotations

import argparse
import os
import statistics
import threading
import time
from pathlib import Path

import evigrid


def drive_path() -> Path:
    shared = Path(os.environ.get("EVIGRID_SHARED", Path(__file__).resolve().parents[3].parent / "shared"))
    path = shared / "data" / "lidar" / "kitti-raw-0013" / "2011_09_26"
    if not path.is_dir():
        raise SystemExit(f"the shared KITTI drive is not at {path}; set EVIGRID_SHARED")
    return path


def rust(path: Path) -> float:
    started = time.perf_counter()
    summary = evigrid.run(path, out=None)
    assert summary["complete"]
    return time.perf_counter() - started


def python(path: Path) -> float:
    started = time.perf_counter()
    session = evigrid.Session()
    for frame in evigrid.open_drive(path):
        session.step(frame)
    assert session.frames > 0
    return time.perf_counter() - started


def per_step(path: Path) -> tuple[float, float]:
    frames = list(evigrid.open_drive(path))
    session = evigrid.Session()
    call_s = process_s = 0.0
    for frame in frames:
        started = time.perf_counter()
        result = session.step(frame)
        call_s += time.perf_counter() - started
        process_s += result.record["process_ms"] / 1e3
    return call_s, process_s


def threads(path: Path) -> tuple[float, float]:
    frames = list(evigrid.open_drive(path))

    def drive() -> None:
        session = evigrid.Session()
        for frame in frames:
            session.step(frame)

    started = time.perf_counter()
    drive()
    drive()
    serial = time.perf_counter() - started
    workers = [threading.Thread(target=drive) for _ in range(2)]
    started = time.perf_counter()
    for worker in workers:
        worker.start()
    for worker in workers:
        worker.join()
    return serial, time.perf_counter() - started


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=3, help="interleaved rounds (default 3)")
    args = parser.parse_args()
    path = drive_path()
    python(path)  # warm the file cache and the allocator
    rows = []
    for k in range(args.rounds):
        r, p = rust(path), python(path)
        c, q = per_step(path)
        s, t = threads(path)
        rows.append((r, p, c, q, s, t))
        print(f"round {k + 1}: rust {r:.3f} s, python {p:.3f} s (ratio {p / r:.3f}); "
              f"step calls {c:.3f} s over pipeline {q:.3f} s (ratio {c / q:.3f}); "
              f"two sessions serial {s:.3f} s, two threads {t:.3f} s (ratio {t / s:.3f})")
    ratios = [[row[1] / row[0], row[2] / row[3], row[5] / row[4]] for row in rows]
    whole, step, two = (statistics.median(column) for column in zip(*ratios))
    print(f"median ratios: python / rust (whole drive) = {whole:.3f}; "
          f"step call / pipeline = {step:.3f}; two threads / serial = {two:.3f}")
    print("target: python / rust <= 1.05")


if __name__ == "__main__":
    main()
