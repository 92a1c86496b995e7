// The tables of a cohort output folder: eyes.csv, eyes_onh.csv, failures.csv, the QC gallery.

#include "commands/cohort_tables.h"

#include <spdlog/spdlog.h>

#include <algorithm>

#include "commands/gallery.h"
#include "octshape/io/atomic_file.h"
#include "octshape/retina/report_util.h"

namespace octshape::app {

namespace fs = std::filesystem;

std::string failures_csv(const std::vector<Item>& items, const std::vector<Skipped>& skipped) {
    std::vector<std::vector<std::string>> rows;
    for (const auto& it : items) {
        if (!it.failed) continue;
        rows.push_back({it.path, it.failure.value("reason", std::string()),
                        std::to_string(it.failure.value("exit_code", 0))});
    }
    for (const auto& s : skipped) rows.push_back({s.path, s.reason, std::to_string(s.exit_code)});
    std::sort(rows.begin(), rows.end());
    std::string s = retina::csv_line({"file", "reason", "exit_code"});
    for (const auto& r : rows) s += retina::csv_line(r);
    return s;
}

CohortTables write_cohort_tables(const fs::path& out, const std::vector<Item>& items,
                                 const std::vector<Skipped>& skipped, const GroupMap& groups,
                                 bool qc) {
    std::vector<nlohmann::json> eyes;
    std::vector<std::string> names;
    std::size_t failed = skipped.size();
    for (const auto& it : items) {
        if (it.done) {
            eyes.push_back(it.slim);
            names.push_back((out / "eyes" / (it.key + ".json")).string());
        }
        if (it.failed) ++failed;
    }
    // One table per scan type (their parameter columns differ): eyes.csv holds the maculae,
    // eyes_onh.csv the optic nerve heads (written when the cohort has any).
    io::write_text_atomically((out / "eyes.csv").string(),
                              eyes_csv(eyes, names, "macula", groups));
    const bool any_onh = std::any_of(eyes.begin(), eyes.end(), [](const nlohmann::json& e) {
        return e.contains("cohort") && e["cohort"].value("scan_type", std::string()) == "onh";
    });
    if (any_onh) {
        io::write_text_atomically((out / "eyes_onh.csv").string(),
                                  eyes_csv(eyes, names, "onh", groups));
    }
    io::write_text_atomically((out / "failures.csv").string(), failures_csv(items, skipped));
    spdlog::info("{} eyes in {}, {} failed (see {})", eyes.size(), (out / "eyes.csv").string(),
                 failed, (out / "failures.csv").string());
    if (qc) {
        const GalleryResult g = write_qc_gallery(out);
        spdlog::info("QC gallery: {} ({} eyes, {} failures, {} pictures)",
                     (out / "qc" / "index.html").string(), g.eyes, g.failures, g.pictures);
    }
    return {eyes.size(), failed};
}

}  // namespace octshape::app
