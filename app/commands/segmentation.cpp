#include "commands/segmentation.h"

#include "octshape/error.h"
#include "octshape/io/iowa_surfaces.h"
#include "octshape/io/scan_reader.h"
#include "octshape/io/sha256.h"

namespace octshape::app {

void add_segmentation_options(CLI::App* cmd, SegmentationOptions& o, bool per_eye_files) {
    if (per_eye_files) {
        cmd->add_option("--segmentation", o.file,
                        "Use the layer boundaries of this Iowa surfaces XML (OCTExplorer / "
                        "OCTLayerSeg *_Surfaces_Iowa.xml) instead of the export's own; it must be "
                        "a segmentation of this scan (same sizes and eye)");
    }
    cmd->add_option("--bm-surface", o.bm_surface,
                    "Surface used as BM for an Iowa surfaces XML or a Topcon .fda/.fds: ob_rpe "
                    "(outer boundary of the RPE: Iowa label 150, where Heidelberg's BM line runs; "
                    "Topcon RETINA_4) or ib_rpe (inner boundary: Iowa label 140, Topcon RETINA_3)")
        ->check(CLI::IsMember({"ob_rpe", "ib_rpe"}))
        ->capture_default_str();
}

io::IowaBm segmentation_bm(const SegmentationOptions& o) { return io::parse_iowa_bm(o.bm_surface); }

nlohmann::ordered_json apply_segmentation_file(io::Scan& scan,
                                               const SegmentationOptions& o,
                                               bool record_paths) {
    if (o.file.empty()) return nullptr;
    io::ReadOptions read;
    read.iowa_bm = segmentation_bm(o);
    const io::HashedScan seg = io::read_scan_hashed(o.file, read);
    if (seg.scan.meta.format != io::SourceFormat::kIowaSurfaces) {
        throw UsageError(o.file + ": --segmentation needs an Iowa surfaces XML, this is a " +
                         std::string(io::to_string(seg.scan.meta.format)) + " file");
    }
    io::apply_segmentation(scan, seg.scan);
    nlohmann::ordered_json j = {{"sha256", seg.sha256},
                                {"source", seg.scan.meta.version},
                                {"bm_surface", o.bm_surface}};
    if (record_paths) j["path"] = o.file;
    return j;
}

void add_segmentation_input(nlohmann::ordered_json& provenance_inputs,
                            const nlohmann::ordered_json& segmentation) {
    if (segmentation.is_null()) return;
    nlohmann::ordered_json in = {{"sha256", segmentation["sha256"]}, {"role", "segmentation"}};
    if (segmentation.contains("path")) in["path"] = segmentation["path"];
    provenance_inputs.push_back(in);
}

std::string file_fingerprint(const std::string& path) {
    try {
        return "sha256:" + io::sha256_file(path);
    } catch (const Error&) {
        return "unreadable";  // the analysis reports it with the file's name
    }
}

std::string segmentation_options_text(const SegmentationOptions& o) {
    return "bm_surface=" + o.bm_surface +
           " segmentation=" + (o.file.empty() ? std::string("none") : file_fingerprint(o.file));
}

}  // namespace octshape::app
