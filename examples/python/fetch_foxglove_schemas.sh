#!/usr/bin/env bash
# Fetches Foxglove's published JSON schemas from the npm registry (the @foxglove/schemas package, the
# version below) into DIR, one file per schema (LocationFix.json, GeoJSON.json, ...). The recording
# test validates every Foxglove message of a uavloc recording against them:
#
#   examples/python/fetch_foxglove_schemas.sh target/foxglove-schemas
#   target/pyenv/bin/python examples/python/check_foxglove.py run.mcap target/foxglove-schemas
#
# Needs npm and node (Node.js 18 or newer).
set -euo pipefail
VERSION=2.1.0
dir=${1:?usage: fetch_foxglove_schemas.sh DIR}
command -v npm >/dev/null && command -v node >/dev/null || { echo "fetch_foxglove_schemas.sh needs npm and node" >&2; exit 1; }
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
(cd "$work" && npm pack --silent "@foxglove/schemas@$VERSION" >/dev/null && tar xzf foxglove-schemas-"$VERSION".tgz)
mkdir -p "$work/out"
node -e '
const schemas = require(process.argv[1]);
const fs = require("fs");
for (const [name, schema] of Object.entries(schemas)) {
  fs.writeFileSync(process.argv[2] + "/" + name + ".json", JSON.stringify(schema, null, 2) + "\n");
}' "$work/package/jsonschema.js" "$work/out"
echo "$VERSION" > "$work/out/VERSION"
rm -rf "$dir.tmp.$$" && mkdir -p "$(dirname "$dir")" && mv "$work/out" "$dir.tmp.$$"
rm -rf "$dir" && mv "$dir.tmp.$$" "$dir"
