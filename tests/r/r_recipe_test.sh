#!/usr/bin/env bash
# End-to-end test of the statistics path (ctest "r_recipe_phantom_cohort", label slow):
# phantom cohort -> octshape cohort -> octshape stats --retest and the R recipe
# (docs/r/octshape_gee.R, real R with geepack and psych) -> assertions in
# tests/r/check_phantom_cohort.R (known effects found, nulls not, ICCs equal to 3 decimals).
# Usage: r_recipe_test.sh OCTSHAPE_EXE SOURCE_DIR
set -euo pipefail
exe=$1
src=$2
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

# 40 subjects (20 per group), 12 of them with both eyes re-scanned: 104 small scans.
# The seed is fixed; docs/phantoms.md argues why effects and nulls hold for any seed.
"$exe" -q phantom cohort -o "$work/ph" --subjects 40 --retest-subjects 12 --seed 1
"$exe" -q cohort "$work/ph/scans" -o "$work/out" --jobs 2 \
    --subjects "$work/ph/subjects.csv" --groups "$work/ph/groups.csv"
"$exe" -q stats "$work/out/eyes.csv" --retest -o "$work/table.csv" \
    --retest-output "$work/icc_octshape.csv"
Rscript "$src/docs/r/octshape_gee.R" "$work/out/eyes.csv" --ref control \
    --out "$work/gee.csv" --retest --icc-out "$work/icc_r.csv"
Rscript "$src/tests/r/check_phantom_cohort.R" "$work/gee.csv" "$work/icc_r.csv" \
    "$work/icc_octshape.csv" "$work/ph/expected.csv"
