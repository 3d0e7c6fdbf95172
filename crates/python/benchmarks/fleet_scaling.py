"""How a fleet scales on Ray, measured on drives made from the shared data.

Eight drives of 48 frames each (the kitti-city-22 scans 0-21, 21-0, 0-3 as a scan folder with a
pose file, 1 m per scan east at 10 Hz; links, no copies) are run three ways:

1. **serial**: ``evigrid.run`` on each, one after another, in this process (evigrid's thread
   pool on every CPU, as a shell loop over ``evigrid run`` would);
2. **fleet on N CPUs**: ``evigrid.fleet.run`` on a local Ray instance of ``--num-cpus`` CPUs
   (default 2), one CPU per drive, Ray already started (its start-up is printed apart);
3. **fleet one at a time**: the same instance, each drive taking every CPU, so drives run one
   after another as in 1, and what is added to 1 is Ray's (and the fleet's) overhead.

Printed: the ratio 2 / 1 (target ≤ 0.6 on 2 CPUs) and Ray's overhead per drive,
(3 − Σ run time inside the tasks) / 8, as a share of a 48-frame drive's time (target ≤ 5 %).

    python crates/python/benchmarks/fleet_scaling.py [--shared ../shared] [--num-cpus 2]
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

# Ray's servers on the loopback interface only (read when Ray is imported).
os.environ.setdefault("RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER", "0")

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


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--shared", default=os.environ.get("EVIGRID_SHARED", "../shared"))
    parser.add_argument("--num-cpus", type=int, default=2)
    args = parser.parse_args()
    scans = sorted((Path(args.shared) / "data" / "lidar" / "kitti-city-22").glob("*.pcd"))
    if len(scans) != 22:
        print(f"{args.shared}: the 22 kitti-city-22 scans not found (--shared)", file=sys.stderr)
        return 2

    import ray

    with tempfile.TemporaryDirectory(prefix="evigrid-fleet-bench-") as tmp:
        root = Path(tmp)
        drives = [make_drive(scans, root / "drives" / f"d{k}") for k in range(DRIVES)]

        started = time.perf_counter()
        serial_runs = []
        for k, drive in enumerate(drives):
            begun = time.perf_counter()
            summary = evigrid.run(drive["path"], poses=drive["poses"], out=str(root / "serial" / f"d{k}"))
            serial_runs.append(time.perf_counter() - begun)
            assert summary["frames"] == FRAMES, summary["frames"]
        serial = time.perf_counter() - started

        begun = time.perf_counter()
        ray.init(num_cpus=args.num_cpus, include_dashboard=False, log_to_driver=False)
        ray_start = time.perf_counter() - begun
        try:
            begun = time.perf_counter()
            table = evigrid.fleet.run(drives, out=root / "fleet")
            fleet = time.perf_counter() - begun
            assert table.column("status").to_pylist() == ["ok"] * DRIVES

            begun = time.perf_counter()
            table = evigrid.fleet.run(drives, out=root / "fleet-one", cpus_per_drive=args.num_cpus)
            one_at_a_time = time.perf_counter() - begun
            inside = sum(table.column("run_s").to_pylist())
            memory = max(table.column("peak_rss_mb").to_pylist())
        finally:
            ray.shutdown()

    drive_s = statistics.median(serial_runs)
    overhead = (one_at_a_time - inside) / DRIVES
    print(f"{DRIVES} drives of {FRAMES} frames, {args.num_cpus} CPUs for Ray, os.cpu_count() = {os.cpu_count()}")
    print(f"serial (evigrid.run one after another): {serial:.1f} s (median drive {drive_s:.2f} s)")
    print(f"Ray start-up (ray.init, not counted below): {ray_start:.1f} s")
    print(f"fleet on {args.num_cpus} CPUs: {fleet:.1f} s; ratio to serial {fleet / serial:.2f} (target <= 0.6)")
    print(
        f"fleet one drive at a time: {one_at_a_time:.1f} s, of which {inside:.1f} s inside evigrid.run; "
        f"Ray's overhead {overhead:.3f} s per drive = {100 * overhead / drive_s:.1f} % of a "
        f"{FRAMES}-frame drive (target <= 5 %)"
    )
    print(f"largest worker peak memory: {memory:.0f} MiB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
