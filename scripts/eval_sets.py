#!/usr/bin/env python3
"""Run one of the drive sets of scenarios/README.md (tuning, validation, test) through
`evigrid eval` and print each drive's in-view figures and the set's means.

    python3 scripts/eval_sets.py tuning|validation|test|all [--config C.toml] [--out DIR]
        [--bin target/release/evigrid] [--only drive,drive] [--list]

The sets are read from the table in scenarios/README.md, so that they cannot drift from it;
`--list` only checks that every drive named there exists and prints the sets. Each drive runs
`evigrid eval --map MAP --scenario scenarios/S.toml --seeds 2 --variants evigrid,kurdej2013
--json`; the map is chosen by the city in the drive's name. Columns: moving IoU, dynamic
accuracy, M precision, occupied-static accuracy, macro-F1 (all `scores_visible` of the
`evigrid` variant), and `kurdej2013`'s occupied-static accuracy.
"""
import argparse
import json
import os
import re
import statistics
import subprocess
import sys

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
MAPS = {"helsinki": "helsinki-centre.osm.pbf", "kouvola": "kouvola.osm.pbf",
        "monaco": "monaco.osm.gz", "village": "bavarian-village.osm"}
KEYS = ["moving_iou", "dynamic_accuracy", "moving_precision", "occupied_static_accuracy",
        "macro_f1"]


def read_sets():
    """The sets of scenarios/README.md's table: {set: [drive, ...]} (family drives prefixed)."""
    path = os.path.join(REPO, "scenarios", "README.md")
    sets = {}
    for line in open(path, encoding="utf-8"):
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) == 3 and cells[0] in ("tuning", "validation", "test"):
            shipped = re.findall(r"`([^`]+)`", cells[1])
            families = ["families/" + d for d in re.findall(r"`([^`]+)`", cells[2])]
            sets[cells[0]] = shipped + families
    if set(sets) != {"tuning", "validation", "test"}:
        sys.exit(f"{path}: the table of tuning, validation and test drives was not found")
    return sets


def map_for(drive):
    name = drive.split("/")[-1]
    for city, file in MAPS.items():
        if city in name:
            return file
    sys.exit(f"{drive}: no city of {sorted(MAPS)} in its name, so no map")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("set", choices=["tuning", "validation", "test", "all"])
    ap.add_argument("--bin", default=os.path.join(REPO, "target", "release", "evigrid"))
    ap.add_argument("--config")
    ap.add_argument("--out", default="eval-sets")
    ap.add_argument("--only", help="comma-separated drives of the set to run")
    ap.add_argument("--list", action="store_true", help="check and print the sets only")
    a = ap.parse_args()
    sets = read_sets()
    names = list(sets) if a.set == "all" else [a.set]
    for name in names:
        for drive in sets[name]:
            if not os.path.isfile(os.path.join(REPO, "scenarios", drive + ".toml")):
                sys.exit(f"scenarios/README.md names {drive} in the {name} set; "
                         f"scenarios/{drive}.toml does not exist")
            map_for(drive)
        if a.list:
            print(f"{name} ({len(sets[name])}): {' '.join(sets[name])}")
    if a.list:
        return
    shared = os.environ.get("EVIGRID_SHARED", os.path.join(REPO, "..", "shared"))
    for name in names:
        drives = sets[name]
        if a.only:
            drives = [d for d in drives if d in a.only.split(",")]
        rows = []
        for drive in drives:
            cmd = [a.bin, "eval", "--map", os.path.join(shared, "data", "osm", map_for(drive)),
                   "--scenario", os.path.join(REPO, "scenarios", drive + ".toml"),
                   "--seeds", "2", "--variants", "evigrid,kurdej2013",
                   "--out", os.path.join(a.out, name, drive.replace("/", "_")),
                   "--force", "--json"]
            if a.config:
                cmd += ["--config", a.config]
            run = subprocess.run(cmd, capture_output=True, text=True)
            if run.returncode != 0:
                sys.exit(f"{drive}: evigrid eval exited {run.returncode}: {run.stderr.strip()}")
            scores = {v["variant"]: v["scores_visible"] for v in json.loads(run.stdout)["variants"]}
            row = [scores["evigrid"][k] for k in KEYS]
            row.append(scores["kurdej2013"]["occupied_static_accuracy"])
            rows.append(row)
            print(f"{name:10s} {drive:36s} " + " ".join(f"{x:.4f}" for x in row), flush=True)
        if rows:
            means = [statistics.mean(col) for col in zip(*rows)]
            label = f"MEAN ({len(rows)})"
            print(f"{name:10s} {label:36s} " + " ".join(f"{x:.4f}" for x in means), flush=True)
    print("columns: moving IoU, DA, M precision, occupied-static, macro-F1 | kurdej2013 "
          "occupied-static")


if __name__ == "__main__":
    main()
