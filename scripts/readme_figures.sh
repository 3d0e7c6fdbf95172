#!/usr/bin/env bash
# Re-measures the figures of the README's front (Quick start, Demo, the recording's size), each
# with the command that gives it, so that a README figure can be checked or brought up to date.
#
#   scripts/readme_figures.sh [--first-build]
#
# Always: the demo (`evigrid demo`, release build): wall and CPU time, the folder's size and file
# count, the GIF and the recording; with $EVIGRID_SHARED (the shared data), the recording of the
# 40 KITTI raw 0013 frames, per frame. With --first-build: the README's main command from nothing,
# `cargo build --release -p evigrid-cli` in an empty target folder (several CPU-minutes), CPU
# (user + sys) and wall time. Times depend on the machine and on what else runs on it: the README
# states the machine (2 cores) and whether it was idle.
set -euo pipefail
cd "$(dirname "$0")/.."
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
timed() { /usr/bin/time -f "%e %U %S" -o "$work/time" "$@"; read -r wall user sys < "$work/time"; }

if [ "${1:-}" = "--first-build" ]; then
  timed env CARGO_TARGET_DIR="$work/target" cargo build --release -q -p evigrid-cli
  echo "first build: $(awk "BEGIN { print $user + $sys }") s CPU (user $user + sys $sys), $wall s wall" \
    "(CARGO_TARGET_DIR=<empty> cargo build --release -p evigrid-cli)"
  rm -rf "$work/target"
fi

cargo build --release -q -p evigrid-cli
evigrid="target/release/evigrid"
timed "$evigrid" demo --out "$work/demo" > /dev/null
echo "demo: $wall s wall, $(awk "BEGIN { print $user + $sys }") s CPU (evigrid demo)"
echo "demo folder: $(du -sb "$work/demo" | cut -f1) bytes in $(find "$work/demo" -type f | wc -l) files" \
  "(du -sb evigrid-demo; find evigrid-demo -type f | wc -l)"
echo "demo GIF: $(stat -c %s "$work/demo/decision.gif") bytes; recording: $(stat -c %s "$work/demo/run.mcap") bytes" \
  "for $(python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["frames_per_seed"])' "$work/demo/metrics.json" 2> /dev/null || echo '?') frames"

kitti="${EVIGRID_SHARED:-../shared}/data/lidar/kitti-raw-0013/2011_09_26"
if [ -d "$kitti" ]; then
  timed "$evigrid" run --drive "$kitti" --config examples/config.toml --out "$work/kitti" > /dev/null
  bytes="$(stat -c %s "$work/kitti/run.mcap")"
  echo "KITTI 0013, 40 frames: run.mcap $bytes bytes, $((bytes / 40)) a frame; $wall s wall" \
    "(evigrid run --drive $kitti --config examples/config.toml)"
else
  echo "KITTI: skipped (no shared data at $kitti; set EVIGRID_SHARED)"
fi
