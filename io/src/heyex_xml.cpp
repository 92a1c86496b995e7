#include "octshape/io/heyex_xml.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <set>

#include "octshape/error.h"
#include "octshape/io/image.h"
#include "xml_dom.h"

namespace octshape::io {
namespace {

namespace fs = std::filesystem;
using detail::XmlNode;

// Sanity bounds: far above any Spectralis export, far below what could exhaust memory.
constexpr std::uintmax_t kMaxXmlBytes = 1ULL << 30;
constexpr int kMaxImageSide = 8192;
constexpr std::size_t kMaxBScans = 4096;

class XmlScanReader {
public:
    XmlScanReader(std::string path, const ReadOptions& options)
        : path_(std::move(path)), options_(options) {}

    Scan read() {
        const std::string doc = slurp();
        const XmlNode root = detail::parse_xml(doc, path_);
        if (root.name != "HEDX") {
            throw InputError::unsupported(path_, "XML but not a Heidelberg export (root <" +
                                                     root.name + ">)");
        }
        const XmlNode* body = require(root, "BODY");
        const XmlNode* patient = require(*body, "Patient");
        const XmlNode* study = require(*patient, "Study");
        const XmlNode* series = require(*study, "Series");

        Scan scan;
        scan.source_path = path_;
        scan.meta.format = SourceFormat::kHeyexXml;
        scan.meta.version = "Heidelberg XML export";
        if (const XmlNode* sw = body->child("SWVersion")) {
            scan.meta.version += " (" + text_or(sw->child("Name"), "") + " " +
                                 text_or(sw->child("Version"), "") + ")";
        }
        read_identifiers(*patient, scan);
        if (const auto d = date_of(study->find("StudyDate/Date"))) scan.meta.visit_date_ole = *d;
        read_laterality(*series, scan);

        const XmlNode* localizer = nullptr;
        std::vector<const XmlNode*> octs;
        for (const XmlNode* image : series->children_named("Image")) {
            const std::string type = text_or(image->find("ImageType/Type"), "");
            if (type == "LOCALIZER") {
                if (localizer == nullptr) localizer = image;
            } else if (type == "OCT") {
                octs.push_back(image);
            }
        }
        if (octs.empty()) throw InputError::unsupported(path_, "the export holds no OCT image");
        if (octs.size() > kMaxBScans) {
            throw InputError::corrupt(path_, std::to_string(octs.size()) + " OCT images",
                                      octs[kMaxBScans]->offset);
        }
        if (localizer != nullptr) read_localizer(*localizer, scan);
        read_bscans(octs, scan);
        scan.meta.pattern = pattern_of(*series, scan);
        scan.meta.scan_pattern_code = static_cast<std::int32_t>(scan.meta.pattern);
        set_exam_time(*series, *octs.front(), scan);
        if (const XmlNode* grid = series->child("ThicknessGrid")) read_grid(*grid, scan);
        scan.pixels_loaded = options_.pixels;
        return scan;
    }

private:
    std::string slurp() const {
        return detail::read_whole_file(path_, kMaxXmlBytes, "XML export");
    }

    const XmlNode* require(const XmlNode& parent, std::string_view name) const {
        const XmlNode* n = parent.find(name);
        if (n == nullptr) {
            throw InputError::corrupt(path_, "<" + parent.name + "> has no <" +
                                                 std::string(name) + ">",
                                      parent.offset);
        }
        return n;
    }

    static std::string trimmed(const std::string& s) {
        const auto b = s.find_first_not_of(" \t\r\n");
        if (b == std::string::npos) return {};
        const auto e = s.find_last_not_of(" \t\r\n");
        return s.substr(b, e - b + 1);
    }
    static std::string text_or(const XmlNode* n, const std::string& fallback) {
        return n == nullptr ? fallback : trimmed(n->text);
    }

    double number(const XmlNode& parent, std::string_view name) const {
        const XmlNode* n = require(parent, name);
        const std::string t = trimmed(n->text);
        double v = 0.0;
        const auto [end, ec] = std::from_chars(t.data(), t.data() + t.size(), v);
        if (ec != std::errc() || end != t.data() + t.size() || !std::isfinite(v)) {
            throw InputError::corrupt(path_, "<" + std::string(name) + "> is not a number: '" +
                                                 t.substr(0, 40) + "'",
                                      n->offset);
        }
        return v;
    }
    int positive_int(const XmlNode& parent, std::string_view name, int max) const {
        const double v = number(parent, name);
        if (v < 1.0 || v > max || v != std::floor(v)) {
            throw InputError::corrupt(path_, "<" + std::string(name) + "> = " +
                                                 std::to_string(v) + " is not a size in 1.." +
                                                 std::to_string(max),
                                      parent.offset);
        }
        return static_cast<int>(v);
    }
    double positive_scale(const XmlNode& parent, std::string_view name) const {
        const double v = number(parent, name);
        if (!(v > 0.0 && v < 10.0)) {
            throw InputError::corrupt(path_, "<" + std::string(name) + "> = " +
                                                 std::to_string(v) + " mm is not a plausible scale",
                                      parent.offset);
        }
        return v;
    }

