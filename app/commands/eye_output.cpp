#include "commands/eye_output.h"

#include "commands/eye_record.h"
#include "commands/provenance.h"

#include <filesystem>
#include <iostream>

#include "octshape/io/atomic_file.h"
#include "octshape/error.h"
#include "octshape/retina/record.h"
#include "octshape/retina/report_util.h"
#include "octshape/retina/scan_summary.h"

namespace octshape::app {

nlohmann::ordered_json eye_json_preamble(const std::string& command,
                                         const std::string& file,
                                         const std::string& sha256,
                                         const io::Scan& scan,
                                         bool record_paths) {
    nlohmann::ordered_json j;
    j["command"] = command;
    j["provenance"] = nlohmann::ordered_json::object();
    j["input"] = {{"sha256", sha256}};
    if (record_paths) j["input"]["path"] = file;
    j["scan"] = retina::scan_summary(scan);  // without identifiers
    if (!record_paths) j["scan"].erase("file");
    return j;
}

nlohmann::ordered_json eye_provenance_options(const std::string& options_text,
                                              const std::string& qc_dir, bool record_paths) {
    nlohmann::ordered_json o = options_from_text(options_text);
    o["qc_pictures"] = !qc_dir.empty();
    o["record_paths"] = record_paths;
    return o;
}

std::vector<std::string> eye_csv_header(bool record_paths) {
    using retina::record::Name;
    std::vector<std::string> h = retina::record::names(
        {Name::kEyeKey, Name::kSha256, Name::kEye, Name::kScanPattern, Name::kNumBscans});
    if (record_paths) h.insert(h.begin(), retina::record::name(Name::kFile));
    return h;
}

std::vector<std::string> eye_csv_values(const std::string& file,
                                        const std::string& sha256,
                                        const io::Scan& scan,
                                        bool record_paths) {
    std::vector<std::string> v{eye_key(absolute_path(file)), sha256,
                               std::string(io::to_string(scan.meta.laterality)),
                               std::string(io::to_string(scan.meta.pattern)),
                               std::to_string(scan.num_bscans())};
    if (record_paths) v.insert(v.begin(), file);
    return v;
}

std::string naming_file(const std::string& file, const std::string& message) {
    if (message.rfind(file + ":", 0) == 0) return message;
    return file + ": " + message;
}

std::string output_stem(const std::string& json_out, const std::string& csv_out) {
    for (const std::string& p : {json_out, csv_out}) {
        if (p.empty() || p == "-") continue;
        const std::string stem = std::filesystem::path(p).stem().string();
        if (!stem.empty()) return stem;
    }
    return "eye";
}

void check_eye_outputs(const std::string& json_out, const std::string& csv_out,
                       const std::string& qc_dir, const std::string& mesh_dir) {
    if (json_out == "-" && csv_out == "-") {
        throw UsageError("-o - and --csv - would both write to stdout: choose one");
    }
    for (const std::string& p : {json_out, csv_out}) {
        if (!p.empty()) io::check_output_location(p);
    }
    for (const std::string& d : {qc_dir, mesh_dir}) {
        if (!d.empty()) io::check_output_directory(d);
    }
}

void publish_eye_outputs(const std::string& json_out,
                         const std::string& csv_out,
                         const nlohmann::ordered_json& j,
                         const std::vector<std::string>& csv_header,
                         const std::vector<std::string>& csv_values) {
    // The CSV first and the JSON last: neither appears half-written (atomic rename).
    if (!csv_out.empty()) {
        io::write_text_atomically(csv_out,
                                  retina::csv_line(csv_header) + retina::csv_line(csv_values));
    }
    if (!json_out.empty()) io::write_text_atomically(json_out, j.dump(2) + "\n");
    if (json_out.empty() && csv_out.empty()) std::cout << j.dump(2) << '\n';
}

}  // namespace octshape::app
