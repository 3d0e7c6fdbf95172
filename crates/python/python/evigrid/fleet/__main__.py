"""``python -m evigrid.fleet DRIVE... --out DIR``: a fleet of drives on Ray, one table.

Exit status: 0 when every drive is ok, 1 when some failed or were interrupted, 2 for bad usage
or input (nothing run), 130 after Ctrl-C (the table of what finished is written first).
"""

from __future__ import annotations

import argparse
import sys
from typing import List, Optional

import evigrid
from evigrid import fleet

_EPILOG = """\
A DRIVE is a KITTI raw drive folder, a folder of scans, or a ROS 2 recording (.mcap), or a text
file listing drives one a line, each line a path with that drive's own options of `evigrid run`
(--poses, --pose-format, --calib, --times, --mounting, --cloud-topic, --pose-source, --origin,
--max-frames), relative paths taken from the list's folder, # for comments.

Outputs in DIR: one folder per drive (the outputs of `evigrid run`, with fleet-drive.json),
fleet.parquet (one row per drive), fleet.md, fleet.html and fleet.svg (the report).
Rerunning the same command skips the drives already done with the same options.
"""


def main(argv: Optional[List[str]] = None) -> int:
    """Runs the command; returns its exit status."""
    parser = argparse.ArgumentParser(
        prog="python -m evigrid.fleet",
        description="Run evigrid over many drives on Ray and gather one table.",
        epilog=_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("drives", nargs="+", metavar="DRIVE", help="drives, or files listing them")
    parser.add_argument("--out", required=True, metavar="DIR", help="the fleet's output folder")
    parser.add_argument(
        "--address",
        metavar="ADDR",
        help="a Ray cluster to join (HOST:PORT, or auto); by default a local instance",
    )
    parser.add_argument(
        "--num-cpus",
        type=int,
        metavar="N",
        help="CPUs of the local instance (default: all); drives run N at a time",
    )
    parser.add_argument(
        "--retries",
        type=int,
        default=2,
        metavar="N",
        help="tries again a drive whose worker died, N times (default: 2)",
    )
    parser.add_argument("--config", metavar="C", help="parameters (TOML), as for evigrid run")
    parser.add_argument(
        "--method", default="evigrid", metavar="M", help="evigrid (default) or kurdej2013"
    )
    parser.add_argument("--map", metavar="MAP", help="vector map, the same for every drive")
    parser.add_argument("-q", "--quiet", action="store_true", help="no progress lines")
    args = parser.parse_args(argv)

    def progress(line: str) -> None:
        print(line, file=sys.stderr, flush=True)

    try:
        table = fleet.run(
            args.drives,
            out=args.out,
            address=args.address,
            num_cpus=args.num_cpus,
            retries=args.retries,
            config=args.config,
            method=args.method,
            map=args.map,
            progress=None if args.quiet else progress,
        )
    except (evigrid.Error, ImportError) as error:
        print(f"evigrid fleet: {error}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("evigrid fleet: interrupted; the table holds what finished", file=sys.stderr)
        return 130
    statuses = table.column("status").to_pylist()
    return 0 if all(status == "ok" for status in statuses) else 1


if __name__ == "__main__":
    sys.exit(main())