    std::optional<double> date_of(const XmlNode* date) const {
        if (date == nullptr) return std::nullopt;
        const double y = number(*date, "Year");
        const double m = number(*date, "Month");
        const double d = number(*date, "Day");
        if (y < 1800 || y > 2200 || m < 1 || m > 12 || d < 1 || d > 31) {
            throw InputError::corrupt(path_, "impossible date", date->offset);
        }
        // OLE date: days since 1899-12-30, which is 25569 days before 1970-01-01.
        return static_cast<double>(days_from_civil(static_cast<long long>(y),
                                                   static_cast<unsigned>(m),
                                                   static_cast<unsigned>(d)) +
                                   25569);
    }

    void read_identifiers(const XmlNode& patient, Scan& scan) const {
        // Names are deliberately not read: octshape never needs them.
        scan.meta.ids.id = text_or(patient.child("ID"), "");
        scan.meta.ids.patient_id = text_or(patient.child("PatientID"), "");
        scan.meta.ids.dob_ole = date_of(patient.find("Birthdate/Date"));
    }

    void read_laterality(const XmlNode& series, Scan& scan) const {
        const std::string lat = text_or(series.child("Laterality"), "");
        scan.meta.scan_position_raw = lat;
        if (lat == "R" || lat == "OD") {
            scan.meta.laterality = Laterality::kOD;
        } else if (lat == "L" || lat == "OS") {
            scan.meta.laterality = Laterality::kOS;
        } else {
            scan.notes.push_back("laterality '" + lat + "' not recognised");
        }
    }

    fs::path image_file(const XmlNode& image) const {
        const std::string url = text_or(image.find("ImageData/ExamURL"), "");
        // A Windows path or file URL: the basename is the file beside the XML.
        const auto cut = url.find_last_of("\\/");
        const std::string base = cut == std::string::npos ? url : url.substr(cut + 1);
        if (base.empty() || base == "." || base == "..") {
            throw InputError::corrupt(path_, "image without a file name", image.offset);
        }
        return fs::path(path_).parent_path() / base;
    }

    std::vector<std::uint8_t> load_image(const XmlNode& image, int width, int height) const {
        const fs::path file = image_file(image);
        std::error_code ec;
        // Errors name the image file and the export that refers to it.
        const std::string of = " (image of " + fs::path(path_).filename().string() + ")";
        if (!fs::is_regular_file(file, ec)) {
            throw InputError(InputError::Kind::kMissing, file.string(), "no such file" + of);
        }
        return read_tiff_gray(file.string(), width, height, of);
    }

    void read_localizer(const XmlNode& image, Scan& scan) const {
        const XmlNode* ctx = require(image, "OphthalmicAcquisitionContext");
        scan.meta.size_x_slo = positive_int(*ctx, "Width", kMaxImageSide);
        scan.meta.size_y_slo = positive_int(*ctx, "Height", kMaxImageSide);
        scan.meta.scale_x_slo_mm = positive_scale(*ctx, "ScaleX");
        scan.meta.scale_y_slo_mm = positive_scale(*ctx, "ScaleY");
        if (ctx->child("Angle") != nullptr) {
            scan.meta.field_size_slo_deg = static_cast<std::uint32_t>(
                std::clamp(number(*ctx, "Angle"), 0.0, 360.0));
        }
        if (ctx->child("Focus") != nullptr) scan.meta.scan_focus_dpt = number(*ctx, "Focus");
        if (options_.pixels) {
            scan.slo = load_image(image, scan.meta.size_x_slo, scan.meta.size_y_slo);
        }
    }

