#pragma once
// The per-eye macula work shared by `octshape macula` and `octshape cohort` (one code path):
// read the export, hash it, run the CuBe analysis, optionally draw the QC pictures, and build
// the per-eye JSON object and CSV row (docs/outputs.md, docs/cohort.md).

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "commands/eye_record.h"
#include "commands/segmentation.h"
#include "octshape/io/scan_reader.h"
#include "octshape/retina/cube.h"
#include "octshape/retina/etdrs.h"

namespace octshape::app {

struct MaculaEyeOptions {
    retina::CubeParams params;  // tau_mm and rim_point are set from the user's by effective_params
    // The user options behind params.tau_mm and params.rim_point, their defaults CubeParams's.
    double tau_um = retina::CubeParams{}.tau_mm * 1e3;  // pit-flat threshold above CFT (um)
    std::string rim_point{retina::to_string(retina::CubeParams{}.rim_point)};  // crest | maximum
    std::string qc_dir;         // empty: no QC pictures; else the scan must be read with pixels
    std::string qc_stem;        // QC file names DIR/STEM_*.png; empty: "eye" (never the input's name)
    bool record_paths = false;  // --record-paths: the input's path in the JSON and CSV (identifying)
    // Refuse (AnalysisError) a volume that retina::classify_scan calls an ONH scan: a CuBe fit
    // of an optic disc gives numbers, but meaningless ones. The cohort classifies first.
    bool check_scan_type = true;
    SegmentationOptions segmentation;  // --segmentation, --bm-surface
    retina::EtdrsParams etdrs;
    std::string etdrs_layers = "ILM,BM";  // --etdrs-layers UPPER,LOWER
};

// The per-eye object (with its "cohort" record) and the `macula --csv` columns.
using MaculaEye = EyeResult;

// Throws InputError (file), AnalysisError (scan not analysable), OutputError (QC pictures).
// `record` carries the subject settings and the option signature; its file facts are filled
// here from the file itself.
[[nodiscard]] MaculaEye analyse_macula_eye(const std::string& file,
                                           MaculaEyeOptions options,
                                           const SubjectSource& subjects);
// The same on a scan already read from `file` with its hash (io::read_scan_hashed; headers and
// segmentation, and the pixels when QC pictures are asked for), `facts` being the file's state taken *before* it was read
// (a file changed meanwhile is then redone by the next cohort run).
[[nodiscard]] MaculaEye analyse_macula_eye(const std::string& file,
                                           const FileFacts& facts,
                                           const io::HashedScan& input,
                                           MaculaEyeOptions options,
                                           const SubjectSource& subjects);

// The analysis's parameters with the user's tau_um and rim_point applied (validated: UsageError).
[[nodiscard]] retina::CubeParams effective_params(const MaculaEyeOptions& options);

// The one list of the analysis's effective options, under the command line's names
// (--half-lines: half_lines, --tau-um: tau_um, ...), code defaults included: the canonical text
// "macula half_lines=24 radius_mm=2 ..." that the fingerprint hashes (the resume signature).
// The per-eye JSON's "options" and the provenance's options are this text parsed
// (macula_options, options_from_text), so the three never disagree.
[[nodiscard]] std::string macula_options_text(const MaculaEyeOptions& options);
// The JSON "options" of a macula result: macula_options_text parsed.
[[nodiscard]] nlohmann::ordered_json macula_options(const MaculaEyeOptions& options);

// Adds the CuBe options (--half-lines, --radius-mm, ...) to a command.
// `lateral_flag` false: no --no-lateral-registration of its own (cohort: one flag for both
// analyses, add_cohort_options).
void add_macula_analysis_options(CLI::App* cmd, MaculaEyeOptions& options,
                                 bool lateral_flag = true);

}  // namespace octshape::app
