#pragma once
// The per-eye optic-nerve-head work shared by `octshape onh` and `octshape cohort` (one code
// path): read the export (with pixels for the level-set ILM and the QC pictures), hash it, build
// the ILM surface, run the ONH analysis, optionally write the QC pictures and meshes, and build
// the per-eye JSON object and CSV row (docs/outputs.md, docs/cohort.md).

#include <string>

#include "commands/eye_record.h"
#include "commands/segmentation.h"
#include "octshape/retina/onh.h"

namespace CLI {
class App;
}  // namespace CLI

namespace octshape::app {

struct OnhEyeOptions {
    retina::OnhParams params;
    std::string ilm = "levelset";  // ILM source: levelset | device
    std::string bmo_file;          // user BMO points (CSV); empty: automatic detection
    std::string qc_dir;            // empty: no QC pictures
    std::string qc_stem;           // QC/mesh file names DIR/STEM_*; empty: "eye" (never the input's name)
    bool record_paths = false;     // --record-paths: input and BMO file paths in the outputs
    std::string mesh_dir;          // empty: no meshes
    std::string mesh_format = "vtp";
    SegmentationOptions segmentation;  // --segmentation, --bm-surface
};

// Throws InputError (file), AnalysisError (not an ONH volume), OutputError (pictures, meshes).
// `facts` is the file's state taken before it is read.
[[nodiscard]] EyeResult analyse_onh_eye(const std::string& file,
                                        const FileFacts& facts,
                                        OnhEyeOptions options,
                                        const SubjectSource& subjects);

// The one list of the ONH analysis's effective options, under the command line's names, code
// defaults included (the BMO file by its SHA-256, never its path): the canonical text the
// fingerprint hashes, and, parsed (options_from_text), the per-eye JSON's "options" and the
// provenance's options.
[[nodiscard]] std::string onh_options_text(const OnhEyeOptions& options);

// Adds the ONH analysis options (--ilm, --bmo-points, ...) to a command, and --bmo (a file of
// one eye's BMO points) when `per_eye_files`.
void add_onh_analysis_options(CLI::App* cmd, OnhEyeOptions& options, bool per_eye_files = true);

}  // namespace octshape::app