    std::vector<float> seg_values(const XmlNode& array, int width) const {
        std::vector<float> values;
        values.reserve(static_cast<std::size_t>(width));
        const std::string& t = array.text;
        const char* p = t.data();
        const char* end = t.data() + t.size();
        for (;;) {
            while (p < end && (*p == ' ' || *p == '\t' || *p == '\n' || *p == '\r')) ++p;
            if (p == end) break;
            if (values.size() == static_cast<std::size_t>(width)) {
                throw InputError::corrupt(path_, "segmentation line longer than Width",
                                          array.offset);
            }
            double v = 0.0;
            const auto [next, ec] = std::from_chars(p, end, v);
            if (ec == std::errc::result_out_of_range) {
                v = std::numeric_limits<double>::infinity();  // beyond double: invalid anyway
            } else if (ec != std::errc()) {
                throw InputError::corrupt(path_, "segmentation value is not a number",
                                          array.offset);
            }
            const auto f = static_cast<float>(v);
            values.push_back(std::isfinite(v) && is_valid_raw(f)
                                 ? f
                                 : std::numeric_limits<float>::quiet_NaN());
            p = next;
        }
        if (values.size() != static_cast<std::size_t>(width)) {
            throw InputError::corrupt(path_,
                                      "segmentation line has " + std::to_string(values.size()) +
                                          " values, Width is " + std::to_string(width),
                                      array.offset);
        }
        return values;
    }

    void read_bscans(const std::vector<const XmlNode*>& octs, Scan& scan) const {
        std::set<int> present;
        for (const XmlNode* image : octs) {
            const XmlNode* ctx = require(*image, "OphthalmicAcquisitionContext");
            const int width = positive_int(*ctx, "Width", kMaxImageSide);
            const int height = positive_int(*ctx, "Height", kMaxImageSide);
            const double sx = positive_scale(*ctx, "ScaleX");
            const double sz = positive_scale(*ctx, "ScaleY");
            if (scan.bscans.empty()) {
                scan.meta.size_x = width;
                scan.meta.size_z = height;
                scan.meta.scale_x_mm = sx;
                scan.meta.scale_z_mm = sz;
            } else if (width != scan.meta.size_x || height != scan.meta.size_z) {
                throw InputError::corrupt(path_, "OCT images of different sizes", image->offset);
            }
            BScan b;
            b.version = "XML";
            if (const XmlNode* c = ctx->find("Start/Coord")) {
                b.start_x_mm = number(*c, "X");
                b.start_y_mm = number(*c, "Y");
            }
            if (const XmlNode* c = ctx->find("End/Coord")) {
                b.end_x_mm = number(*c, "X");
                b.end_y_mm = number(*c, "Y");
            } else if (const XmlNode* centre = ctx->find("Center/Coord")) {
                b.end_x_mm = number(*centre, "X");  // circle scans: End holds the centre
                b.end_y_mm = number(*centre, "Y");
            }
            if (ctx->child("ImageQuality") != nullptr) {
                b.quality = static_cast<float>(number(*ctx, "ImageQuality"));
            }
            if (const XmlNode* segs = image->child("Segmentation")) {
                for (const XmlNode* line : segs->children_named("SegLine")) {
                    const std::string name = text_or(line->child("Name"), "");
                    const auto k = layer_from_name(name);
                    if (!k) {
                        scan.notes.push_back("segmentation line '" + name + "' ignored");
                        continue;
                    }
                    const XmlNode* array = require(*line, "Array");
                    auto values = seg_values(*array, width);
                    if (b.seg.size() <= static_cast<std::size_t>(*k)) {
                        b.seg.resize(static_cast<std::size_t>(*k) + 1,
                                     std::vector<float>(static_cast<std::size_t>(width),
                                                        std::numeric_limits<float>::quiet_NaN()));
                    }
                    b.seg[static_cast<std::size_t>(*k)] = std::move(values);
                    present.insert(*k);
                }
            }
            if (options_.pixels) {
                const std::vector<std::uint8_t> m = load_image(*image, width, height);
                b.pixels.resize(m.size());
                for (std::size_t i = 0; i < m.size(); ++i) {
                    // Inverse of the display transform v^0.25 * 255.
                    const double d = m[i] / 255.0;
                    b.pixels[i] = static_cast<float>(d * d * d * d);
                }
            }
            scan.bscans.push_back(std::move(b));
        }
        // Lines every B-scan has the same length; pad B-scans with fewer lines with NaN.
        std::size_t lines = 0;
        for (const BScan& b : scan.bscans) lines = std::max(lines, b.seg.size());
        for (BScan& b : scan.bscans) {
            b.seg.resize(lines, std::vector<float>(static_cast<std::size_t>(scan.meta.size_x),
                                                   std::numeric_limits<float>::quiet_NaN()));
        }
        std::string absent;
        for (std::size_t k = 0; k < lines; ++k) {
            if (present.count(static_cast<int>(k)) == 0) absent += " " + layer_name(static_cast<int>(k));
        }
        if (!absent.empty()) scan.notes.push_back("lines absent from the export:" + absent);
        // There is no Distance in the XML: derive it from the Start positions.
        if (scan.bscans.size() > 1) {
            const BScan& first = scan.bscans.front();
            const BScan& last = scan.bscans.back();
            scan.meta.distance_mm = std::hypot(last.start_x_mm - first.start_x_mm,
                                               last.start_y_mm - first.start_y_mm) /
                                    static_cast<double>(scan.bscans.size() - 1);
        }
    }

