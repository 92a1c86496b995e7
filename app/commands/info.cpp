// `octshape info FILE [--json] [--show-identifiers]`: what an export holds.

#include <CLI/CLI.hpp>
#include <functional>
#include <iomanip>
#include <iostream>
#include <sstream>

#include <nlohmann/json.hpp>

#include "commands/provenance.h"
#include <spdlog/spdlog.h>

#include "commands/command.h"
#include "octshape/io/scan_reader.h"
#include "octshape/retina/scan_summary.h"

namespace octshape::app {
namespace {

using nlohmann::json;

struct InfoOptions {
    std::string file;
    bool json = false;
    bool record_paths = false;
    bool identifiers = false;
};

std::string num(const json& v, const char* unit = "") {
    if (v.is_null()) return "missing";
    std::ostringstream ss;
    ss << std::setprecision(8) << v.get<double>() << unit;
    return ss.str();
}

using Row = std::function<void(const std::string&, const std::string&)>;

// A radial scan as it is (retina/radial_geometry.h): lines, length, crossing, angular step.
void print_radial(const json& r, const Row& row) {
    if (r.contains("error")) {
        row("radial", "lines unusable: " + r["error"].get<std::string>());
        return;
    }
    row("radial", std::to_string(r["num_lines"].get<int>()) + " lines of " +
                      num(r["line_length_mm"], " mm") + " (header " +
                      num(r["line_length_from_header_mm"], " mm") + "), step " +
                      num(r["angular_step_deg"], " deg") + " (min " + num(r["min_step_deg"]) +
                      ", max " + num(r["max_step_deg"]) + ") " +
                      (r["regular"].get<bool>() ? "regular" : "IRREGULAR"));
    row("crossing", "SLO (" + num(r["crossing_slo_mm"][0]) + ", " + num(r["crossing_slo_mm"][1]) +
                        ") mm; lines miss it by <= " + num(r["max_miss_mm"], " mm") +
                        (r["lines_cross"].get<bool>() ? "" : " (MORE than one A-scan)"));
    for (const json& s : r["irregular_steps"]) row("irregular step", s.get<std::string>());
    const json& bmo = r["bmo_fields"];
    if (bmo["bscans_with_fields"].get<int>() > 0) {
        row("BMO fields", std::to_string(bmo["bscans_with_fields"].get<int>()) +
                              " B-scans, not used: " + bmo["why"].get<std::string>());
    }
}

void print_spacing(const json& j, const Row& row) {
    const json& s = j["bscan_spacing"];
    std::string spacing = "header " + num(s["header_mm"], " mm");
    if (s["positions_known"].get<bool>()) {
        spacing += "; measured " + num(s["measured_mean_mm"], " mm") + " (min " +
                   num(s["measured_min_mm"]) + ", max " + num(s["measured_max_mm"]) + ") ";
        spacing += s["uniform"].get<bool>() ? "uniform" : "NOT UNIFORM";
        if (!s["matches_header"].get<bool>()) spacing += ", differs from the header";
    } else if (j["num_bscans"].get<int>() > 1) {
        spacing += "; positions do not tell";
    }
    row("B-scan spacing", spacing);
}

void print_header(const json& j, const Row& row) {
    row("file", j["file"].get<std::string>());
    row("sha256", j["sha256"].get<std::string>());
    row("format", j["format"].get<std::string>() + " (" + j["format_version"].get<std::string>() +
                      ")");
    row("eye", j["eye"].get<std::string>());
    row("scan pattern", j["scan_pattern"].get<std::string>() + " (code " +
                            std::to_string(j["scan_pattern_code"].get<int>()) + ")");
    row("size", std::to_string(j["num_bscans"].get<int>()) + " B-scan(s) x " +
                    std::to_string(j["ascans_per_bscan"].get<int>()) + " A-scans x " +
                    std::to_string(j["pixels_per_ascan"].get<int>()) + " px");
    row("scale", "x " + num(j["scale_x_mm"], " mm/A-scan") + ", z " +
                     num(j["scale_z_mm"], " mm/px") + ", depth " +
                     num(j["scan_depth_mm"], " mm"));
    if (j.contains("circle_radius_mm")) {
        row("circle", "radius " + num(j["circle_radius_mm"], " mm") + " (from positions " +
                          num(j["circle_radius_from_positions_mm"], " mm") + ")");
    } else if (j.contains("radial")) {
        print_radial(j["radial"], row);
    } else {
        row("extent", num(j["bscan_width_mm"], " mm") + " x " +
                          num(j["volume_height_mm"], " mm"));
    }
    if (j.contains("bscan_spacing")) print_spacing(j, row);
}

void print_text(const json& j, std::ostream& out) {
    auto row = [&](const std::string& key, const std::string& value) {
        out << std::left << std::setw(18) << (key + ":") << value << '\n';
    };
    print_header(j, row);
    if (j.contains("orientation")) {
        const json& o = j["orientation"];
        std::string text = "+x " + o["grid_x_points"].get<std::string>();
        if (o.contains("grid_y_points")) text += ", +y " + o["grid_y_points"].get<std::string>();
        text += o["from_bscan_positions"].get<bool>() ? " (from B-scan positions)"
                                                       : " (assumed: positions unusable)";
        row("orientation", text);
    }
    const json& slo = j["slo"];
    if (slo["width_px"].get<int>() == 0) {
        row("SLO", "none in this file");
    } else {
        row("SLO", std::to_string(slo["width_px"].get<int>()) + " x " +
                       std::to_string(slo["height_px"].get<int>()) + " px, " +
                       num(slo["scale_x_mm"], " mm/px") + ", " +
                       std::to_string(slo["field_size_deg"].get<unsigned>()) + " deg");
    }
    std::string layers;
    for (const json& l : j["layers"]) {
        if (!layers.empty()) layers += ", ";
        std::ostringstream ss;
        ss << l["name"].get<std::string>() << ' ' << std::fixed << std::setprecision(1)
           << l["valid_percent"].get<double>() << '%';
        layers += ss.str();
    }
    row("layers (valid)", layers.empty() ? "none" : layers);
    for (const json& g : j["thickness_grids"]) {
        std::string text = g["kind"].get<std::string>() + " (type " +
                           std::to_string(g["type"].get<int>()) + "), centre SLO (" +
                           num(g["centre_slo_mm"][0]) + ", " + num(g["centre_slo_mm"][1]) +
                           ") mm";
        if (!g["centre_grid_mm"].is_null()) {
            text += " = grid (" + num(g["centre_grid_mm"][0]) + ", " +
                    num(g["centre_grid_mm"][1]) + ") mm";
        }
        if (!g["from_header"].get<bool>()) text += " [found after the last B-scan]";
        row("thickness grid", text);
    }
    for (const json& n : j["notes"]) row("note", n.get<std::string>());
    if (j.contains("identifiers")) {
        for (const auto& [k, v] : j["identifiers"].items()) {
            row(k, v.is_null() ? "missing" : v.is_string() ? v.get<std::string>() : v.dump());
        }
    }
}

}  // namespace

void add_info_command(CLI::App& app, RunContext& /*ctx*/) {
    auto opts = std::make_shared<InfoOptions>();
    CLI::App* cmd = app.add_subcommand(
        "info", "Show what an export holds: eye, scan pattern, sizes, scales, B-scan spacing, "
                "layers and their valid values, thickness-grid centre");
    cmd->add_option("file", opts->file,
                    "A Spectralis .vol, Heidelberg XML export, Topcon .fda/.fds or Iowa "
                    "surfaces XML")
        ->required();
    cmd->add_flag("--json", opts->json, "Print JSON instead of text");
    cmd->add_flag("--show-identifiers", opts->identifiers,
                  "Also print patient/visit identifiers, date of birth and exam dates "
                  "(private: off by default)");
    cmd->add_flag("--record-paths", opts->record_paths,
                  "--json: also write the file's path (identifying: export names often hold the "
                  "patient's name)");
    cmd->callback([opts] {
        Provenance prov("info");
        const io::HashedScan input = io::read_scan_hashed(opts->file);
        prov.mark("read_hash");
        json j = retina::scan_summary(input.scan, {.identifiers = opts->identifiers});
        j["sha256"] = input.sha256;
        if (opts->json) {
            // The file is identified by its SHA-256; its name (often the patient's) only on
            // request.
            if (!opts->record_paths) j.erase("file");
            prov.add_input(input.sha256, opts->record_paths ? opts->file : std::string());
            prov.set_options({{"show_identifiers", opts->identifiers},
                              {"record_paths", opts->record_paths}});
            j["provenance"] = json(prov.json());
            std::cout << j.dump(2) << '\n';
        } else {
            print_text(j, std::cout);
        }
    });
}

}  // namespace octshape::app
