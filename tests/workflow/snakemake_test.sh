#!/usr/bin/env bash
# ctest `workflow.snakemake_equals_cohort` (docs/cohort.md, "Snakemake and Slurm"): the Snakemake
# workflow on one machine (`cohort --list`, one `cohort-eye` job per input, `cohort-tables`) on a
# mixed folder (maculae, an ONH volume, a truncated export, a file of unknown content) writes the
# output folder of `octshape cohort` byte for byte; a second run has nothing to do.
# Usage: snakemake_test.sh OCTSHAPE SOURCE_DIR
set -euo pipefail
OCTSHAPE=$(readlink -f "$1")
SRC=$(readlink -f "$2")
command -v snakemake >/dev/null || { echo "snakemake missing: run scripts/install-deps.sh"; exit 1; }
T=$(mktemp -d)
trap 'rm -rf "$T"' EXIT
LOG_TAG=snakemake-test
source "$SRC/tests/workflow/common.sh"
make_mixed_folder "$T/in"
reference_cohort "$T/in" "$T/smk" "$T/cohort"
write_config "$T/in" "$T/smk" "$OCTSHAPE" >"$T/config.yaml"
snakemake -s "$SRC/workflow/Snakefile" --cores 2 --configfile "$T/config.yaml" \
  --directory "$T" --quiet >"$T/smk.log" 2>&1 || { cat "$T/smk.log"; exit 1; }
compare_outputs "$T/cohort" "$T/smk"
snakemake -s "$SRC/workflow/Snakefile" --cores 2 --configfile "$T/config.yaml" \
  --directory "$T" >"$T/smk2.log" 2>&1 || { cat "$T/smk2.log"; exit 1; }
grep -q "Nothing to be done" "$T/smk2.log" || { echo "the second run redid jobs"; cat "$T/smk2.log"; exit 1; }
log "second run: nothing to be done"
