#!/usr/bin/env bash
# Regenerates the JSON Schemas of the MCAP recording's JSON channels (crates/output/src/mcap/schemas/)
# from Foxglove's official package, @foxglove/schemas on npm, at the version pinned below.
# Run it to move to a newer version, then scripts/foxglove_descriptors.sh (the protobuf `/scan`'s
# descriptor set, same version); `git diff` then shows what Foxglove changed.
set -euo pipefail
version="2.1.0"
repo="$(cd "$(dirname "$0")/.." && pwd)"
out="$repo/crates/output/src/mcap/schemas"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
cd "$work"
npm install --silent --no-audit --no-fund "@foxglove/schemas@$version" >/dev/null
mkdir -p "$out"
for name in Grid FrameTransform SceneUpdate LocationFix; do
  node -e '
    const schemas = require("@foxglove/schemas/jsonschema");
    const name = process.argv[1];
    process.stdout.write(JSON.stringify(schemas[name], null, 2) + "\n");
  ' "$name" > "$out/$name.json"
done
echo "@foxglove/schemas $version" > "$out/VERSION"
echo "wrote $(ls "$out" | wc -l) files to $out"
