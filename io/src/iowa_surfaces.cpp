#include "octshape/io/iowa_surfaces.h"

#include <algorithm>
#include <optional>
#include <cctype>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <set>

#include "octshape/error.h"
#include "xml_dom.h"

namespace octshape::io {
namespace {

namespace fs = std::filesystem;
using detail::XmlNode;

// The largest surfaces file of a Spectralis export: 11 surfaces x 97 B-scans x 1024 A-scans at
// ~24 bytes per <y> element is ~26 MB; the cap keeps the parsed tree (~15 bytes of memory per
// byte of <y> elements) near 1 GB at worst.
constexpr std::uintmax_t kMaxBytes = 64ULL << 20U;
constexpr int kMaxAScans = 4096;   // Spectralis: 512..1536
constexpr int kMaxDepth = 4096;    // Spectralis: 496..1536
constexpr int kMaxBScans = 1024;   // Spectralis: 1..193
constexpr int kMaxSurfaces = 64;   // OCTLayerSeg writes 11
// A row further than this outside the image is not a segmentation but a broken number.
constexpr double kMaxAbsRow = 1e6;

std::string trimmed(std::string_view s) {
    const auto b = s.find_first_not_of(" \t\r\n");
    if (b == std::string_view::npos) return {};
    const auto e = s.find_last_not_of(" \t\r\n");
    return std::string(s.substr(b, e - b + 1));
}

class Parser {
public:
    explicit Parser(std::string name) : name_(std::move(name)) {}

    IowaSurfaces parse(std::string_view doc) const {
        const XmlNode root = detail::parse_xml(doc, name_);
        if (root.name != "surfaces") {
            throw InputError::unsupported(name_, "XML but not an Iowa surfaces file (root <" +
                                                     root.name + ">)");
        }
        IowaSurfaces s;
        s.format_version = text(root.child("version"));
        if (const XmlNode* exe = root.child("executable")) {
            s.executable = text(exe->child("name"));
            s.executable_version = text(exe->child("version"));
        }
        const XmlNode* sc = require(root, "scan_characteristics");
        s.manufacturer = text(sc->child("manufacturer"));
        s.center_type = text(sc->child("center_type"));
        const XmlNode* size = require(*sc, "size");
        unit_must_be(*size, "voxel");
        s.size_x = count(*size, "x", kMaxAScans);
        s.size_y = count(*size, "y", kMaxDepth);
        s.size_z = count(*size, "z", kMaxBScans);
        const XmlNode* voxel = require(*sc, "voxel_size");
        unit_must_be(*voxel, "mm");
        s.voxel_x_mm = scale(*voxel, "x");
        s.voxel_y_mm = scale(*voxel, "y");
        s.voxel_z_mm = scale(*voxel, "z");
        const std::string lat = text(sc->child("laterality"));
        if (lat == "OD" || lat == "R") {
            s.laterality = Laterality::kOD;
        } else if (lat == "OS" || lat == "L") {
            s.laterality = Laterality::kOS;
        }
        if (const XmlNode* unit = root.child("unit"); unit != nullptr && text(unit) != "voxel") {
            throw InputError::unsupported(name_, "surfaces in '" + text(unit) +
                                                     "', not in voxels", unit->offset);
        }
        if (const XmlNode* ss = root.child("surface_size")) {
            const int x = count(*ss, "x", kMaxAScans);
            const int z = count(*ss, "z", kMaxBScans);
            if (x != s.size_x || z != s.size_z) {
                throw InputError::corrupt(name_,
                                          "<surface_size> " + std::to_string(x) + " x " +
                                              std::to_string(z) + " differs from <size> " +
                                              std::to_string(s.size_x) + " x " +
                                              std::to_string(s.size_z),
                                          ss->offset);
            }
        }
        const auto surfaces = root.children_named("surface");
        if (surfaces.size() > static_cast<std::size_t>(kMaxSurfaces)) {
            throw InputError::corrupt(name_, std::to_string(surfaces.size()) + " surfaces",
                                      surfaces[kMaxSurfaces]->offset);
        }
        if (const XmlNode* num = root.child("surface_num")) {
            const int n = count(root, "surface_num", kMaxSurfaces);
            if (static_cast<std::size_t>(n) != surfaces.size()) {
                throw InputError::corrupt(name_,
                                          "<surface_num> says " + std::to_string(n) +
                                              " surfaces, the file holds " +
                                              std::to_string(surfaces.size()),
                                          num->offset);
            }
        }
        std::set<int> labels;
        for (const XmlNode* node : surfaces) {
            IowaSurface surface = read_surface(*node, s);
            if (!labels.insert(surface.label).second) {
                throw InputError::corrupt(name_,
                                          "surface label " + std::to_string(surface.label) +
                                              " appears twice",
                                          node->offset);
            }
            s.surfaces.push_back(std::move(surface));
        }
        for (const int label : {kIowaIlm, kIowaInnerRpe, kIowaOuterRpe}) {
            if (s.find(label) == nullptr) {
                throw InputError::unsupported(
                    name_, "no surface with label " + std::to_string(label) +
                               (label == kIowaIlm ? " (ILM)"
                                                  : label == kIowaInnerRpe ? " (IB_RPE)"
                                                                           : " (OB_RPE)"));
            }
        }
        if (const XmlNode* undefined = root.child("undefined_region")) {
            mark_undefined(*undefined, s);
        }
        return s;
    }

private:
    std::string name_;

