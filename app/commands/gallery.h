#pragma once
// The QC gallery of a cohort output directory (docs/outputs.md, "QC gallery"): one static page
// OUTDIR/qc/index.html, no server, no external assets, listing the failures first and then
// every eye with its QC pictures, key parameters and QC flags, sortable by column.

#include <cstddef>
#include <filesystem>

namespace octshape::app {

struct GalleryResult {
    std::size_t eyes = 0;      // rows in the eye table (one per OUTDIR/eyes/*.json)
    std::size_t failures = 0;  // rows of OUTDIR/failures.csv
    std::size_t pictures = 0;  // QC pictures linked
};

// Reads OUTDIR/eyes/*.json (the eyes; their "cohort" object and OUTDIR/eyes.csv add subject,
// visit and group where present), OUTDIR/failures.csv (file,reason,exit_code; optional) and
// lists OUTDIR/qc/<eye_key>_*.png; writes OUTDIR/qc/index.html atomically. Throws InputError
// when OUTDIR or a JSON file cannot be read, OutputError when the page cannot be written.
// allow_empty = false (the `gallery` command): nothing to show (no eye, no failure) is an
// InputError (kMissing, exit 66) and no page is written.
GalleryResult write_qc_gallery(const std::filesystem::path& outdir, bool allow_empty = true);

}  // namespace octshape::app
