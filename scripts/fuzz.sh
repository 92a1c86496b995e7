#!/usr/bin/env bash
# Bounded libFuzzer runs of the .vol reader, the Iowa surfaces XML reader and the Topcon
# .fda/.fds reader (clang, ASan + UBSan): configures and builds the `fuzz` preset, writes seed
# corpora (write_vol; the tests' Iowa document fixture; write_topcon, half of them with JPEG 2000
# frames coded by OpenJPEG) and fuzzes them for
# 2/3, 1/3 and 1/2 of SECONDS (default 60): 1.5 x SECONDS in all, as before the Topcon target.
# Exits non-zero if a fuzzer finds a crash, a sanitizer report, a leak or a timeout; the
# reproducer is left in build/fuzz/NAME/artifacts/ (NAME = vol, iowa, topcon).
# Usage: scripts/fuzz.sh [SECONDS]
set -euo pipefail
cd "$(dirname "$0")/.."
secs=${1:-60}
jobs=$(nproc)
echo "== configure + build (fuzz)"
cmake --preset fuzz >/dev/null
cmake --build --preset fuzz -j "$jobs" --target vol_fuzz make_vol_seeds iowa_fuzz make_iowa_seeds \
  topcon_fuzz make_topcon_seeds

# fuzz NAME WHAT SECONDS MAX_LEN: seeds from make_NAME_seeds, then NAME_fuzz on them.
fuzz() {
  local name=$1 what=$2 time=$3 max_len=$4
  local work=build/fuzz/$name
  mkdir -p "$work/corpus" "$work/artifacts"
  rm -rf "$work/seeds"
  "build/fuzz/tests/fuzz/make_${name}_seeds" "$work/seeds"
  echo "== fuzz $what for ${time} s"
  "build/fuzz/tests/fuzz/${name}_fuzz" -max_total_time="$time" -max_len="$max_len" \
    -rss_limit_mb=2048 -timeout=10 -print_final_stats=1 -artifact_prefix="$work/artifacts/" \
    "$work/corpus" "$work/seeds"
}

# max_len: the .vol seeds are 1.5-4 kB (16 kB leaves room to grow every structure); the Iowa
# seeds 1-3 kB of XML; the Topcon seeds 0.7-0.9 kB, 1.1-2.6 kB with their JPEG 2000 frames.
fuzz vol ".vol reader" "$((secs * 2 / 3))" 16384
fuzz iowa "Iowa surfaces reader" "$((secs / 3))" 8192
fuzz topcon "Topcon .fda reader" "$((secs / 2))" 8192