    static std::string text(const XmlNode* n) { return n == nullptr ? std::string() : trimmed(n->text); }

    const XmlNode* require(const XmlNode& parent, std::string_view child) const {
        const XmlNode* n = parent.child(child);
        if (n == nullptr) {
            throw InputError::corrupt(name_,
                                      "<" + parent.name + "> has no <" + std::string(child) + ">",
                                      parent.offset);
        }
        return n;
    }

    void unit_must_be(const XmlNode& parent, std::string_view unit) const {
        const XmlNode* u = parent.child("unit");
        if (u != nullptr && text(u) != unit) {
            throw InputError::unsupported(name_,
                                          "<" + parent.name + "> in '" + text(u) + "', not " +
                                              std::string(unit),
                                          u->offset);
        }
    }

    double number(const XmlNode& n) const {
        const std::string t = trimmed(n.text);
        double v = 0.0;
        const auto [end, ec] = std::from_chars(t.data(), t.data() + t.size(), v);
        if (ec != std::errc() || end != t.data() + t.size() || !std::isfinite(v)) {
            throw InputError::corrupt(name_,
                                      "<" + n.name + "> is not a number: '" + t.substr(0, 40) + "'",
                                      n.offset);
        }
        return v;
    }

    int count(const XmlNode& parent, std::string_view child, int max) const {
        const XmlNode* n = require(parent, child);
        const double v = number(*n);
        if (v < 1.0 || v > max || v != std::floor(v)) {
            throw InputError::corrupt(name_,
                                      "<" + parent.name + "><" + std::string(child) + "> = " +
                                          trimmed(n->text).substr(0, 20) + " is not a size in 1.." +
                                          std::to_string(max),
                                      n->offset);
        }
        return static_cast<int>(v);
    }

    double scale(const XmlNode& parent, std::string_view child) const {
        const XmlNode* n = require(parent, child);
        const double v = number(*n);
        // Spectralis voxels: 3.9 um deep, 6-30 um across, B-scans 30-250 um apart (up to 2 mm
        // for sparse patterns).
        if (!(v > 0.0 && v < 10.0)) {
            throw InputError::corrupt(name_,
                                      "<voxel_size><" + std::string(child) + "> = " +
                                          trimmed(n->text).substr(0, 20) +
                                          " mm is not a plausible voxel size",
                                      n->offset);
        }
        return v;
    }

