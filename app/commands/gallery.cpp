// The QC gallery page (gallery.h) and `octshape gallery OUTDIR`.

#include "commands/gallery.h"

#include <spdlog/fmt/fmt.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <fstream>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "commands/command.h"
#include "octshape/io/atomic_file.h"
#include "octshape/error.h"
#include "octshape/retina/eye_stats.h"
#include "octshape/version.h"

namespace octshape::app {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

// Parameters shown per scan type (the rest stay in the JSON); other types show their first
// kMaxGenericParams scalar parameters.
const std::map<std::string, std::vector<std::string>>& key_parameters() {
    static const std::map<std::string, std::vector<std::string>> k{
        {"macula",
         {"cft_mm", "rim_height_mm", "pit_depth_mm", "max_pit_slope_deg", "rim_diameter_mm",
          "pit_volume_mm3", "rmse_um"}},
        {"onh",
         {"cup_volume_mm3", "conht_mm", "bmo_volume_mm3", "bmo_area_mm2", "mrw_mm",
          "bending_energy"}},
    };
    return k;
}
constexpr std::size_t kMaxGenericParams = 6;

std::string escape(const std::string& s) {
    std::string o;
    for (const char c : s) {
        switch (c) {
            case '&':
                o += "&amp;";
                break;
            case '<':
                o += "&lt;";
                break;
            case '>':
                o += "&gt;";
                break;
            case '"':
                o += "&quot;";
                break;
            case '\'':
                o += "&#39;";
                break;
            default:
                o += c;
        }
    }
    return o;
}

// A relative link to a file in qc/ (its name, percent-encoding what a URL may not hold).
std::string url_name(const std::string& name) {
    std::string o;
    for (const unsigned char c : name) {
        if (std::isalnum(c) != 0 || c == '-' || c == '_' || c == '.' || c == '~') {
            o += static_cast<char>(c);
        } else {
            o += fmt::format("%{:02X}", static_cast<unsigned>(c));
        }
    }
    return o;
}

std::string text_of(const json& j) {
    if (j.is_string()) return j.get<std::string>();
    if (j.is_number()) return fmt::format("{:.6g}", j.get<double>());
    if (j.is_boolean()) return j.get<bool>() ? "true" : "false";
    return "";
}

struct EyeRow {
    std::string key;
    std::map<std::string, std::string> fields;  // subject_id, eye, visit_date, group, ...
    std::map<std::string, std::string> params;
    std::vector<std::string> flags;
    std::vector<std::string> pictures;  // file names in qc/
};

json read_json(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    if (!in) throw InputError::unreadable(p.string(), "cannot open");
    try {
        return json::parse(in);
    } catch (const json::exception& e) {
        throw InputError::corrupt(p.string(), std::string("not JSON: ") + e.what());
    }
}

const char* kCss = R"(
body{font:14px/1.35 system-ui,sans-serif;margin:1.2em;color:#222}
h1{font-size:1.4em} h2{font-size:1.15em;margin-top:1.5em}
table{border-collapse:collapse;margin:.5em 0}
th,td{border:1px solid #ccc;padding:3px 6px;vertical-align:top}
th{background:#eee;cursor:pointer;user-select:none;position:sticky;top:0}
th.asc::after{content:" \25B2"} th.desc::after{content:" \25BC"}
td.num{text-align:right;font-variant-numeric:tabular-nums}
tr.flagged td{background:#fff6e0}
table.failures th{background:#f6d5d5} table.failures td{background:#fdf0f0}
.flags{color:#a04000;font-size:.9em}
td{white-space:nowrap} td.flags{white-space:normal;min-width:8em}
img{max-height:130px;display:inline-block;margin:1px;border:1px solid #999}
.none{color:#2a7a2a}
)";

// Sorting: click a header (again: reverse); numbers sort numerically, NA last. `#sort=COL` or
// `#sort=-COL` in the URL sorts the eye table on load (bookmarkable; the tests use it).
const char* kScript = R"(
(function () {
  'use strict';
  function key(td) {
    var v = td.getAttribute('data-v');
    return v === null ? td.textContent.trim() : v;
  }
  function sortTable(table, col, desc) {
    var body = table.tBodies[0];
    var rows = Array.prototype.slice.call(body.rows);
    rows.sort(function (a, b) {
      var x = key(a.cells[col]), y = key(b.cells[col]);
      var nx = parseFloat(x), ny = parseFloat(y);
      var ax = x === '' || x === 'NA', ay = y === '' || y === 'NA';
      if (ax || ay) { return ax === ay ? 0 : (ax ? 1 : -1); }
      var c = (!isNaN(nx) && !isNaN(ny) && isFinite(x) && isFinite(y)) ? nx - ny
            : (x < y ? -1 : (x > y ? 1 : 0));
      return desc ? -c : c;
    });
    rows.forEach(function (r) { body.appendChild(r); });
    var ths = table.tHead.rows[0].cells;
    for (var i = 0; i < ths.length; i++) { ths[i].className = ''; }
    ths[col].className = desc ? 'desc' : 'asc';
  }
  var tables = document.querySelectorAll('table.sortable');
  tables.forEach(function (table) {
    var ths = table.tHead.rows[0].cells;
    for (var i = 0; i < ths.length; i++) {
      (function (col) {
        ths[col].addEventListener('click', function () {
          sortTable(table, col, ths[col].className === 'asc');
        });
      })(i);
    }
  });
  var m = /^#sort=(-?)(.+)$/.exec(window.location.hash);
  var eyes = document.getElementById('eyes');
  if (m && eyes) {
    var ths = eyes.tHead.rows[0].cells;
    for (var i = 0; i < ths.length; i++) {
      if (ths[i].getAttribute('data-col') === decodeURIComponent(m[2])) {
        sortTable(eyes, i, m[1] === '-');
      }
    }
  }
  document.body.setAttribute('data-ready', '1');
})();
)";

}  // namespace

GalleryResult write_qc_gallery(const fs::path& outdir) {
    std::error_code ec;
    if (!fs::is_directory(outdir, ec)) {
        if (!fs::exists(outdir, ec)) throw InputError::missing(outdir.string());
        throw InputError::not_regular(outdir.string());
    }
    GalleryResult res;

    // eyes.csv rows by eye key and by sha256 (subject, visit, group when the JSON lacks them).
    std::map<std::string, std::map<std::string, std::string>> csv_by_key;
    std::map<std::string, std::map<std::string, std::string>> csv_by_sha;
    if (fs::is_regular_file(outdir / "eyes.csv", ec)) {
        const auto t = retina::read_eye_table_file((outdir / "eyes.csv").string());
        for (const auto& row : t.rows) {
            std::map<std::string, std::string> m;
            for (std::size_t c = 0; c < t.header.size(); ++c) m[t.header[c]] = row[c];
            if (m.count("eye_key") != 0) csv_by_key[m["eye_key"]] = m;
            if (m.count("sha256") != 0) csv_by_sha[m["sha256"]] = m;
        }
    }

    // The eyes: OUTDIR/eyes/*.json in name order.
    std::vector<EyeRow> eyes;
    std::vector<std::string> param_columns;
    auto add_param_column = [&](const std::string& name) {
        if (std::find(param_columns.begin(), param_columns.end(), name) == param_columns.end()) {
            param_columns.push_back(name);
        }
    };
    std::vector<fs::path> json_files;
    if (fs::is_directory(outdir / "eyes", ec)) {
        for (const auto& e : fs::directory_iterator(outdir / "eyes")) {
            if (e.is_regular_file() && e.path().extension() == ".json") {
                json_files.push_back(e.path());
            }
        }
    }
    std::sort(json_files.begin(), json_files.end());
    for (const auto& path : json_files) {
        const json j = read_json(path);
        EyeRow row;
        row.key = path.stem().string();
        const std::string type = j.value("command", std::string());
        std::string sha;
        if (j.contains("input") && j["input"].is_object()) {
            sha = j["input"].value("sha256", std::string());
        }
        const std::map<std::string, std::string>* csv = nullptr;
        if (const auto it = csv_by_key.find(row.key); it != csv_by_key.end()) {
            csv = &it->second;
        } else if (const auto is = csv_by_sha.find(sha); is != csv_by_sha.end()) {
            csv = &is->second;
        }
        for (const char* f : {"subject_id", "eye", "visit_date", "group", "scan_type"}) {
            std::string v;
            if (j.contains("cohort") && j["cohort"].is_object() && j["cohort"].contains(f)) {
                v = text_of(j["cohort"][f]);
            }
            if (v.empty() && csv != nullptr && csv->count(f) != 0) v = csv->at(f);
            row.fields[f] = v;
        }
        if (row.fields["eye"].empty() && j.contains("scan") && j["scan"].is_object()) {
            row.fields["eye"] = text_of(j["scan"].value("eye", json()));
        }
        if (row.fields["scan_type"].empty()) row.fields["scan_type"] = type;
        if (j.contains("parameters") && j["parameters"].is_object()) {
            const json& p = j["parameters"];
            const auto kt = key_parameters().find(type);
            if (kt != key_parameters().end()) {
                for (const auto& name : kt->second) {
                    if (!p.contains(name)) continue;
                    add_param_column(name);
                    row.params[name] = p[name].is_number() ? text_of(p[name]) : "NA";
                }
            } else {
                std::size_t shown = 0;
                for (const auto& [name, v] : p.items()) {
                    if (shown == kMaxGenericParams) break;
                    if (!v.is_number() && !v.is_null()) continue;
                    add_param_column(name);
                    row.params[name] = v.is_number() ? text_of(v) : "NA";
                    ++shown;
                }
            }
        }
        if (j.contains("qc_flags") && j["qc_flags"].is_array()) {
            for (const auto& f : j["qc_flags"]) row.flags.push_back(text_of(f));
        }
        eyes.push_back(std::move(row));
    }

    // QC pictures: each qc/*.png goes to the longest eye key it starts with (KEY_...).
    std::vector<std::string> pngs;
    if (fs::is_directory(outdir / "qc", ec)) {
        for (const auto& e : fs::directory_iterator(outdir / "qc")) {
            if (e.is_regular_file() && e.path().extension() == ".png") {
                pngs.push_back(e.path().filename().string());
            }
        }
    }
    std::sort(pngs.begin(), pngs.end());
    for (const auto& png : pngs) {
        EyeRow* best = nullptr;
        for (auto& e : eyes) {
            const std::string prefix = e.key + "_";
            if (png.compare(0, prefix.size(), prefix) == 0 &&
                (best == nullptr || e.key.size() > best->key.size())) {
                best = &e;
            }
        }
        if (best != nullptr) {
            best->pictures.push_back(png);
            ++res.pictures;
        }
    }

    // Failures.
    retina::EyeTable failures;
    if (fs::is_regular_file(outdir / "failures.csv", ec)) {
        failures = retina::read_eye_table_file((outdir / "failures.csv").string());
    }
    res.failures = failures.rows.size();
    res.eyes = eyes.size();

    std::ostringstream h;
    h << "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
      << "<link rel=\"icon\" href=\"data:,\">\n"
      << "<title>octshape QC gallery</title>\n<style>" << kCss << "</style>\n</head>\n<body>\n"
      << "<h1>octshape QC gallery</h1>\n"
      << "<p>" << res.eyes << " eyes, " << res.failures << " failures &middot; octshape " << kVersion
      << ". Click a column header to sort (again to reverse).</p>\n";

    h << "<h2 id=\"failures-title\">Failures (" << res.failures << ")</h2>\n";
    if (failures.rows.empty()) {
        h << "<p class=\"none\">No failures.</p>\n";
    } else {
        h << "<table id=\"failures\" class=\"failures sortable\">\n<thead><tr>";
        for (const auto& c : failures.header) h << "<th>" << escape(c) << "</th>";
        h << "</tr></thead>\n<tbody>\n";
        for (const auto& r : failures.rows) {
            h << "<tr class=\"failure\">";
            for (const auto& v : r) h << "<td>" << escape(v) << "</td>";
            h << "</tr>\n";
        }
        h << "</tbody>\n</table>\n";
    }

    // No file or folder name: the page is shared (docs/cohort.md, "Output folder").
    const std::vector<std::string> fixed{"eye_key", "subject_id", "eye",
                                         "visit_date", "group", "scan_type"};
    h << "<h2>Eyes (" << res.eyes << ")</h2>\n"
      << "<table id=\"eyes\" class=\"sortable\">\n<thead><tr>";
    h << "<th data-col=\"eye_key\">eye_key</th><th data-col=\"pictures\">pictures</th>";
    for (std::size_t c = 1; c < fixed.size(); ++c) {
        h << "<th data-col=\"" << escape(fixed[c]) << "\">" << escape(fixed[c]) << "</th>";
    }
    for (const auto& c : param_columns) {
        h << "<th data-col=\"" << escape(c) << "\">" << escape(c) << "</th>";
    }
    h << "<th data-col=\"qc_flags\">qc_flags</th></tr></thead>\n<tbody>\n";
    for (const auto& e : eyes) {
        h << "<tr class=\"eye" << (e.flags.empty() ? "" : " flagged") << "\" data-key=\""
          << escape(e.key) << "\">";
        h << "<td>" << escape(e.key) << "</td><td data-v=\"" << e.pictures.size() << "\">";
        for (const auto& p : e.pictures) {
            const std::string u = url_name(p);
            h << "<a href=\"" << u << "\"><img src=\"" << u << "\" alt=\"" << escape(p)
              << "\" loading=\"lazy\"></a>";
        }
        h << "</td>";
        for (std::size_t c = 1; c < fixed.size(); ++c) {
            const auto it = e.fields.find(fixed[c]);
            h << "<td>" << escape(it == e.fields.end() ? "" : it->second) << "</td>";
        }
        for (const auto& c : param_columns) {
            const auto it = e.params.find(c);
            const std::string v = it == e.params.end() ? "NA" : it->second;
            h << "<td class=\"num\" data-v=\"" << escape(v) << "\">" << escape(v) << "</td>";
        }
        std::string flags;
        for (const auto& f : e.flags) flags += (flags.empty() ? "" : "; ") + f;
        h << "<td class=\"flags\" data-v=\"" << e.flags.size() << "\">" << escape(flags)
          << "</td></tr>\n";
    }
    h << "</tbody>\n</table>\n<script>" << kScript << "</script>\n</body>\n</html>\n";

    const fs::path qc = outdir / "qc";
    fs::create_directories(qc, ec);
    if (ec) throw OutputError(qc.string(), ec.message());
    io::write_text_atomically((qc / "index.html").string(), h.str());
    return res;
}

void add_gallery_command(CLI::App& app, RunContext& /*ctx*/) {
    auto outdir = std::make_shared<std::string>();
    CLI::App* cmd = app.add_subcommand(
        "gallery",
        "Write OUTDIR/qc/index.html: a static page (no server, no external files) with the "
        "failures on top and every eye's QC pictures, key parameters and QC flags, sortable");
    cmd->add_option("outdir", *outdir, "A cohort output directory (eyes/, eyes.csv, qc/)")
        ->required();
    cmd->callback([outdir] {
        const GalleryResult r = write_qc_gallery(*outdir);
        spdlog::info("{}: QC gallery with {} eyes, {} failures, {} pictures",
                     (fs::path(*outdir) / "qc" / "index.html").string(), r.eyes, r.failures,
                     r.pictures);
    });
}

}  // namespace octshape::app
