"""How a fleet scales on Ray, measured on drives made from the shared data.

Eight drives of 48 frames each (the kitti-city-22 scans 0-21, 21-0, 0-3 as a scan folder with a
pose file, 1 m per scan east at 10 Hz; links, no copies) are run three ways:

1. **serial**: ``evigrid.run`` on each, one after another, in this process (evigrid's thread
   pool on every CPU, as a shell loop over ``evigrid run`` would);
2. **fleet on N CPUs**: ``evigrid.fleet.run`` on a local Ray instance of ``--num-cpus`` CPUs
   (default 2), one CPU per drive, Ray already started (its start-up is printed apart);
3. **fleet one at a time**: the same instance, each drive taking every CPU, so drives run one
   after another as in 1, and what is added to 1 is Ray's (and the fleet's) overhead; run twice,
   the second time with its worker already started (a fleet of hundreds of drives pays the
   worker's start once).

Printed: the ratio 2 / 1 (target ≤ 0.6 on 2 CPUs) and Ray's overhead per drive,
(3 − Σ run time inside the tasks) / 8, as a share of a 48-frame drive's time (target ≤ 5 %),
with the machine's load average (other processes take CPUs from both sides differently), the
CPU seconds spent, and the workers' peak memory. ``--rounds N`` interleaves N rounds of the three
and keeps the fastest of each.

    python crates/python/benchmarks/fleet_scaling.py [--shared DIR] [--num-cpus 2] [--rounds 1]
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

# Ray's servers on the loopback interface only (read when Ray is imported), and its workers at
# this process's priority, as evigrid.fleet starts a local instance (Ray's default is niceness
# 15, which on a shared machine measures the other tenants, not the fleet).
os.environ.setdefault("RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER", "0")
os.environ.setdefault("RAY_worker_niceness", "0")  # an increment on this process's niceness

import evigrid  # noqa: E402
import evigrid.fleet  # noqa: E402

DRIVES = 8
FRAMES = 48


def make_drive(scans: list, folder: Path) -> dict:
    """A 48-frame scan folder with its pose file, from the 22 kitti-city-22 scans."""
    order = list(range(22)) + list(range(21, -1, -1)) + list(range(4))
    (folder / "scans").mkdir(parents=True)
    for k, index in enumerate(order[:FRAMES]):
        (folder / "scans" / f"{k:010d}.pcd").symlink_to(scans[index])
    poses = folder / "poses.txt"
    poses.write_text(
        "# time x y z roll pitch yaw\n"
        + "".join(f"{0.1 * k:.1f} {k} 0 1.73 0 0 0\n" for k in range(FRAMES))
    )
    return {"path": str(folder / "scans"), "poses": str(poses)}


def serial_run(drives: list, out: Path) -> "tuple[float, float, list]":
    """Wall and CPU seconds of ``evigrid.run`` on each drive, one after another, and each
    drive's wall time."""
    begun, cpu = time.perf_counter(), time.process_time()
    runs = []
    for k, drive in enumerate(drives):
        start = time.perf_counter()
        summary = evigrid.run(drive["path"], poses=drive["poses"], out=str(out / f"d{k}"))
        runs.append(time.perf_counter() - start)
        assert summary["frames"] == FRAMES, summary["frames"]
    return time.perf_counter() - begun, time.process_time() - cpu, runs


def fleet_run(drives: list, out: Path, cpus_per_drive: int) -> "tuple[float, object]":
    begun = time.perf_counter()
    table = evigrid.fleet.run(drives, out=out, cpus_per_drive=cpus_per_drive)
    assert table.column("status").to_pylist() == ["ok"] * DRIVES
    return time.perf_counter() - begun, table


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--shared", default=os.environ.get("EVIGRID_SHARED", "../shared"))
    parser.add_argument("--num-cpus", type=int, default=2)
    parser.add_argument(
        "--rounds",
        type=int,
        default=1,
        help="rounds of the three runs, interleaved; the fastest of each is kept",
    )
    args = parser.parse_args()
    scans = sorted((Path(args.shared) / "data" / "lidar" / "kitti-city-22").glob("*.pcd"))
    if len(scans) != 22:
        print(f"{args.shared}: the 22 kitti-city-22 scans not found (--shared)", file=sys.stderr)
        return 2

    import ray

    load_before = os.getloadavg()[0]
    with tempfile.TemporaryDirectory(prefix="evigrid-fleet-bench-") as tmp:
        root = Path(tmp)
        drives = [make_drive(scans, root / "drives" / f"d{k}") for k in range(DRIVES)]
        begun = time.perf_counter()
        ray.init(num_cpus=args.num_cpus, include_dashboard=False, log_to_driver=False)
        ray_start = time.perf_counter() - begun
        serial, fleet, one, warm = [], [], [], []
        try:
            for r in range(args.rounds):
                serial.append(serial_run(drives, root / f"serial-{r}"))
                fleet.append(fleet_run(drives, root / f"fleet-{r}", 1))
                one.append(fleet_run(drives, root / f"one-{r}", args.num_cpus))
                # Again, its worker started: what a drive costs once the fleet is under way.
                warm.append(fleet_run(drives, root / f"warm-{r}", args.num_cpus))
        finally:
            ray.shutdown()
    load_after = os.getloadavg()[0]

    serial_s, serial_cpu, serial_runs = min(serial, key=lambda x: x[0])
    fleet_s, fleet_table = min(fleet, key=lambda x: x[0])
    one_s, one_table = min(one, key=lambda x: x[0])
    drive_s = statistics.median(serial_runs)
    inside = sum(one_table.column("run_s").to_pylist())
    overhead = (one_s - inside) / DRIVES
    warm_s, warm_table = min(warm, key=lambda x: x[0])
    warm_inside = sum(warm_table.column("run_s").to_pylist())
    warm_overhead = (warm_s - warm_inside) / DRIVES
    print(
        f"{DRIVES} drives of {FRAMES} frames; {args.num_cpus} CPUs for Ray; os.cpu_count() = "
        f"{os.cpu_count()}; load average {load_before:.1f} before, {load_after:.1f} after; "
        f"fastest of {args.rounds} round(s)"
    )
    print(
        f"serial (evigrid.run one after another): {serial_s:.1f} s, {serial_cpu:.1f} CPU s "
        f"(median drive {drive_s:.2f} s)"
    )
    print(f"Ray start-up (ray.init, not counted below): {ray_start:.1f} s")
    print(
        f"fleet on {args.num_cpus} CPUs: {fleet_s:.1f} s, "
        f"{sum(fleet_table.column('cpu_s').to_pylist()):.1f} CPU s in the workers; "
        f"ratio to serial {fleet_s / serial_s:.2f} (target <= 0.6)"
    )
    print(
        f"fleet one drive at a time: {one_s:.1f} s, of which {inside:.1f} s inside evigrid.run; "
        f"Ray's overhead {overhead:.3f} s per drive = {100 * overhead / drive_s:.1f} % of a "
        f"{FRAMES}-frame drive (target <= 5 %)"
    )
    print(
        f"again, its worker started: {warm_s:.1f} s, of which {warm_inside:.1f} s inside "
        f"evigrid.run; {warm_overhead:.3f} s per drive = {100 * warm_overhead / drive_s:.1f} %"
    )
    memory = max(
        fleet_table.column("peak_rss_mb").to_pylist() + one_table.column("peak_rss_mb").to_pylist()
    )
    print(f"largest worker peak memory: {memory:.0f} MiB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
