#pragma once
// The tables of a cohort output folder (docs/cohort.md, "Output folder"): eyes.csv (maculae),
// eyes_onh.csv (optic nerve heads, when there are any), failures.csv and, with --qc, the QC
// gallery. `octshape cohort` writes them at the end of its run and `octshape cohort-tables`
// (the Snakemake workflow's last job) with the same code, from the same records.

#include <cstddef>
#include <filesystem>
#include <string>
#include <vector>

#include "commands/cohort_eye.h"
#include "commands/eye_record.h"

namespace octshape::app {

// OUTDIR/failures.csv (`with_paths` false: eye_key,reason,exit_code, reasons without the
// input's name) or OUTDIR/private/failures.csv (eye_key,file,reason,exit_code): one row per
// failed item and per skipped file, sorted by eye key.
[[nodiscard]] std::string failures_csv(const std::vector<Item>& items,
                                       const std::vector<Skipped>& skipped, bool with_paths);

// OUTDIR/private/inputs.csv: eye_key,file,sha256,result (eye | failure) of the inputs, by eye
// key: the only map from the keys of the shared tables back to the files.
[[nodiscard]] std::string inputs_csv(const std::vector<Item>& items,
                                     const std::vector<Skipped>& skipped);

struct CohortTables {
    std::size_t eyes = 0;    // rows of eyes.csv and eyes_onh.csv
    std::size_t failed = 0;  // rows of failures.csv
};

// OUTDIR/provenance.json: the provenance block (commands/provenance.h, without run times, so
// that a re-run writes the same folder byte for byte) of the tables: command "cohort tables",
// every eye in eyes.csv/eyes_onh.csv by its input's SHA-256 and eye key, and as options the
// groups file by its SHA-256, `qc`, and the fingerprints and effective options of the records
// the tables were made from.
[[nodiscard]] std::string tables_provenance(const std::vector<Item>& items,
                                            const GroupMap& groups, bool qc);

// Writes OUTDIR/eyes.csv, OUTDIR/eyes_onh.csv (when an item is an ONH eye), OUTDIR/failures.csv,
// OUTDIR/provenance.json, OUTDIR/private/failures.csv and OUTDIR/private/inputs.csv (each atomically and durably) from
// the items' records, and with `qc` the gallery OUTDIR/qc/index.html. The records must be on
// disk (the gallery reads them). A groups file matching no eye is refused before any table is
// written.
CohortTables write_cohort_tables(const std::filesystem::path& out, const std::vector<Item>& items,
                                 const std::vector<Skipped>& skipped, GroupMap groups, bool qc);

}  // namespace octshape::app
