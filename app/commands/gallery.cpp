// The QC gallery page (gallery.h) and `octshape gallery OUTDIR`.

#include "commands/gallery.h"

#include <CLI/CLI.hpp>
#include <spdlog/fmt/fmt.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "commands/command.h"
#include "octshape/qc/names.h"
#include "octshape/io/atomic_file.h"
#include "octshape/error.h"
#include "octshape/retina/cube_report.h"
#include "octshape/retina/eye_stats.h"
#include "octshape/retina/onh_report.h"
#include "octshape/version.h"
#include "octshape/retina/record.h"

namespace octshape::app {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;
namespace record = retina::record;
using record::Name;

// Parameters shown for an eye of the command `type` (the rest stay in the JSON): the
// analysis's key columns (cube_report.h, onh_report.h); nullptr for another command, whose
// first kMaxGenericParams scalar parameters are shown.
const std::vector<std::string>* key_parameters(const std::string& type) {
    const std::optional<retina::ScanType> t = retina::record::parse_scan_type(type);
    if (t == retina::ScanType::kMacula) return &retina::macula_key_columns();
    if (t == retina::ScanType::kOnh) return &retina::onh_key_columns();
    return nullptr;
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

// A parameter's column header: its name in words with the unit in brackets (cft_mm ->
// "cft (mm)").
std::string param_label(const std::string& name) {
    static const std::vector<std::pair<std::string, std::string>> units{
        {"_mm3", "mm3"}, {"_mm2", "mm2"}, {"_mm", "mm"}, {"_deg", "deg"}, {"_um", "um"}};
    std::string base = name;
    std::string unit;
    for (const auto& [suffix, u] : units) {
        if (base.size() > suffix.size() && base.ends_with(suffix)) {
            base.resize(base.size() - suffix.size());
            unit = u;
            break;
        }
    }
    std::replace(base.begin(), base.end(), '_', ' ');
    return unit.empty() ? base : base + " (" + unit + ")";
}

// 4 significant digits for the table (the full value stays in data-v for sorting).
std::string short_value(const std::string& v) {
    char* end = nullptr;
    const double d = std::strtod(v.c_str(), &end);
    if (v.empty() || end != v.c_str() + v.size() || !std::isfinite(d)) return v;
    return fmt::format("{:.4g}", d);
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
body{font:13px/1.3 system-ui,sans-serif;margin:.6em .8em;color:#222}
header h1{font-size:1.2em;margin:0 0 .2em} header p{margin:0 0 .5em;color:#555}
table{border-collapse:collapse}
th,td{border:1px solid #ccc;padding:2px 5px;vertical-align:top}
th{background:#eee;cursor:pointer;user-select:none;position:sticky;top:0;z-index:1;
   font-weight:600;white-space:normal;max-width:6.5em}
th.asc::after{content:" \25B2"} th.desc::after{content:" \25BC"}
td{white-space:nowrap} td.num{text-align:right;font-variant-numeric:tabular-nums}
td.flags{white-space:normal;min-width:10em;max-width:22em;color:#a04000}
td.key{font-family:monospace;font-size:12px}
tr.failed td{background:#fbe3e3} tr.failed td.status{color:#b00000;font-weight:700}
tr.flagged td{background:#fff3d6} tr.flagged td.status{color:#a04000;font-weight:700}
tr.passed td.status{color:#2a7a2a}
tr.pics td{border-top:none;padding:3px 5px 8px;background:#fafafa}
tr.failed + tr.pics td{display:none}
a.thumb img{height:210px;max-width:440px;object-fit:contain;margin:0 4px 0 0;
   border:1px solid #999;vertical-align:top;background:#222}
#viewer{position:fixed;inset:0;background:rgba(0,0,0,.85);overflow:auto;z-index:9;
   cursor:zoom-out;text-align:center}
#viewer img{max-width:none;margin:1em auto;background:#fff}
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
  // Rows come in pairs: the eye's cells, then its pictures (tr.pics); they move together.
  function sortTable(table, col, desc) {
    var body = table.tBodies[0];
    var rows = Array.prototype.filter.call(body.rows, function (r) {
      return r.className.indexOf('pics') < 0;
    });
    var pics = rows.map(function (r) { return r.nextElementSibling; });
    var order = rows.map(function (r, i) { return i; });
    order.sort(function (i, j) {
      var x = key(rows[i].cells[col]), y = key(rows[j].cells[col]);
      var nx = parseFloat(x), ny = parseFloat(y);
      var ax = x === '' || x === 'NA', ay = y === '' || y === 'NA';
      if (ax || ay) { return ax === ay ? i - j : (ax ? 1 : -1); }
      var c = (!isNaN(nx) && !isNaN(ny) && isFinite(x) && isFinite(y)) ? nx - ny
            : (x < y ? -1 : (x > y ? 1 : 0));
      return (desc ? -c : c) || i - j;
    });
    order.forEach(function (i) { body.appendChild(rows[i]); body.appendChild(pics[i]); });
    var ths = table.tHead.rows[0].cells;
    for (var i = 0; i < ths.length; i++) { ths[i].classList.remove('asc', 'desc'); }
    ths[col].classList.add(desc ? 'desc' : 'asc');
  }
  var tables = document.querySelectorAll('table.sortable');
  tables.forEach(function (table) {
    var ths = table.tHead.rows[0].cells;
    for (var i = 0; i < ths.length; i++) {
      (function (col) {
        ths[col].addEventListener('click', function () {
          sortTable(table, col, ths[col].classList.contains('asc'));
        });
      })(i);
    }
  });
  // A click on a thumbnail shows the picture at full size; a click or Escape closes it.
  var viewer = document.getElementById('viewer');
  document.querySelectorAll('a.thumb').forEach(function (a) {
    a.addEventListener('click', function (ev) {
      ev.preventDefault();
      viewer.firstElementChild.src = a.getAttribute('href');
      viewer.hidden = false;
    });
  });
  viewer.addEventListener('click', function () { viewer.hidden = true; });
  document.addEventListener('keydown', function (ev) {
    if (ev.key === 'Escape') { viewer.hidden = true; }
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

// The eyes: OUTDIR/eyes/*.json in name order, subject, visit and group from eyes.csv (by eye
// key, then by sha256) where the JSON lacks them; the parameter columns in first-seen order.
struct Eyes {
    std::vector<EyeRow> rows;
    std::vector<std::string> param_columns;
};

Eyes read_eyes(const fs::path& outdir) {
    std::error_code ec;
    Eyes out;
    std::map<std::string, std::map<std::string, std::string>> csv_by_key;
    std::map<std::string, std::map<std::string, std::string>> csv_by_sha;
    const std::string& key_col = record::name(Name::kEyeKey);
    const std::string& sha_col = record::name(Name::kSha256);
    const fs::path table = outdir / record::eyes_table_file(retina::ScanType::kMacula);
    if (fs::is_regular_file(table, ec)) {
        const auto t = retina::read_eye_table_file(table.string());
        for (const auto& row : t.rows) {
            std::map<std::string, std::string> m;
            for (std::size_t c = 0; c < t.header.size(); ++c) m[t.header[c]] = row[c];
            if (m.count(key_col) != 0) csv_by_key[m[key_col]] = m;
            if (m.count(sha_col) != 0) csv_by_sha[m[sha_col]] = m;
        }
    }

    auto add_param_column = [&](const std::string& name) {
        if (std::find(out.param_columns.begin(), out.param_columns.end(), name) ==
            out.param_columns.end()) {
            out.param_columns.push_back(name);
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
        const std::string& input = record::name(Name::kInput);
        if (j.contains(input) && j[input].is_object()) sha = j[input].value(sha_col, std::string());
        const std::map<std::string, std::string>* csv = nullptr;
        if (const auto it = csv_by_key.find(row.key); it != csv_by_key.end()) {
            csv = &it->second;
        } else if (const auto is = csv_by_sha.find(sha); is != csv_by_sha.end()) {
            csv = &is->second;
        }
        const std::string& cohort = record::name(Name::kCohort);
        // The page's own field names (the drawing's), each read from the record's name.
        for (const auto& [field, n] : std::vector<std::pair<std::string, Name>>{
                 {"subject_id", Name::kSubjectId},
                 {"eye", Name::kEye},
                 {"visit_date", Name::kVisitDate},
                 {"group", Name::kGroup},
                 {"scan_type", Name::kScanType}}) {
            const std::string& f = record::name(n);
            std::string v;
            if (j.contains(cohort) && j[cohort].is_object() && j[cohort].contains(f)) {
                v = text_of(j[cohort][f]);
            }
            if (v.empty() && csv != nullptr && csv->count(f) != 0) v = csv->at(f);
            row.fields[field] = v;
        }
        if (row.fields["eye"].empty() && j.contains("scan") && j["scan"].is_object()) {
            row.fields["eye"] = text_of(j["scan"].value("eye", json()));
        }
        if (row.fields["scan_type"].empty()) row.fields["scan_type"] = type;
        if (j.contains("parameters") && j["parameters"].is_object()) {
            const json& p = j["parameters"];
            if (const std::vector<std::string>* key = key_parameters(type)) {
                for (const auto& name : *key) {
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
        out.rows.push_back(std::move(row));
    }

    return out;
}

// Gives each qc/*.png to its eye; returns how many were given.
std::size_t assign_pictures(const fs::path& outdir, std::vector<EyeRow>& eyes) {
    std::error_code ec;
    std::size_t pictures = 0;
    // QC pictures: each qc/*.png goes to the longest eye key whose picture name it is
    // (KEY_KIND.png, octshape/qc/names.h).
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
            if (!qc::picture_kind(e.key, png).empty() &&
                (best == nullptr || e.key.size() > best->key.size())) {
                best = &e;
            }
        }
        if (best != nullptr) {
            best->pictures.push_back(png);
            ++pictures;
        }
    }

    return pictures;
}

// One table, failures first, then flagged eyes (most flags first), then the rest, each
// by eye key; a column header click re-sorts. Status: 0 failed, 1 flagged, 2 passed.
struct Line {
    int status = 2;
    std::string key;
    const EyeRow* eye = nullptr;
    std::string reason;  // failures
};

std::vector<Line> table_lines(const retina::EyeTable& failures, const std::vector<EyeRow>& eyes) {
    std::vector<Line> lines;
    const int key_col = failures.column(record::name(Name::kEyeKey));
    const int file_col = failures.column(record::name(Name::kFile));
    const int reason_col = failures.column(record::name(Name::kReason));
    const int code_col = failures.column(record::name(Name::kExitCode));
    for (const auto& row : failures.rows) {
        Line l;
        l.status = 0;
        if (key_col >= 0) l.key = row[static_cast<std::size_t>(key_col)];
        std::string reason = reason_col >= 0 ? row[static_cast<std::size_t>(reason_col)] : "";
        // Error messages start with the file's path: the page shows no file names.
        if (file_col >= 0) {
            const std::string& f = row[static_cast<std::size_t>(file_col)];
            if (!f.empty() && reason.rfind(f + ": ", 0) == 0) reason = reason.substr(f.size() + 2);
        }
        if (code_col >= 0) reason += " (exit " + row[static_cast<std::size_t>(code_col)] + ")";
        l.reason = reason;
        lines.push_back(std::move(l));
    }
    for (const auto& e : eyes) {
        Line l;
        l.status = e.flags.empty() ? 2 : 1;
        l.key = e.key;
        l.eye = &e;
        lines.push_back(std::move(l));
    }
    std::stable_sort(lines.begin(), lines.end(), [](const Line& a, const Line& b) {
        const std::size_t fa = a.eye != nullptr ? a.eye->flags.size() : 0;
        const std::size_t fb = b.eye != nullptr ? b.eye->flags.size() : 0;
        if (a.status != b.status) return a.status < b.status;
        if (fa != fb) return fa > fb;
        return a.key < b.key;
    });

    return lines;
}

// The page: one sortable table, each eye's pictures in a row under it.
std::string page(const GalleryResult& res, const std::vector<std::string>& param_columns,
                 const std::vector<Line>& lines) {
    std::ostringstream h;
    h << "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
      << "<link rel=\"icon\" href=\"data:,\">\n"
      << "<title>octshape QC gallery</title>\n<style>" << kCss << "</style>\n</head>\n<body>\n"
      << "<header><h1>octshape QC gallery</h1><p>" << res.eyes << " eyes, " << res.failures
      << " failures &middot; octshape " << kVersion
      << " &middot; sorted by QC: failed, flagged, passed. Click a column header to sort "
         "(again to reverse), a picture to see it full size.</p></header>\n";

    const std::vector<std::pair<std::string, std::string>> fixed{
        {"eye", "eye"}, {"scan_type", "scan"}};
    const std::vector<std::pair<std::string, std::string>> trailing{
        {"subject_id", "subject"}, {"visit_date", "visit"}, {"group", "group"}};
    const std::size_t columns = 4 + fixed.size() + param_columns.size() + trailing.size();
    h << "<table id=\"eyes\" class=\"sortable\">\n<thead><tr>"
      << "<th data-col=\"status\" class=\"asc\">QC</th>"
      << "<th data-col=\"qc_flags\">QC flags / failure</th>"
      << "<th data-col=\"eye_key\">eye key</th>";
    for (const auto& [col, label] : fixed) {
        h << "<th data-col=\"" << escape(col) << "\">" << escape(label) << "</th>";
    }
    for (const auto& c : param_columns) {
        h << "<th data-col=\"" << escape(c) << "\" class=\"num\">" << escape(param_label(c))
          << "</th>";
    }
    h << "<th data-col=\"pictures\">pictures</th>";
    for (const auto& [col, label] : trailing) {
        h << "<th data-col=\"" << escape(col) << "\">" << escape(label) << "</th>";
    }
    h << "</tr></thead>\n<tbody>\n";
    static const char* kStatus[] = {"failed", "flagged", "passed"};
    for (const Line& l : lines) {
        const EyeRow* e = l.eye;
        h << "<tr class=\"row " << kStatus[l.status] << (l.status == 0 ? " failure" : "")
          << "\"" << (e != nullptr ? " data-key=\"" + escape(e->key) + "\"" : std::string())
          << ">";
        h << "<td class=\"status\" data-v=\"" << l.status << "\">" << kStatus[l.status] << "</td>";
        std::string flags = l.reason;
        if (e != nullptr) {
            for (const auto& f : e->flags) flags += (flags.empty() ? "" : "; ") + f;
        }
        h << "<td class=\"flags\" data-v=\""
          << (e != nullptr ? std::to_string(e->flags.size()) : escape(flags)) << "\">"
          << escape(flags) << "</td>";
        h << "<td class=\"key\">" << escape(l.key) << "</td>";
        const auto field = [&](const std::string& c) {
            if (e == nullptr) return std::string();
            const auto it = e->fields.find(c);
            return it == e->fields.end() ? std::string() : it->second;
        };
        for (const auto& fc : fixed) h << "<td>" << escape(field(fc.first)) << "</td>";
        for (const auto& c : param_columns) {
            std::string v = "NA";
            if (e != nullptr) {
                const auto it = e->params.find(c);
                if (it != e->params.end()) v = it->second;
            }
            h << "<td class=\"num param\" data-v=\"" << escape(v) << "\">" << escape(short_value(v))
              << "</td>";
        }
        h << "<td data-v=\"" << (e != nullptr ? e->pictures.size() : 0) << "\">"
          << (e != nullptr ? e->pictures.size() : 0) << "</td>";
        for (const auto& tc : trailing) h << "<td>" << escape(field(tc.first)) << "</td>";
        h << "</tr>\n";
        // The pictures under their eye, across the whole table (moved with the row on sorting).
        h << "<tr class=\"pics\"><td colspan=\"" << columns << "\">";
        if (e != nullptr) {
            for (const auto& p : e->pictures) {
                const std::string u = url_name(p);
                h << "<a class=\"thumb\" href=\"" << u << "\"><img src=\"" << u
                  << "\" alt=\"QC picture " << escape(qc::picture_kind(e->key, p)) << "\"></a>";
            }
        }
        h << "</td></tr>\n";
    }
    h << "</tbody>\n</table>\n"
      << "<div id=\"viewer\" hidden><img alt=\"full size\"></div>\n"
      << "<script>" << kScript << "</script>\n</body>\n</html>\n";

    return h.str();
}

}  // namespace

GalleryResult write_qc_gallery(const fs::path& outdir, bool allow_empty) {
    std::error_code ec;
    if (!fs::is_directory(outdir, ec)) {
        if (!fs::exists(outdir, ec)) throw InputError::missing(outdir.string());
        throw InputError::not_regular(outdir.string());
    }
    GalleryResult res;

    Eyes read = read_eyes(outdir);
    std::vector<EyeRow>& eyes = read.rows;
    res.pictures = assign_pictures(outdir, eyes);

    // Failures.
    retina::EyeTable failures;
    if (fs::is_regular_file(outdir / "failures.csv", ec)) {
        failures = retina::read_eye_table_file((outdir / "failures.csv").string());
    }
    res.failures = failures.rows.size();
    res.eyes = eyes.size();

    if (!allow_empty && eyes.empty() && failures.rows.empty()) {
        throw InputError(InputError::Kind::kMissing, outdir.string(),
                         "nothing to show: no eyes/*.json and no failures.csv rows (run "
                         "octshape cohort --qc first)");
    }

    const std::vector<Line> lines = table_lines(failures, eyes);

    const fs::path qc = outdir / "qc";
    fs::create_directories(qc, ec);
    if (ec) throw OutputError(qc.string(), ec.message());
    io::write_text_atomically((qc / "index.html").string(), page(res, read.param_columns, lines));
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
        const GalleryResult r = write_qc_gallery(*outdir, /*allow_empty=*/false);
        spdlog::info("{}: QC gallery with {} eyes, {} failures, {} pictures",
                     (fs::path(*outdir) / "qc" / "index.html").string(), r.eyes, r.failures,
                     r.pictures);
    });
}

}  // namespace octshape::app
