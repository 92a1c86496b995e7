#!/usr/bin/env bash
# The long form of the hostile-input campaigns: every pair of the scan campaign's mutations on
# six phantom bases (macula OD/OS, ONH cupped/swollen/overhang, and the macula written as a
# Topcon .fda) through info, macula and onh (both ILM sources), then the mesh campaign; each run
# under a time limit. OCTSHAPE_CAMPAIGN_BASES=macula_fda (a comma list) runs only those bases.
# Prints the tables (inputs x commands: crashes, hangs, internal errors, impossible successes,
# clean errors, successes). Run it on a sanitizer build for the sanitizers' verdict too:
#   scripts/campaign.sh [PRESET]      (default: release; e.g. asan)
set -euo pipefail
cd "$(dirname "$0")/.."
preset=${1:-release}
cmake --preset "$preset" >/dev/null
cmake --build --preset "$preset" -j "$(nproc)" --target octshape octshape_cli_tests \
  octshape_mesh_tests
OCTSHAPE_CAMPAIGN_LONG=1 "build/$preset/tests/octshape_cli_tests" --gtest_filter='ScanCampaign.*'
OCTSHAPE_CAMPAIGN_LONG=1 "build/$preset/tests/octshape_mesh_tests" --gtest_filter='MeshCampaign.*'
