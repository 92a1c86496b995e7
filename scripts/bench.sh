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
  case "$bench" in
    rofi_autostop) args=(--bunny build/mesh_family/bunny.obj) ;;
    *) args=() ;;
  esac
  "./build/release/bench/$bench" "${args[@]}"
done < build/release/bench/benches.txt
