#!/usr/bin/env bash
# Builds Release and runs every benchmark in bench/ (each prints its own tables). The list of
# benchmarks and their order are bench/CMakeLists.txt's (octshape_bench), written to benches.txt.
set -euo pipefail
cd "$(dirname "$0")/.."
cmake --preset release >/dev/null
cmake --build --preset release -j 2 --target octshape_benches
while read -r bench; do
  [ -n "$bench" ] && "./build/release/bench/$bench"
done < build/release/bench/benches.txt