    IowaSurface read_surface(const XmlNode& node, const IowaSurfaces& s) const {
        IowaSurface out;
        const XmlNode* label = require(node, "label");
        const double l = number(*label);
        if (l < 0 || l > 1e6 || l != std::floor(l)) {
            throw InputError::corrupt(name_, "surface label '" + trimmed(label->text) +
                                                 "' is not a label", label->offset);
        }
        out.label = static_cast<int>(l);
        out.name = text(node.child("name"));
        const auto bscans = node.children_named("bscan");
        if (bscans.size() != static_cast<std::size_t>(s.size_z)) {
            throw InputError::corrupt(name_,
                                      "surface " + std::to_string(out.label) + " has " +
                                          std::to_string(bscans.size()) + " <bscan> elements, " +
                                          "<size><z> says " + std::to_string(s.size_z),
                                      node.offset);
        }
        out.depth_px.reserve(static_cast<std::size_t>(s.size_x) *
                             static_cast<std::size_t>(s.size_z));
        for (std::size_t b = 0; b < bscans.size(); ++b) {
            const auto ys = bscans[b]->children_named("y");
            if (ys.size() != static_cast<std::size_t>(s.size_x)) {
                throw InputError::corrupt(name_,
                                          "surface " + std::to_string(out.label) + ", B-scan " +
                                              std::to_string(b) + " has " +
                                              std::to_string(ys.size()) + " <y> values, " +
                                              "<size><x> says " + std::to_string(s.size_x),
                                          bscans[b]->offset);
            }
            for (const XmlNode* y : ys) {
                const double v = number(*y);
                if (std::fabs(v) > kMaxAbsRow) {
                    throw InputError::corrupt(name_,
                                              "surface " + std::to_string(out.label) +
                                                  ": row " + trimmed(y->text).substr(0, 20) +
                                                  " is not a depth",
                                              y->offset);
                }
                out.depth_px.push_back(static_cast<float>(v));
            }
        }
        return out;
    }

