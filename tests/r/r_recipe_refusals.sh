#!/usr/bin/env bash
# What the R recipe (docs/r/octshape_gee.R) cannot do it refuses in one line with a non-zero
# exit, and it never pools two analyses (ctest "r_recipe_refusals"). Every case stops before
# the recipe loads geepack and psych, so the test takes Rscript's start-up only (~0.3 s each).
# Usage: r_recipe_refusals.sh SOURCE_DIR. Skips (77) without Rscript.
set -uo pipefail
src=$1
command -v Rscript >/dev/null || { echo "Rscript not installed: skipped"; exit 77; }
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
recipe="$src/docs/r/octshape_gee.R"
fail=0

# expect NAME STATUS STDERR_REGEX ARGS...: exit STATUS, and the last stderr line matches.
expect() {
    local name=$1 status=$2 pattern=$3
    shift 3
    Rscript "$recipe" "$@" >"$work/out" 2>"$work/err"
    local got=$?
    local last
    last=$(tail -n 1 "$work/err")
    if [ "$got" -ne "$status" ] || ! grep -Eq -- "$pattern" <<<"$last"; then
        echo "FAIL $name: exit $got (expected $status); stderr:"; cat "$work/err"
        fail=1
    fi
    # A refusal is one line.
    if [ "$status" -ne 0 ] && [ "$(grep -c . "$work/err")" -ne 1 ] && [ "$name" != pooled ]; then
        echo "FAIL $name: more than one line on stderr:"; cat "$work/err"
        fail=1
    fi
}

header='subject_id,eye,visit_date,scan_type,eye_key,sha256,group,analysis,cft_mm,scan_pattern,num_bscans'
# A cohort without --groups: group all NA.
{
    echo "$header"
    echo "S1,OD,2024-01-01,macula,k1,NA,NA,volume,0.25,volume,49"
    echo "S2,OD,2024-01-01,macula,k2,NA,NA,volume,0.24,volume,49"
} >"$work/nogroups.csv"
expect no-groups 65 "^octshape_gee.R: error: .*nogroups.csv: the GEE needs two groups" \
    "$work/nogroups.csv"
expect unknown-option 64 "^octshape_gee.R: error: unknown option --frobnicate" \
    "$work/nogroups.csv" --frobnicate
expect bad-analysis 64 "^octshape_gee.R: error: --analysis must be volume, radial or line" \
    "$work/nogroups.csv" --analysis radial2
expect missing-file 65 "^octshape_gee.R: error: .*absent.csv: no such file" "$work/absent.csv"
expect no-such-rows 65 "no row of analysis 'radial'" "$work/nogroups.csv" --analysis radial
printf 'eye_key,reason,exit_code\nk1,bad,65\n' >"$work/failures.csv"
expect not-a-table 65 "failures.csv: no column 'subject_id'" "$work/failures.csv"
# Two analyses in one table: the line rows are left out and said so (one line), then the
# groupless table is refused: the recipe never reaches a pooled fit.
{
    echo "$header"
    echo "S1,OD,2024-01-01,macula,k1,NA,NA,volume,0.25,volume,49"
    echo "S2,OD,2024-01-01,macula,k2,NA,NA,line,0.24,line,1"
    echo "S3,OD,2024-01-01,macula,k3,NA,NA,line,0.23,line,1"
} >"$work/mixed.csv"
expect pooled 65 "the GEE needs two groups" "$work/mixed.csv"
if ! grep -q "2 rows of analysis 'line' left out (one analysis a table: give --analysis line)" \
        "$work/err"; then
    echo "FAIL pooled: the left-out rows are not named:"; cat "$work/err"
    fail=1
fi
exit $fail
