#!/usr/bin/env bash
# ctest `workflow.snakemake_equals_cohort`: the Snakemake workflow (one `octshape macula` per
# scan + `octshape merge`) and `octshape cohort` give byte-identical eyes.csv on phantoms.
# Usage: snakemake_test.sh OCTSHAPE SOURCE_DIR
set -euo pipefail
OCTSHAPE=$1
SRC=$2
command -v snakemake >/dev/null || { echo "snakemake missing: run scripts/install-deps.sh"; exit 1; }
T=$(mktemp -d)
trap 'rm -rf "$T"' EXIT
mkdir -p "$T/in/a" "$T/in/b"
# Four small macula volumes (no pixels) of both families and eyes, one in a subfolder.
"$OCTSHAPE" -q phantom macula --family bezier --eye OD --bscans 25 --ascans 128 --depth 96 \
  --scale-z 0.0154868 --no-pixels --seed 1 -o "$T/in/a/s1_od.vol"
"$OCTSHAPE" -q phantom macula --family scheibe --eye OS --bscans 25 --ascans 128 --depth 96 \
  --scale-z 0.0154868 --no-pixels --noise-um 3 --seed 2 -o "$T/in/a/s1_os.vol"
"$OCTSHAPE" -q phantom macula --family scheibe --eye OD --bscans 25 --ascans 128 --depth 96 \
  --scale-z 0.0154868 --no-pixels --missing 0.02 --seed 3 -o "$T/in/b/s2_od.vol"
cp "$SRC/sample_scans/macula_line_od.vol" "$T/in/b/line_od.vol"
rm -f "$T"/in/*/*.truth.json
printf 'snakemake-test-key\n' > "$T/key"
printf 'file,group\ns1_od.vol,control\ns1_os.vol,control\ns2_od.vol,case\n' > "$T/groups.csv"

"$OCTSHAPE" -q cohort "$T/in" -o "$T/cohort" --jobs 2 --subject-key-file "$T/key" \
  --groups "$T/groups.csv" --tau-um 4

cat > "$T/config.yaml" <<YAML
inputs: ["$T/in"]
out: "$T/smk"
octshape: "$OCTSHAPE"
subject_key_file: "$T/key"
groups: "$T/groups.csv"
macula_args: "--tau-um 4"
YAML
snakemake -s "$SRC/workflow/Snakefile" --cores 2 --configfile "$T/config.yaml" \
  --directory "$T" --quiet

test "$(wc -l < "$T/smk/eyes.csv")" -eq 5 || { echo "expected 4 eyes"; cat "$T/smk/eyes.csv"; exit 1; }
grep -q ',control,' "$T/smk/eyes.csv"
cmp "$T/cohort/eyes.csv" "$T/smk/eyes.csv"
echo "snakemake eyes.csv == cohort eyes.csv ($(wc -l < "$T/smk/eyes.csv") lines)"
