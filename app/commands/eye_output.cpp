#include "commands/eye_output.h"

#include <iostream>

#include "octshape/io/atomic_file.h"
#include "octshape/retina/report_util.h"
#include "octshape/retina/scan_summary.h"
#include "octshape/version.h"

namespace octshape::app {

nlohmann::ordered_json eye_json_preamble(const std::string& command,
                                         const std::string& file,
                                         const std::string& sha256,
                                         const io::Scan& scan) {
    nlohmann::ordered_json j;
    j["octshape_version"] = kVersion;
    j["command"] = command;
    j["input"] = {{"path", file}, {"sha256", sha256}};
    j["scan"] = retina::scan_summary(scan);  // without identifiers
    return j;
}

std::vector<std::string> eye_csv_header() {
    return {"file", "sha256", "eye", "scan_pattern", "num_bscans"};
}

std::vector<std::string> eye_csv_values(const std::string& file,
                                        const std::string& sha256,
                                        const io::Scan& scan) {
    return {file, sha256, std::string(io::to_string(scan.meta.laterality)),
            std::string(io::to_string(scan.meta.pattern)), std::to_string(scan.num_bscans())};
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
