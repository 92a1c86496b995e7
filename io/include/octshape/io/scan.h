#pragma once
// The format-neutral scan model every reader fills and every analysis reads.
//
// Conventions (docs/coordinates.md):
//  * Segmentation values are depths in pixels from the top of the B-scan. A value the device
//    marks invalid (non-finite, or >= 1e30, FLT_MAX in practice) is stored as quiet NaN and is
//    *missing*: use `is_valid()` and never use a NaN as a number.
//  * Pixels are linear reflectance (f32, as in .vol). `kNoPixelData` (FLT_MAX) marks "no data"
//    and is kept as is so that write -> read is bit exact.
//  * Start/End of a B-scan are in mm on the SLO image (origin top-left, x right, y down).
//  * Nothing here converts to the anatomical frame: that is libretina's ScanGeometry.

#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace octshape::io {

inline constexpr float kNoPixelData = std::numeric_limits<float>::max();
// Device threshold: values at or above it (FLT_MAX in practice) mean "invalid".
inline constexpr float kInvalidThreshold = 1e30F;

// True when a raw segmentation value from a file is a usable number.
[[nodiscard]] inline bool is_valid_raw(float v) {
    return std::isfinite(v) && v < kInvalidThreshold && v > -kInvalidThreshold;
}
// True when a stored segmentation value (NaN = missing) is present.
[[nodiscard]] inline bool is_valid(float v) { return !std::isnan(v); }

enum class Laterality { kUnknown, kOD, kOS };
enum class SourceFormat { kVol, kHeyexXml, kIowaSurfaces, kTopcon };

// .vol ScanPattern codes.
enum class ScanPattern : std::int32_t {
    kUnknown = 0,
    kLine = 1,
    kCircle = 2,
    kVolume = 3,
    kFastVolume = 4,
    kRadial = 5,
    kRadialCircles = 6,
};

// Boundary (segmentation line) index as stored in .vol: line k of a B-scan header.
enum class Layer : int {
    kILM = 0, kBM = 1, kRNFL = 2, kGCL = 3, kIPL = 4, kINL = 5, kOPL = 6, kONL = 7, kELM = 8,
    kIOS = 9, kOPT = 10, kCHO = 11, kVIT = 12, kANT = 13, kPR1 = 14, kPR2 = 15, kRPE = 16,
};
inline constexpr int kNumKnownLayers = 17;

// "ILM", "BM", ... for a line index; "LINE<k>" beyond the known ones.
[[nodiscard]] std::string layer_name(int index);
// Index of a boundary name as used in .vol docs and Heidelberg XML (case-insensitive; accepts
// the aliases "EZ" for PR1 and "IZ" for PR2). nullopt for an unknown name.
[[nodiscard]] std::optional<int> layer_from_name(std::string_view name);

[[nodiscard]] std::string_view to_string(Laterality l);
[[nodiscard]] std::string_view to_string(ScanPattern p);
[[nodiscard]] std::string_view to_string(SourceFormat f);
// Pattern from a raw code; codes outside 0..6 give kUnknown.
[[nodiscard]] ScanPattern scan_pattern_from_code(std::int32_t code);

// Private data: never printed above debug level, never written unless the user asks.
struct Identifiers {
    std::string id;            // ID
    std::string reference_id;  // ReferenceID
    std::uint32_t pid = 0;     // PID (v101+)
    std::string patient_id;    // PatientID (v101+)
    std::optional<double> dob_ole;  // date of birth, OLE date (days since 1899-12-30)
    std::uint32_t vid = 0;          // VID
    std::string visit_id;           // VisitID
};

