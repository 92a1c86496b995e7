#pragma once
// `--segmentation FILE` and `--bm-surface` of the per-eye commands (macula, onh): a segmentation
// made elsewhere (an Iowa surfaces XML, io/iowa_surfaces.h) laid over the export, and which of
// its surfaces plays Bruch's membrane (also for an Iowa file analysed alone).

#include <nlohmann/json.hpp>
#include <string>

#include "octshape/io/scan.h"

namespace CLI {
class App;
}  // namespace CLI

namespace octshape::app {

struct SegmentationOptions {
    std::string file;                   // empty: the export's own segmentation
    std::string bm_surface = "ob_rpe";  // ob_rpe | ib_rpe (Iowa labels 150 | 140)
};

// Adds --segmentation (when `per_eye_files`) and --bm-surface to a command.
void add_segmentation_options(CLI::App* cmd, SegmentationOptions& o, bool per_eye_files = true);

// The read options for the input: which Iowa surface is BM when the input is one.
[[nodiscard]] io::IowaBm segmentation_bm(const SegmentationOptions& o);

// Lays o.file's segmentation over `scan` (io::apply_segmentation; the file is read and hashed
// as an input is) and returns its record for the JSON's "input" ({"sha256", "source",
// "bm_surface"}, and "path" with `record_paths`); null when no file is given. Throws
// InputError for the file, UsageError when it is not a segmentation of this scan.
[[nodiscard]] nlohmann::ordered_json apply_segmentation_file(io::Scan& scan,
                                                             const SegmentationOptions& o,
                                                             bool record_paths);

// The segmentation record (apply_segmentation_file's) as a provenance input: {"sha256",
// "role": "segmentation"} (+ "path"); nothing for null.
void add_segmentation_input(nlohmann::ordered_json& provenance_inputs,
                            const nlohmann::ordered_json& segmentation);

// "sha256:HEX" of a file an analysis reads besides its input (a segmentation, BMO points), for
// the fingerprint's text (never the path); "unreadable" when it cannot be read (the analysis
// then reports it, naming the file).
[[nodiscard]] std::string file_fingerprint(const std::string& path);

// "bm_surface=ob_rpe segmentation=none|sha256:HEX": the fingerprint's part (never the path).
[[nodiscard]] std::string segmentation_options_text(const SegmentationOptions& o);

}  // namespace octshape::app
