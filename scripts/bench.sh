#!/usr/bin/env bash
# Builds Release and runs every benchmark in bench/ (each prints its own tables).
set -euo pipefail
cd "$(dirname "$0")/.."
cmake --preset release >/dev/null
cmake --build --preset release -j 2 --target read_bench octshape_mesh_bench macula_bench octshape_shape_bench \
  macula_accuracy macula_rescan cohort_bench onh_bench onh_pipeline_bench onh_rescan \
  mesh_realisations macula_crb rofi_autostop
./build/release/bench/read_bench
./build/release/bench/octshape_mesh_bench
./build/release/bench/mesh_realisations
# The bunny of the organic family (npm package `bunny`; skipped by the bench if npm is absent).
./scripts/mesh_family.sh build/mesh_family || echo "(no bunny: npm/node unavailable)"
./build/release/bench/rofi_autostop --bunny build/mesh_family/bunny.obj
./build/release/bench/macula_bench
./build/release/bench/macula_accuracy
./build/release/bench/macula_crb
./build/release/bench/macula_rescan
./build/release/bench/octshape_shape_bench
./build/release/bench/cohort_bench
./build/release/bench/onh_bench
./build/release/bench/onh_pipeline_bench
./build/release/bench/onh_rescan