// A device thickness grid (ETDRS circles or a rectangular grid).
struct ThicknessGrid {
    struct Cell {
        float thickness_mm = 0.0F;
        float volume_mm3 = 0.0F;
    };
    std::int32_t type = 0;           // 1..3 circular, 8..10 rectangular
    std::uint64_t file_offset = 0;   // where it was read (0 for XML)
    bool from_header = true;         // false: found after the last B-scan with GridType 0
    // Circular grids (types 1..3).
    std::array<double, 3> diameters_mm{};
    float central_thickness_mm = 0.0F;
    float min_central_thickness_mm = 0.0F;
    float max_central_thickness_mm = 0.0F;
    float total_volume_mm3 = 0.0F;
    // Rectangular grids (types 8..10).
    std::int32_t rows = 0;
    std::int32_t cols = 0;
    float cell_width_mm = 0.0F;
    float cell_height_mm = 0.0F;
    float tilt = 0.0F;
    // Both: the centre on the SLO (mm) and the cells (9 sectors C0,N1,N2,S1,S2,T1,T2,I1,I2 for
    // circular grids, order unverified; rows*cols row-major for rectangular ones).
    double centre_x_slo_mm = 0.0;
    double centre_y_slo_mm = 0.0;
    std::vector<Cell> cells;

    [[nodiscard]] bool is_circular() const { return type >= 1 && type <= 3; }
    [[nodiscard]] bool is_rectangular() const { return type >= 8 && type <= 10; }
};

// HSF-OCT-104 B-scan header fields whose meaning is unverified (no public 104 file exists).
struct BmoFields {
    std::array<std::int32_t, 3> left{};
    std::array<std::int32_t, 3> right{};
};

struct BScan {
    std::string version = "HSF-BS-103";  // B-scan header magic
    double start_x_mm = 0.0;  // SLO coordinates of the first A-scan
    double start_y_mm = 0.0;
    double end_x_mm = 0.0;    // of the last A-scan (circle scans: the centre)
    double end_y_mm = 0.0;
    std::int32_t off_seg = 256;  // byte offset of the segmentation inside the header
    float quality = 0.0F;        // v101+
    std::int32_t shift = 0;      // v102+ (circle scans)
    std::array<float, 6> iv_trafo{};   // v103+
    std::optional<BmoFields> bmo;      // v104 only, unverified
    // seg[k][a]: depth (pixels from the top) of boundary k (see Layer) at A-scan a; NaN = missing.
    std::vector<std::vector<float>> seg;
    // size_z rows x size_x columns, row-major; empty unless pixels were loaded.
    std::vector<float> pixels;
    // Rows by which the segmentation lines lie deeper than the same content in the pixels (0 as
    // read): the sub-row residual that ONH axial registration leaves when it moves the lines by
    // the shift and the pixels by whole rows. What is found in the pixels lies this much deeper
    // in the lines' (registered) frame.
    double line_offset_px = 0.0;

    [[nodiscard]] int num_seg() const { return static_cast<int>(seg.size()); }
    [[nodiscard]] bool has_line(int k) const { return k >= 0 && k < num_seg(); }
};

struct ScanMeta {
    SourceFormat format = SourceFormat::kVol;
    std::string version;            // "HSF-OCT-103", or the XML export's description
    int size_x = 0;                 // A-scans per B-scan
    int size_z = 0;                 // pixels per A-scan
    double scale_x_mm = 0.0;        // mm per A-scan (circle scans: circumference / size_x)
    double scale_z_mm = 0.0;        // mm per pixel in depth
    double distance_mm = 0.0;       // mm between B-scans as the header states (0: line/circle)
    int size_x_slo = 0;
    int size_y_slo = 0;
    double scale_x_slo_mm = 0.0;
    double scale_y_slo_mm = 0.0;
    std::uint32_t field_size_slo_deg = 0;
    double scan_focus_dpt = 0.0;
    Laterality laterality = Laterality::kUnknown;
    std::string scan_position_raw;  // "OD"/"OS" as stored
    ScanPattern pattern = ScanPattern::kUnknown;
    std::int32_t scan_pattern_code = 0;
    std::optional<std::uint64_t> exam_time_filetime;  // 100 ns since 1601-01-01 UTC
    std::optional<double> visit_date_ole;             // days since 1899-12-30
    Identifiers ids;
    // .vol bookkeeping kept for exact round trips.
    std::uint32_t bscan_hdr_size = 0;
    std::int32_t grid_type = 0;
    std::int32_t grid_offset = 0;
    std::int32_t grid_type1 = 0;
    std::int32_t grid_offset1 = 0;
    std::string prog_id;
};

