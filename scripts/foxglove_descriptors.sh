#!/usr/bin/env bash
# Regenerates the protobuf FileDescriptorSet of the recording's protobuf channel (`/scan`,
# foxglove.PointCloud) in crates/output/src/mcap/schemas/PointCloud.fds from Foxglove's official
# package, @foxglove/schemas on npm, at the version of the JSON Schemas beside it
# (schemas/VERSION, written by scripts/foxglove_schemas.sh: run that first to move on): the
# package's own `generateProto` writes the .proto files (as Foxglove's SDK generates its
# published ones), and `protoc` compiles them with their imports (google/protobuf/timestamp
# from protoc's well-known types) into one descriptor set, without source info.
# Needs node/npm and protoc (Debian: `apt-get install protobuf-compiler`).
set -euo pipefail
repo="$(cd "$(dirname "$0")/.." && pwd)"
out="$repo/crates/output/src/mcap/schemas"
version="$(sed -n 's/^@foxglove\/schemas //p' "$out/VERSION")"
command -v protoc >/dev/null || { echo "protoc not found (apt-get install protobuf-compiler)" >&2; exit 1; }
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
cd "$work"
npm install --silent --no-audit --no-fund "@foxglove/schemas@$version" >/dev/null
mkdir -p proto/foxglove
# The message and every foxglove.* message it nests, one .proto each (google.protobuf types,
# `protoEquivalent`, are protoc's own).
node -e '
  const fs = require("fs");
  const { foxgloveMessageSchemas, foxgloveEnumSchemas, generateProto } =
    require("@foxglove/schemas/internal");
  const done = new Set();
  const write = (schema) => {
    if (schema.protoEquivalent !== undefined || done.has(schema.name)) return;
    done.add(schema.name);
    const enums = Object.values(foxgloveEnumSchemas)
      .filter((e) => e.parentSchemaName === schema.name);
    fs.writeFileSync(`proto/foxglove/${schema.name}.proto`, generateProto(schema, enums));
    for (const field of schema.fields) {
      if (field.type.type === "nested") write(field.type.schema);
    }
  };
  write(foxgloveMessageSchemas[process.argv[1]]);
' PointCloud
protoc --proto_path=proto --include_imports \
  --descriptor_set_out="$out/PointCloud.fds" foxglove/PointCloud.proto
echo "wrote $out/PointCloud.fds ($(stat -c %s "$out/PointCloud.fds") bytes) from" \
  "$(cd proto && ls foxglove/*.proto | tr '\n' ' ')with $(protoc --version)"
