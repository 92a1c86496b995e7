#!/usr/bin/env bash
# Builds Release and runs every benchmark in bench/ (each prints its own tables). The list of
# benchmarks and their order are bench/CMakeLists.txt's (octshape_bench), written to benches.txt.
set -euo pipefail
cd "$(dirname "$0")/.."
cmake --preset release >/dev/null
cmake --build --preset release -j 2 --target octshape_benches
# The bunny of the organic mesh family (npm package `bunny`; skipped if npm/node are absent).
./scripts/mesh_family.sh build/mesh_family || echo "(no bunny: npm/node unavailable)"
while read -r bench; do
  [ -n "$bench" ] || continue
  # One run per line of `runs` (its arguments; an empty line: the defaults). The re-scan
  # benches also run on radial scans (issue 20; full sizes: see each bench's usage line).
  case "$bench" in
    rofi_autostop) runs=("--bunny build/mesh_family/bunny.obj") ;;
    macula_rescan) runs=("" "--pattern radial --lines 12" "--pattern radial --lines 24") ;;
    onh_rescan) runs=("" "--pattern radial --lines 24" "--pattern radial --lines 24 --ilm device") ;;
    *) runs=("") ;;
  esac
  for run in "${runs[@]}"; do
    read -ra args <<< "$run"
    "./build/release/bench/$bench" "${args[@]}"
  done
done < build/release/bench/benches.txt