struct Scan {
    std::string source_path;
    ScanMeta meta;
    std::vector<BScan> bscans;
    std::vector<std::uint8_t> slo;  // size_y_slo x size_x_slo, row-major; empty unless loaded
    std::vector<ThicknessGrid> grids;
    bool pixels_loaded = false;
    std::vector<std::string> notes;  // what the reader noticed (unverified fields, odd files)
    // Names of the segmentation lines when they are not Heidelberg's (a segmentation from
    // elsewhere, io/iowa_surfaces.h): line_names[k] names line k; empty = layer_name(k).
    std::vector<std::string> line_names;

    [[nodiscard]] int num_bscans() const { return static_cast<int>(bscans.size()); }
    // Number of segmentation lines present in every B-scan (the minimum over B-scans).
    [[nodiscard]] int num_lines() const;
    // Fraction of valid values of line k over all B-scans and A-scans; 0 if absent.
    [[nodiscard]] double valid_fraction(int k) const;
    // Depth in pixels of line k at (B-scan b, A-scan a); NaN if missing or absent.
    [[nodiscard]] float depth_px(int k, int b, int a) const;
    // The name of line k: line_names[k] when given, else layer_name(k).
    [[nodiscard]] std::string line_name(int k) const;
    // The index of the line with this name (line_names, else the Heidelberg names and aliases
    // of layer_from_name; case-insensitive), or nullopt.
    [[nodiscard]] std::optional<int> find_line(std::string_view name) const;
};

// Moves the content of a B-scan by `dz_px` pixels deeper and `dx_px` A-scans towards higher
// A-scan indices (both may be fractional or negative): the pixels (size_z rows x size_x columns,
// if loaded) by linear interpolation with the edge rows and columns repeated, and every
// segmentation line with them (depths + dz_px, values resampled along the A-scans: linearly
// between present values, the nearer sample next to a missing one). What an eye's axial
// motion does to a B-scan (acquisition phantoms) and what axial registration undoes.
void shift_bscan(BScan& bscan, int size_x, int size_z, double dz_px, double dx_px = 0.0);

// Calendar conversions for the two date encodings used by the exports; ISO 8601 text (UTC).
[[nodiscard]] std::string filetime_to_iso(std::uint64_t filetime);
[[nodiscard]] std::string ole_date_to_iso_date(double ole_days);
// Days since 1970-01-01 of a proleptic Gregorian date (month 1..12, day 1..31).
[[nodiscard]] long long days_from_civil(long long y, unsigned m, unsigned d);

}  // namespace octshape::io

namespace octshape::io {

// What a reader loads. Headers, positions, grids and segmentation are always read (cheap);
// B-scan pixels and the SLO image only when asked (a 61-B-scan volume holds ~93 MB of pixels).
// Which Iowa surface (io/iowa_surfaces.h) plays Bruch's membrane, the BM line of a Heidelberg
// export: the outer boundary of the RPE (label 150) by default, where Heidelberg's own BM line
// runs (Bruch's membrane is the outer edge of the RPE/Bruch's complex); the inner boundary
// (label 140) runs one RPE thickness further in (docs/formats.md "Iowa surfaces XML").
enum class IowaBm { kOuterRpe, kInnerRpe };

struct ReadOptions {
    bool pixels = false;
    IowaBm iowa_bm = IowaBm::kOuterRpe;  // an Iowa surfaces file read alone
};

}  // namespace octshape::io
