# Shared by the workflow tests (snakemake_test.sh, slurm_test.sh): sourced, with OCTSHAPE, SRC
# and T (the test's temporary folder) set.

t_begin=$(date +%s.%N)
sub() { awk -v a="$1" -v b="$2" 'BEGIN { printf "%.1f", a - b }'; }  # a - b, to 0.1
log() { printf '[%s %6s s] %s\n' "${LOG_TAG:-workflow-test}" "$(sub "$(date +%s.%N)" "$t_begin")" "$*"; }

# The mixed folder: the three sample macula scans, a small ONH phantom, a truncated export, a
# .vol of unknown content and a note (ignored); the key and the groups.
make_mixed_folder() {  # make_mixed_folder IN
  local in=$1
  mkdir -p "$in/macula" "$in/onh" "$in/bad"
  cp "$SRC"/sample_scans/*.vol "$in/macula/"
  "$OCTSHAPE" -q phantom onh --bscans 25 --ascans 96 --seed 7 -o "$in/onh/disc_od.vol"
  rm -f "$in"/*/*.truth.json
  head -c 5000 "$SRC/sample_scans/macula_bezier_od.vol" >"$in/bad/truncated.vol"
  printf 'not an export\n' >"$in/bad/unknown.vol"
  printf 'notes\n' >"$in/bad/notes.txt"
  printf 'workflow-test-key\n' >"$T/key"
  printf 'file,group\nmacula_bezier_od.vol,control\ndisc_od.vol,case\n' >"$T/groups.csv"
}

# The options of the reference `octshape cohort` run, and the workflow config that means them.
COHORT_OPTS=(--subject-key-file "$T/key" --groups "$T/groups.csv" --qc --eye-timeout-s 600
             --tau-um 4)
write_config() {  # write_config IN OUT OCTSHAPE > config.yaml
  cat <<YAML
inputs: ["$1"]
out: "$2"
octshape: "$3"
subject_key_file: "$T/key"
groups: "$T/groups.csv"
qc: true
eye_timeout_s: 600
cohort_args: "--tau-um 4"
YAML
}

# `octshape cohort` on IN into OUT, then moved to REF (so that the workflow can write the same
# OUT: the gallery names its folder), its eye key left in OUT/private/: it must finish with
# exit 1 (the bad files are recorded).
reference_cohort() {  # reference_cohort IN OUT REF
  local rc=0
  "$OCTSHAPE" -q cohort "$1" -o "$2" --jobs 2 "${COHORT_OPTS[@]}" || rc=$?
  [ $rc -eq 1 ] || { echo "cohort: expected exit 1 (failures recorded), got $rc"; exit 1; }
  mv "$2" "$3"
  # The eye keys are HMACs under OUT/private/eye.key: the workflow's OUT starts with the
  # reference's key (as a moved folder would have it), so that keys and file names compare.
  mkdir -p -m 700 "$2/private"
  cp -p "$3/private/eye.key" "$2/private/eye.key"
}

# Every table, record, QC picture and the gallery of two output folders, byte for byte; in the
# per-eye JSON the one value that differs between two analyses of the same file, the ONH
# record's "analysis_seconds" (a timing), is masked.
# The provenance's run time ("utc") and seconds per stage ("seconds": {...}, over several lines)
# differ in any two runs too and are masked.
untimed() {
  sed -E 's/"analysis_seconds": [-+.0-9eE]+/"analysis_seconds": T/; s/"utc": "[^"]*"/"utc": T/' "$1" |
    sed -E '/"seconds": \{/,/\}/d'
}
compare_outputs() {  # compare_outputs A B
  local a=$1 b=$2 n=0 d f
  for f in eyes.csv eyes_onh.csv failures.csv private/inputs.csv private/failures.csv; do
    cmp "$a/$f" "$b/$f" || { echo "$f differs"; diff "$a/$f" "$b/$f" | head; exit 1; }
  done
  # private/ holds the same files (no subject.key: the tests give a key) with the same modes.
  diff <(cd "$a/private" && ls -A) <(cd "$b/private" && ls -A) || { echo "private/ differs"; exit 1; }
  [ "$(stat -c %a "$b/private")" = 700 ] || { echo "private/ is not mode 700"; exit 1; }
  grep -q ',control,' "$b/eyes.csv" || { echo "groups missing"; exit 1; }
  # The failed inputs: by path in private/failures.csv only, by eye key in failures.csv.
  for f in truncated.vol unknown.vol; do
    grep -q "$f" "$b/private/failures.csv" || { echo "$f not in private/failures.csv"; exit 1; }
    ! grep -q "$f" "$b/failures.csv" || { echo "$f named in failures.csv"; exit 1; }
  done
  for d in eyes failures qc; do
    diff <(cd "$a/$d" && ls -A) <(cd "$b/$d" && ls -A) || { echo "$d/ holds other files"; exit 1; }
    for f in "$a/$d"/*; do
      if [[ $f == *.json ]]; then
        cmp <(untimed "$f") <(untimed "$b/$d/${f##*/}") || { echo "$d/${f##*/} differs"; exit 1; }
      else
        cmp "$f" "$b/$d/${f##*/}" || { echo "$d/${f##*/} differs"; exit 1; }
      fi
      n=$((n + 1))
    done
  done
  log "identical to octshape cohort: eyes.csv ($(($(wc -l <"$a/eyes.csv") - 1)) eyes)," \
      "eyes_onh.csv ($(($(wc -l <"$a/eyes_onh.csv") - 1))), failures.csv" \
      "($(($(wc -l <"$a/failures.csv") - 1)) rows), $n per-eye JSON/failure/QC/gallery files"
}
