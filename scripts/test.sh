#!/usr/bin/env bash
# Quick start, command 2: build and run the whole test suite twice, in Release and under
# AddressSanitizer + UndefinedBehaviorSanitizer. Exits non-zero on any failure.
set -euo pipefail
cd "$(dirname "$0")/.."
jobs=$(nproc)
for preset in release asan; do
  echo "== configure + build ($preset)"
  cmake --preset "$preset" >/dev/null
  cmake --build --preset "$preset" -j "$jobs"
  echo "== tests ($preset)"
  ctest --preset "$preset" -j "$jobs"
done
./scripts/fuzz.sh 60
