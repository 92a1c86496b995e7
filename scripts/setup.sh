#!/usr/bin/env bash
# Quick start, command 1: install every dependency (Debian 12 packages), build in Release,
# and run the main job on a bundled sample scan.
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/install-deps.sh
cmake --preset release >/dev/null
cmake --build --preset release
echo "== octshape built: build/release/app/octshape"
./build/release/app/octshape --version
echo "== main job: the CuBe fovea analysis of a bundled sample scan"
out=build/sample
mkdir -p "$out"
./build/release/app/octshape macula sample_scans/macula_bezier_od.vol \
    -o "$out/macula_bezier_od.json" --csv "$out/macula_bezier_od.csv" --qc "$out"
# The CSV row, one "column = value" per line (the JSON holds per-half-line data besides).
awk -F, 'NR == 1 { for (i = 1; i <= NF; i++) name[i] = $i; next }
         { for (i = 1; i <= NF; i++) printf "  %-36s %s\n", name[i], $i }' \
    "$out/macula_bezier_od.csv"
echo "== written: $out/macula_bezier_od.json, .csv and QC pictures (*.png)"
