#!/usr/bin/env bash
# Builds Release and runs every benchmark in bench/ (each prints its own tables). The list of
# benchmarks and their order are bench/CMakeLists.txt's (octshape_bench), written to benches.txt.
set -euo pipefail
cd "$(dirname "$0")/.."
cmake --preset release -DOCTSHAPE_BUILD_BENCH=ON >/dev/null
cmake --build --preset release -j 2 --target octshape_benches
mkdir -p build/bench
# The bunny of the organic mesh family (npm package `bunny`; skipped if npm/node are absent).
./scripts/mesh_family.sh build/mesh_family || echo "(no bunny: npm/node unavailable)"
while read -r bench; do
  [ -n "$bench" ] || continue
  # One run per line of `runs` (its arguments; an empty line: the defaults). The re-scan
  # benches also run on radial scans (issue 20; full sizes: see each bench's usage line).
  case "$bench" in
    # rofi_autostop also writes its curves and trace for bench/rofi_oracle_analysis.py (below).
    rofi_autostop) runs=("--bunny build/mesh_family/bunny.obj --curves build/bench/rofi_curves.tsv --trace build/bench/rofi_trace.tsv") ;;
    macula_rescan) runs=("" "--pattern radial --lines 12" "--pattern radial --lines 24") ;;
    onh_rescan) runs=("" "--pattern radial --lines 24" "--pattern radial --lines 24 --ilm device") ;;
    # Lateral jitter of volumes (docs/algorithms/onh.md "Lateral registration"): the table, and
    # the same with the jitter in whole A-scans (no A-scans blended by the phantom).
    onh_motion) runs=("" "--pattern volume --motion 0,30 --jitter 0,10,30 --oracle"
                      "--pattern volume --motion 0 --jitter 10,30 --oracle --whole-jitter") ;;
    # The macula's lateral registration (docs/algorithms/cube.md "Lateral registration
    # (measured)"): noise-free and noisy whole-A-scan jitter; the real cubes: --file F.
    macula_motion) runs=("" "--whole-jitter --seeds 3 --noise 1,2 --motion 0 --jitter 30") ;;
    *) runs=("") ;;
  esac
  for run in "${runs[@]}"; do
    read -ra args <<< "$run"
    "./build/release/bench/$bench" "${args[@]}"
  done
  if [ "$bench" = rofi_autostop ]; then
    # Where the automatic rule's distance to the oracle comes from (docs/algorithms/rofi.md,
    # "Why the target is out of reach"; the whole family: rofi_autostop --full, see its usage).
    python3 bench/rofi_oracle_analysis.py build/bench/rofi_curves.tsv build/bench/rofi_trace.tsv
  fi
done < build/release/bench/benches.txt