    void mark_undefined(const XmlNode& region, IowaSurfaces& s) const {
        for (const XmlNode* ascan : region.children_named("ascan")) {
            const double x = number(*require(*ascan, "x"));
            const double z = number(*require(*ascan, "z"));
            if (x < 0 || x >= s.size_x || z < 0 || z >= s.size_z || x != std::floor(x) ||
                z != std::floor(z)) {
                throw InputError::corrupt(name_,
                                          "undefined A-scan (" + trimmed(ascan->child("x")->text) +
                                              ", " + trimmed(ascan->child("z")->text) +
                                              ") is outside the " + std::to_string(s.size_x) +
                                              " x " + std::to_string(s.size_z) + " grid",
                                          ascan->offset);
            }
            const std::size_t i = static_cast<std::size_t>(z) * static_cast<std::size_t>(s.size_x) +
                                  static_cast<std::size_t>(x);
            for (IowaSurface& surface : s.surfaces) {
                surface.depth_px[i] = std::numeric_limits<float>::quiet_NaN();
            }
            ++s.num_undefined;
        }
    }
};

// "Outer boundary of RPE (OB_RPE)" -> "OB_RPE"; a name without parentheses as it is; an empty
// one "LABEL<n>".
std::string short_name(const IowaSurface& s) {
    const auto open = s.name.rfind('(');
    const auto close = s.name.rfind(')');
    if (open != std::string::npos && close != std::string::npos && close > open + 1) {
        return trimmed(std::string_view(s.name).substr(open + 1, close - open - 1));
    }
    if (!s.name.empty()) return s.name;
    return "LABEL" + std::to_string(s.label);
}

// The lines in scan order: ILM, BM, then the others in file order.
std::vector<const IowaSurface*> scan_order(const IowaSurfaces& s, IowaBm bm) {
    std::vector<const IowaSurface*> lines = {s.find(kIowaIlm), s.find(label_of(bm))};
    for (const IowaSurface& surface : s.surfaces) {
        if (surface.label != kIowaIlm && surface.label != label_of(bm)) lines.push_back(&surface);
    }
    return lines;
}

void set_lines(Scan& scan, const IowaSurfaces& s, IowaBm bm) {
    const auto lines = scan_order(s, bm);
    scan.line_names.clear();
    for (std::size_t k = 0; k < lines.size(); ++k) {
        scan.line_names.push_back(k == 0 ? "ILM" : k == 1 ? "BM" : short_name(*lines[k]));
    }
    const auto nx = static_cast<std::size_t>(s.size_x);
    for (std::size_t b = 0; b < scan.bscans.size(); ++b) {
        BScan& bs = scan.bscans[b];
        bs.seg.assign(lines.size(), {});
        for (std::size_t k = 0; k < lines.size(); ++k) {
            const auto first = lines[k]->depth_px.begin() + static_cast<std::ptrdiff_t>(b * nx);
            bs.seg[k].assign(first, first + static_cast<std::ptrdiff_t>(nx));
        }
    }
}

// A Zeiss Cirrus cube protocol OCTExplorer segments, from the file's manufacturer, sizes and
// centre type; nullopt for anything else.
std::optional<std::string_view> cirrus_protocol(const IowaSurfaces& s) {
    std::string maker = s.manufacturer;
    std::transform(maker.begin(), maker.end(), maker.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    if (maker.find("zeiss") == std::string::npos) return std::nullopt;
    const bool onh = s.center_type == "onh" || s.center_type == "optic disc";
    if (s.size_x == 512 && s.size_z == 128 && !onh) return "512 x 128 macular cube";
    if (s.size_x == 200 && s.size_z == 200) {
        return onh ? std::string_view("200 x 200 optic disc cube")
                   : std::string_view("200 x 200 macular cube");
    }
    return std::nullopt;
}

// B-scan positions of a Cirrus cube on a fundus frame (mm, x right, y down): B-scan 0 at the
// inferior edge, A-scan 0 at the right (each B-scan runs right to left as OCTExplorer stores
// Cirrus cubes). Established on the real cube's thickness asymmetry: docs/formats.md.
void place_cirrus_bscans(Scan& scan) {
    const ScanMeta& m = scan.meta;
    const double width = (m.size_x - 1) * m.scale_x_mm;
    const std::size_t n = scan.bscans.size();
    for (std::size_t b = 0; b < n; ++b) {
        BScan& bs = scan.bscans[b];
        bs.start_x_mm = width;
        bs.end_x_mm = 0.0;
        bs.start_y_mm = bs.end_y_mm = static_cast<double>(n - 1 - b) * m.distance_mm;
    }
}

std::string source_note(const IowaSurfaces& s, IowaBm bm) {
    return "segmentation: " + s.describe() + ", BM = " + std::string(to_string(bm)) +
           " (label " + std::to_string(label_of(bm)) + ")" +
           (s.num_undefined > 0 ? ", " + std::to_string(s.num_undefined) + " undefined A-scans"
                                : std::string());
}

}  // namespace

std::string_view to_string(IowaBm bm) { return bm == IowaBm::kOuterRpe ? "ob_rpe" : "ib_rpe"; }

IowaBm parse_iowa_bm(std::string_view s) {
    if (s == "ob_rpe") return IowaBm::kOuterRpe;
    if (s == "ib_rpe") return IowaBm::kInnerRpe;
    throw UsageError("BM surface must be ob_rpe or ib_rpe, not '" + std::string(s) + "'");
}

int label_of(IowaBm bm) { return bm == IowaBm::kOuterRpe ? kIowaOuterRpe : kIowaInnerRpe; }

const IowaSurface* IowaSurfaces::find(int label) const {
    for (const IowaSurface& s : surfaces) {
        if (s.label == label) return &s;
    }
    return nullptr;
}

std::string IowaSurfaces::describe() const {
    std::string out = executable.empty() ? std::string("Iowa") : executable;
    if (!executable_version.empty()) out += " " + executable_version;
    out += " surfaces";
    if (!format_version.empty()) out += " (format " + format_version + ")";
    return out;
}

bool looks_like_iowa_surfaces(const char* head, std::size_t n) {
    return detail::xml_root_is(std::string_view(head, n), "surfaces");
}

IowaSurfaces parse_iowa_surfaces(std::string_view doc, const std::string& name) {
    return Parser(name).parse(doc);
}

IowaSurfaces read_iowa_surfaces(const std::string& path) {
    return parse_iowa_surfaces(detail::read_whole_file(path, kMaxBytes, "surfaces file"), path);
}

Scan iowa_scan(const IowaSurfaces& s, const std::string& path, IowaBm bm) {
    Scan scan;
    scan.source_path = path;
    ScanMeta& m = scan.meta;
    m.format = SourceFormat::kIowaSurfaces;
    m.version = "Iowa surfaces XML (" + s.describe() + ")";
    m.size_x = s.size_x;
    m.size_z = s.size_y;
    m.scale_x_mm = s.voxel_x_mm;
    m.scale_z_mm = s.voxel_y_mm;
    m.distance_mm = s.size_z > 1 ? s.voxel_z_mm : 0.0;
    m.laterality = s.laterality;
    m.scan_position_raw = std::string(to_string(s.laterality));
    m.pattern = s.size_z > 1 ? ScanPattern::kVolume : ScanPattern::kLine;
    m.scan_pattern_code = static_cast<std::int32_t>(m.pattern);
    scan.bscans.resize(static_cast<std::size_t>(s.size_z));
    set_lines(scan, s, bm);
    scan.notes.push_back(source_note(s, bm));
    if (const auto protocol = cirrus_protocol(s)) {
        place_cirrus_bscans(scan);
        scan.notes.push_back("Zeiss Cirrus " + std::string(*protocol) +
                             ": B-scans placed in the protocol's orientation as OCTExplorer "
                             "stores it (docs/formats.md)");
    } else {
        scan.notes.push_back(
            "no B-scan positions (a segmentation without its export): a regular grid is "
            "assumed, B-scans " + std::to_string(s.voxel_z_mm) + " mm apart");
    }
    if (s.laterality == Laterality::kUnknown) scan.notes.push_back("laterality not stated");
    return scan;
}

void apply_segmentation(Scan& scan, const Scan& seg) {
    const std::string both = seg.source_path + ": not a segmentation of " + scan.source_path + ": ";
    auto differs = [&](const std::string& what, const std::string& ours,
                       const std::string& theirs) {
        throw UsageError(both + what + " " + ours + " in the segmentation, " + theirs +
                         " in the export");
    };
    const ScanMeta& s = seg.meta;
    if (s.size_x != scan.meta.size_x) {
        differs("A-scans per B-scan", std::to_string(s.size_x), std::to_string(scan.meta.size_x));
    }
    if (s.size_z != scan.meta.size_z) {
        differs("pixels per A-scan", std::to_string(s.size_z), std::to_string(scan.meta.size_z));
    }
    if (seg.num_bscans() != scan.num_bscans()) {
        differs("B-scans", std::to_string(seg.num_bscans()), std::to_string(scan.num_bscans()));
    }
    if (s.laterality != Laterality::kUnknown && scan.meta.laterality != Laterality::kUnknown &&
        s.laterality != scan.meta.laterality) {
        differs("eye", std::string(to_string(s.laterality)),
                std::string(to_string(scan.meta.laterality)));
    }
    // Iowa files store 6 decimals (0.003872 for 0.0038716 mm): 1 % is far above that rounding
    // and far below the difference between any two Spectralis protocols' scales.
    auto scale_differs = [&](const char* what, double ours, double theirs) {
        if (theirs > 0.0 && std::fabs(ours - theirs) > 0.01 * theirs) {
            differs(what, std::to_string(ours) + " mm", std::to_string(theirs) + " mm");
        }
    };
    scale_differs("A-scan spacing", s.scale_x_mm, scan.meta.scale_x_mm);
    scale_differs("pixel height", s.scale_z_mm, scan.meta.scale_z_mm);
    if (seg.num_bscans() > 1) scale_differs("B-scan spacing", s.distance_mm, scan.meta.distance_mm);
    for (std::size_t b = 0; b < scan.bscans.size(); ++b) scan.bscans[b].seg = seg.bscans[b].seg;
    scan.line_names = seg.line_names;
    const std::string source = seg.notes.empty() ? s.version : seg.notes.front();
    scan.notes.push_back(source + ", over the export's geometry");
}

}  // namespace octshape::io