    ScanPattern pattern_of(const XmlNode& series, const Scan& scan) const {
        const std::string type = text_or(series.child("Type"), "");
        if (type == "Volume") return ScanPattern::kVolume;
        if (type == "Line" || type == "LineScan") return ScanPattern::kLine;
        if (type == "Circle" || type == "CircleScan") return ScanPattern::kCircle;
        if (type == "Radial" || type == "RadialScan") return ScanPattern::kRadial;
        if (scan.bscans.size() == 1) return ScanPattern::kLine;
        return ScanPattern::kUnknown;
    }

    void set_exam_time(const XmlNode& series, const XmlNode& first_oct, Scan& scan) const {
        const XmlNode* date = series.find("ReferenceSeries/ExamDate/Date");
        if (date == nullptr) return;
        const auto ole = date_of(date);
        if (!ole) return;
        double secs = 0.0;
        if (const XmlNode* t = first_oct.find("AcquisitionTime/Time")) {
            // Local time; UTCBias is minutes ahead of UTC.
            secs = number(*t, "Hour") * 3600.0 + number(*t, "Minute") * 60.0 +
                   number(*t, "Second");
            if (t->child("UTCBias") != nullptr) secs -= number(*t, "UTCBias") * 60.0;
        }
        // FILETIME: 100 ns ticks since 1601-01-01 = OLE day 0 minus 109205 days.
        const double ticks = ((*ole + 109205.0) * 86400.0 + secs) * 1e7;
        if (ticks > 0.0 && ticks < 1.8e19) {
            scan.meta.exam_time_filetime = static_cast<std::uint64_t>(std::llround(ticks));
        }
    }

    void read_grid(const XmlNode& grid, Scan& scan) const {
        ThicknessGrid g;
        g.type = static_cast<std::int32_t>(number(grid, "Type"));
        g.from_header = true;
        for (int i = 0; i < 3; ++i) {
            const std::string key = "Diameter" + std::to_string(i + 1);
            if (grid.child(key) != nullptr) g.diameters_mm[static_cast<std::size_t>(i)] = number(grid, key);
        }
        if (const XmlNode* c = grid.find("CenterPos/Coord")) {
            // Observed values (e.g. 370, 386) are localizer pixels; convert with its scale.
            // Unverified against a real export with a known centre (docs/formats.md).
            const double sx = scan.meta.scale_x_slo_mm > 0 ? scan.meta.scale_x_slo_mm : 1.0;
            const double sy = scan.meta.scale_y_slo_mm > 0 ? scan.meta.scale_y_slo_mm : 1.0;
            g.centre_x_slo_mm = number(*c, "X") * sx;
            g.centre_y_slo_mm = number(*c, "Y") * sy;
            scan.notes.push_back("XML grid centre read as localizer pixels (unverified)");
        }
        auto opt = [&](const char* key) {
            return grid.child(key) != nullptr ? static_cast<float>(number(grid, key)) : 0.0F;
        };
        g.central_thickness_mm = opt("CentralThickness");
        g.min_central_thickness_mm = opt("MinCentralThickness");
        g.max_central_thickness_mm = opt("MaxCentralThickness");
        g.total_volume_mm3 = opt("TotalVolume");
        for (const XmlNode* zone : grid.children_named("Zone")) {
            ThicknessGrid::Cell cell;
            cell.thickness_mm = static_cast<float>(number(*zone, "AvgThickness"));
            cell.volume_mm3 = static_cast<float>(number(*zone, "Volume"));
            g.cells.push_back(cell);
        }
        scan.grids.push_back(std::move(g));
    }

    std::string path_;
    ReadOptions options_;
};

}  // namespace

bool looks_like_heyex_xml(const char* head, std::size_t n) {
    return detail::xml_root_is(std::string_view(head, n), "HEDX");
}

Scan read_heyex_xml(const std::string& path, const ReadOptions& options) {
    return XmlScanReader(path, options).read();
}

}  // namespace octshape::io
