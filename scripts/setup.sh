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
echo "== main job on a bundled sample scan"
./build/release/app/octshape info sample_scans/macula_bezier_od.vol
