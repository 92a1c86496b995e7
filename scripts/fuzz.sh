#!/usr/bin/env bash
# Bounded libFuzzer runs of the .vol reader and the Iowa surfaces XML reader (clang, ASan +
# UBSan): configures and builds the `fuzz` preset, writes seed corpora (write_vol; the tests'
# Iowa document fixture), fuzzes the .vol reader for SECONDS (default 60) and the Iowa reader
# for half as long.
# Exits non-zero if the fuzzer finds a crash, a sanitizer report, a leak or a timeout; the
# reproducer is left in build/fuzz/vol/artifacts/ (build/fuzz/iowa/artifacts/).
# Usage: scripts/fuzz.sh [SECONDS]
set -euo pipefail
cd "$(dirname "$0")/.."
secs=${1:-60}
jobs=$(nproc)
echo "== configure + build (fuzz)"
cmake --preset fuzz >/dev/null
cmake --build --preset fuzz -j "$jobs" --target vol_fuzz make_vol_seeds iowa_fuzz make_iowa_seeds
work=build/fuzz/vol
mkdir -p "$work/corpus" "$work/artifacts"
rm -rf "$work/seeds"
build/fuzz/tests/fuzz/make_vol_seeds "$work/seeds"
echo "== fuzz .vol reader for ${secs} s"
# max_len: the seeds are 1.5-4 kB; 16 kB leaves room to grow every structure.
build/fuzz/tests/fuzz/vol_fuzz -max_total_time="$secs" -max_len=16384 -rss_limit_mb=2048 \
  -timeout=10 -print_final_stats=1 -artifact_prefix="$work/artifacts/" \
  "$work/corpus" "$work/seeds"
work=build/fuzz/iowa
mkdir -p "$work/corpus" "$work/artifacts"
rm -rf "$work/seeds"
build/fuzz/tests/fuzz/make_iowa_seeds "$work/seeds"
echo "== fuzz Iowa surfaces reader for $((secs / 2)) s"
# max_len: the seeds are 1-3 kB of XML.
build/fuzz/tests/fuzz/iowa_fuzz -max_total_time="$((secs / 2))" -max_len=8192 -rss_limit_mb=2048 \
  -timeout=10 -print_final_stats=1 -artifact_prefix="$work/artifacts/" \
  "$work/corpus" "$work/seeds"
