#!/usr/bin/env bash
# Writes the Stanford bunny (npm package `bunny` 1.0.1, public domain: Stanford 3D Scanning
# Repository, packed by M. Lysenko; 1,839 vertices, 3,674 triangles) as OBJ for
# bench/rofi_autostop, which subdivides it and adds the noise itself. Needs npm and node.
# Usage: scripts/mesh_family.sh [OUT_DIR=build/mesh_family]
set -euo pipefail
cd "$(dirname "$0")/.."
out="${1:-build/mesh_family}"
mkdir -p "$out"
if [[ -s "$out/bunny.obj" ]]; then exit 0; fi
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
(cd "$tmp" && npm pack --silent bunny@1.0.1 >/dev/null && tar xzf bunny-1.0.1.tgz)
node -e '
const b = require(process.argv[1]);
const lines = b.positions.map(p => "v " + p.join(" "));
for (const c of b.cells) lines.push("f " + c.map(i => i + 1).join(" "));
require("fs").writeFileSync(process.argv[2], lines.join("\n") + "\n");
' "$tmp/package" "$tmp/bunny.obj"
mv "$tmp/bunny.obj" "$out/bunny.obj"
