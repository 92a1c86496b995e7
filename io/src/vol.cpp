#include "octshape/io/vol.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <istream>
#include <limits>
#include <optional>
#include <ostream>
#include <string_view>
#include <tuple>
#include <utility>
#include <vector>

#include "octshape/io/atomic_file.h"
#include "octshape/error.h"

// Layout, version branches and every validation rule below are documented in docs/formats.md;
// keep the two in step.

namespace octshape::io {
namespace {

using Byte = unsigned char;

constexpr std::string_view kMagicPrefix = "HSF-OCT-";
constexpr std::string_view kBScanMagicPrefix = "HSF-BS-";
constexpr int kMinVersion = 100;
constexpr int kMaxVersion = 104;
constexpr int kWriteVersion = 103;

// Plausibility bounds. They are far beyond any Spectralis setting (at most 1536 A-scans,
// 1536 B-scans, 496/768 px per A-scan, a 1536 px SLO, fields of view under 15 mm), and keep
// every size product inside 64 bits: 2048 + 2^28 + 2^16 * (2^26 + 2^16 * 2^16 * 4) < 2^52.
constexpr std::uint32_t kMaxSizeX = 1U << 16;
constexpr std::uint32_t kMaxSizeZ = 1U << 16;
constexpr std::uint32_t kMaxBScans = 1U << 16;
constexpr std::uint32_t kMaxSloSide = 1U << 14;
constexpr std::uint32_t kMaxBScanHdrSize = 1U << 26;
constexpr double kMaxScaleXmm = 10.0;    // mm per A-scan
constexpr double kMaxScaleZmm = 1.0;     // mm per pixel
constexpr double kMaxDistanceMm = 10.0;  // mm between B-scans
constexpr double kMaxSloScaleMm = 10.0;  // mm per SLO pixel
constexpr std::uint32_t kMaxFieldSizeDeg = 360;
constexpr double kMaxFocusDpt = 100.0;
constexpr double kMaxPositionMm = 1000.0;  // |Start/End/centre| on the SLO
constexpr double kMaxGridDiameterMm = 100.0;
constexpr std::int32_t kMaxGridSide = 1024;
// OLE dates of years 100..9999 (the OLE automation date range); FILETIME before year 9999.
constexpr double kMinOleDate = -657434.0;
constexpr double kMaxOleDate = 2958465.0;
constexpr std::uint64_t kMaxFiletime = 2650467743990000000ULL;

// Fixed B-scan header fields end here, per version (Quality 101+, Shift 102+, IVTrafo 103+,
// BMO 104).
constexpr std::uint32_t bscan_fixed_end(int version) {
    switch (version) {
        case 100:
            return 56;
        case 101:
            return 60;
        case 102:
            return 64;
        case 103:
            return 88;
        default:
            return 112;
    }
}

// File header field offsets.
namespace fh {
constexpr std::size_t kVersion = 0, kSizeX = 12, kNumBScans = 16, kSizeZ = 20, kScaleX = 24,
                      kDistance = 32, kScaleZ = 40, kSizeXSlo = 48, kSizeYSlo = 52, kScaleXSlo = 56,
                      kScaleYSlo = 64, kFieldSizeSlo = 72, kScanFocus = 76, kScanPosition = 84,
                      kExamTime = 88, kScanPattern = 96, kBScanHdrSize = 100, kId = 104,
                      kReferenceId = 120, kPid = 136, kPatientId = 140, kDob = 164, kVid = 172,
                      kVisitId = 176, kVisitDate = 200, kGridType = 208, kGridOffset = 212,
                      kGridType1 = 216, kGridOffset1 = 220, kProgId = 224;
constexpr std::size_t kIdLen = 16, kPatientIdLen = 24, kVisitIdLen = 24, kProgIdLen = 34;
}  // namespace fh

// B-scan header field offsets.
namespace bh {
constexpr std::size_t kVersion = 0, kHdrSize = 12, kStartX = 16, kStartY = 24, kEndX = 32,
                      kEndY = 40, kNumSeg = 48, kOffSeg = 52, kQuality = 56, kShift = 60,
                      kIvTrafo = 64, kBmoLeft = 88, kBmoRight = 100;
}  // namespace bh

// Thickness grid field offsets, from the start of the grid (the reader, its checks and the
// writer all use these). Circular (ETDRS, types 1-3): type, three diameters, the centre on the
// SLO, central/min/max thickness, total volume, then 9 cells of (thickness, volume).
// Rectangular (types 8-10): type, rows, cols, cell size, tilt, centre, then rows x cols cells.
namespace gh {
constexpr std::size_t kType = 0;
constexpr std::size_t kDiameters = 4;  // 3 x f64
constexpr std::size_t kCentreX = 28, kCentreY = 36;
constexpr std::size_t kCentralThickness = 44, kMinCentralThickness = 48,
                      kMaxCentralThickness = 52, kTotalVolume = 56;
constexpr std::size_t kCircularCells = 60;  // 9 x (f32 thickness, f32 volume)
constexpr std::size_t kRows = 4, kCols = 8, kCellWidth = 12, kCellHeight = 16, kTilt = 20,
                      kRectCentreX = 24, kRectCentreY = 32;
constexpr std::size_t kRectCells = 40;  // rows x cols x (f32 thickness, f32 volume)
constexpr std::size_t kCellBytes = 8, kCellVolume = 4;  // one cell; its volume after the thickness
}  // namespace gh

constexpr std::size_t kCircularGridCells = 9;
constexpr std::size_t kCircularGridSize = gh::kCircularCells + kCircularGridCells * gh::kCellBytes;
constexpr std::size_t kRectGridHeaderSize = gh::kRectCells;
static_assert(kCircularGridSize == 132 && kRectGridHeaderSize == 40);

// ---- little-endian access -------------------------------------------------------------------

std::uint32_t load_u32(const Byte* p) {
    return static_cast<std::uint32_t>(p[0]) | (static_cast<std::uint32_t>(p[1]) << 8U) |
           (static_cast<std::uint32_t>(p[2]) << 16U) | (static_cast<std::uint32_t>(p[3]) << 24U);
}
std::uint64_t load_u64(const Byte* p) {
    return static_cast<std::uint64_t>(load_u32(p)) |
           (static_cast<std::uint64_t>(load_u32(p + 4)) << 32U);
}
std::int32_t load_i32(const Byte* p) { return std::bit_cast<std::int32_t>(load_u32(p)); }
float load_f32(const Byte* p) { return std::bit_cast<float>(load_u32(p)); }
double load_f64(const Byte* p) { return std::bit_cast<double>(load_u64(p)); }

void store_u32(Byte* p, std::uint32_t v) {
    for (int i = 0; i < 4; ++i) p[i] = static_cast<Byte>(v >> (8U * static_cast<unsigned>(i)));
}
void store_u64(Byte* p, std::uint64_t v) {
    store_u32(p, static_cast<std::uint32_t>(v));
    store_u32(p + 4, static_cast<std::uint32_t>(v >> 32U));
}
void store_i32(Byte* p, std::int32_t v) { store_u32(p, std::bit_cast<std::uint32_t>(v)); }
void store_f32(Byte* p, float v) { store_u32(p, std::bit_cast<std::uint32_t>(v)); }
void store_f64(Byte* p, double v) { store_u64(p, std::bit_cast<std::uint64_t>(v)); }

// f32 arrays are read and written in bulk; on a big-endian host each value is byte-swapped.
void fix_endian(float* v, std::size_t n) {
    if constexpr (std::endian::native == std::endian::big) {
        for (std::size_t i = 0; i < n; ++i) {
            v[i] = load_f32(reinterpret_cast<const Byte*>(&v[i]));
        }
    } else {
        (void)v;
        (void)n;
    }
}

// A NUL-terminated string inside a fixed-size field (the whole field if there is no NUL).
std::string load_string(const Byte* p, std::size_t len) {
    std::size_t n = 0;
    while (n < len && p[n] != 0) ++n;
    return {reinterpret_cast<const char*>(p), n};
}
// Same, with non-printable bytes replaced so that the text is safe to print.
std::string load_printable(const Byte* p, std::size_t len) {
    std::string s = load_string(p, len);
    for (char& c : s) {
        const auto u = static_cast<unsigned char>(c);
        if (u < 0x20 || u > 0x7e) c = '?';
    }
    return s;
}

// Shows at most `n` bytes of a magic as text with escapes, for an error message.
std::string quote_bytes(const Byte* p, std::size_t n) {
    static constexpr char kHex[] = "0123456789abcdef";
    std::string s = "\"";
    for (std::size_t i = 0; i < n; ++i) {
        const Byte c = p[i];
        if (c == 0) break;
        if (c >= 0x20 && c <= 0x7e && c != '"' && c != '\\') {
            s += static_cast<char>(c);
        } else {
            s += "\\x";
            s += kHex[c >> 4U];
            s += kHex[c & 0xFU];
        }
    }
    // Trailing padding spaces carry no information.
    while (s.size() > 1 && s.back() == ' ') s.pop_back();
    return s + "\"";
}

std::string num(double v) {
    char buf[40];
    std::snprintf(buf, sizeof buf, "%.9g", v);
    return buf;
}

// ---- value checks shared by the reader (-> InputError::corrupt) and the writer (-> UsageError)

struct Problem {
    std::string reason;
    std::size_t field_offset = 0;  // within the structure checked
};

std::optional<Problem> check_range(double v,
                                   double lo,
                                   double hi,
                                   bool lo_inclusive,
                                   const char* field,
                                   std::size_t off,
                                   const char* unit) {
    const bool ok = std::isfinite(v) && (lo_inclusive ? v >= lo : v > lo) && v <= hi;
    if (ok) return std::nullopt;
    return Problem{std::string(field) + " = " + num(v) + " " + unit + " is not in " +
                       (lo_inclusive ? "[" : "(") + num(lo) + ", " + num(hi) + "]",
                   off};
}

template <typename T>
std::optional<Problem> check_count(T v, T lo, T hi, const char* field, std::size_t off) {
    if (v >= lo && v <= hi) return std::nullopt;
    return Problem{std::string(field) + " = " + std::to_string(v) + " is not in " +
                       std::to_string(lo) + ".." + std::to_string(hi),
                   off};
}

// File-header values that must hold for a file to be read (sizes, scales). The size of the
// stream is checked separately.
std::optional<Problem> check_file_header(std::uint32_t size_x,
                                         std::uint32_t num_bscans,
                                         std::uint32_t size_z,
                                         const ScanMeta& m) {
    if (auto p = check_count<std::uint32_t>(size_x, 1, kMaxSizeX, "SizeX", fh::kSizeX)) return p;
    if (auto p =
            check_count<std::uint32_t>(num_bscans, 1, kMaxBScans, "NumBScans", fh::kNumBScans)) {
        return p;
    }
    if (auto p = check_count<std::uint32_t>(size_z, 1, kMaxSizeZ, "SizeZ", fh::kSizeZ)) return p;
    if (auto p = check_range(m.scale_x_mm, 0.0, kMaxScaleXmm, false, "ScaleX", fh::kScaleX, "mm")) {
        return p;
    }
    if (auto p = check_range(m.distance_mm, 0.0, kMaxDistanceMm, true, "Distance", fh::kDistance,
                             "mm")) {
        return p;
    }
    if (auto p = check_range(m.scale_z_mm, 0.0, kMaxScaleZmm, false, "ScaleZ", fh::kScaleZ, "mm")) {
        return p;
    }
    const auto xs = static_cast<std::uint32_t>(m.size_x_slo);
    const auto ys = static_cast<std::uint32_t>(m.size_y_slo);
    if (auto p = check_count<std::uint32_t>(xs, 0, kMaxSloSide, "SizeXSlo", fh::kSizeXSlo)) {
        return p;
    }
    if (auto p = check_count<std::uint32_t>(ys, 0, kMaxSloSide, "SizeYSlo", fh::kSizeYSlo)) {
        return p;
    }
    if (auto p = check_range(m.scale_x_slo_mm, 0.0, kMaxSloScaleMm, true, "ScaleXSlo",
                             fh::kScaleXSlo, "mm")) {
        return p;
    }
    if (auto p = check_range(m.scale_y_slo_mm, 0.0, kMaxSloScaleMm, true, "ScaleYSlo",
                             fh::kScaleYSlo, "mm")) {
        return p;
    }
    if (auto p = check_count<std::uint32_t>(m.field_size_slo_deg, 0, kMaxFieldSizeDeg,
                                            "FieldSizeSlo", fh::kFieldSizeSlo)) {
        return p;
    }
    if (auto p = check_range(m.scan_focus_dpt, -kMaxFocusDpt, kMaxFocusDpt, true, "ScanFocus",
                             fh::kScanFocus, "dpt")) {
        return p;
    }
    return std::nullopt;
}

// B-scan header values; `hdr_size` is the file's BScanHdrSize, `version` the file version.
std::optional<Problem> check_bscan_header(const BScan& b,
                                          std::int64_t num_seg,
                                          std::uint32_t size_x,
                                          std::uint32_t hdr_size,
                                          int version) {
    const std::array<std::pair<double, const char*>, 4> pos = {{{b.start_x_mm, "StartX"},
                                                                {b.start_y_mm, "StartY"},
                                                                {b.end_x_mm, "EndX"},
                                                                {b.end_y_mm, "EndY"}}};
    for (std::size_t i = 0; i < pos.size(); ++i) {
        if (auto p = check_range(pos[i].first, -kMaxPositionMm, kMaxPositionMm, true, pos[i].second,
                                 bh::kStartX + 8 * i, "mm")) {
            return p;
        }
    }
    if (num_seg < 0) {
        return Problem{"NumSeg = " + std::to_string(num_seg) + " is negative", bh::kNumSeg};
    }
    const std::uint32_t fixed_end = bscan_fixed_end(version);
    if (b.off_seg < static_cast<std::int64_t>(fixed_end) ||
        b.off_seg > static_cast<std::int64_t>(hdr_size)) {
        return Problem{"OffSeg = " + std::to_string(b.off_seg) + " is outside the B-scan header (" +
                           std::to_string(fixed_end) + ".." + std::to_string(hdr_size) + ")",
                       bh::kOffSeg};
    }
    // num_seg < 2^31, size_x <= 2^16: the product fits easily in 64 bits.
    const std::uint64_t seg_bytes = static_cast<std::uint64_t>(num_seg) * size_x * sizeof(float);
    if (seg_bytes > hdr_size - static_cast<std::uint64_t>(b.off_seg)) {
        return Problem{"NumSeg = " + std::to_string(num_seg) + " lines of " +
                           std::to_string(size_x) + " A-scans at OffSeg " +
                           std::to_string(b.off_seg) + " do not fit in BScanHdrSize " +
                           std::to_string(hdr_size),
                       bh::kNumSeg};
    }
    // Quality and IVTrafo: finite and below the device's invalid marker (FLT_MAX).
    if (version >= 101 && !is_valid_raw(b.quality)) {
        return Problem{"Quality = " + num(b.quality) + " is not a finite number", bh::kQuality};
    }
    if (version >= 103) {
        for (std::size_t i = 0; i < b.iv_trafo.size(); ++i) {
            if (!is_valid_raw(b.iv_trafo[i])) {
                return Problem{"IVTrafo[" + std::to_string(i) + "] = " + num(b.iv_trafo[i]) +
                                   " is not a finite number",
                               bh::kIvTrafo + 4 * i};
            }
        }
    }
    return std::nullopt;
}

// Grid values other than the cells: diameters, centre, rectangular cell geometry.
std::optional<Problem> check_grid(const ThicknessGrid& g) {
    if (g.is_circular()) {
        for (std::size_t i = 0; i < 3; ++i) {
            if (auto p = check_range(g.diameters_mm[i], 0.0, kMaxGridDiameterMm, true,
                                     "grid diameter", gh::kDiameters + 8 * i, "mm")) {
                return p;
            }
        }
        if (auto p = check_range(g.centre_x_slo_mm, -kMaxPositionMm, kMaxPositionMm, true,
                                 "grid CenterPos X", gh::kCentreX, "mm")) {
            return p;
        }
        if (auto p = check_range(g.centre_y_slo_mm, -kMaxPositionMm, kMaxPositionMm, true,
                                 "grid CenterPos Y", gh::kCentreY, "mm")) {
            return p;
        }
        return std::nullopt;
    }
    if (g.is_rectangular()) {
        if (auto p = check_count<std::int32_t>(g.rows, 1, kMaxGridSide, "grid rows", gh::kRows))
            return p;
        if (auto p = check_count<std::int32_t>(g.cols, 1, kMaxGridSide, "grid cols", gh::kCols))
            return p;
        if (auto p = check_range(g.cell_width_mm, 0.0, kMaxGridDiameterMm, true, "grid cell width",
                                 gh::kCellWidth, "mm")) {
            return p;
        }
        if (auto p = check_range(g.cell_height_mm, 0.0, kMaxGridDiameterMm, true,
                                 "grid cell height", gh::kCellHeight, "mm")) {
            return p;
        }
        if (!std::isfinite(g.tilt)) return Problem{"grid tilt is not finite", gh::kTilt};
        if (auto p = check_range(g.centre_x_slo_mm, -kMaxPositionMm, kMaxPositionMm, true,
                                 "grid centre X", gh::kRectCentreX, "mm")) {
            return p;
        }
        if (auto p = check_range(g.centre_y_slo_mm, -kMaxPositionMm, kMaxPositionMm, true,
                                 "grid centre Y", gh::kRectCentreY, "mm")) {
            return p;
        }
        return std::nullopt;
    }
    return Problem{"grid type " + std::to_string(g.type) +
                       " is neither circular (1..3) nor "
                       "rectangular (8..10)",
                   0};
}

std::uint64_t grid_byte_size(const ThicknessGrid& g) {
    if (g.is_circular()) return kCircularGridSize;
    return kRectGridHeaderSize +
           static_cast<std::uint64_t>(g.rows) * static_cast<std::uint64_t>(g.cols) * gh::kCellBytes;
}

float invalid_to_nan(float v) {
    return is_valid_raw(v) ? v : std::numeric_limits<float>::quiet_NaN();
}
float nan_to_invalid(float v) { return std::isnan(v) ? kNoPixelData : v; }

bool is_known_grid_type(std::int32_t t) { return (t >= 1 && t <= 3) || (t >= 8 && t <= 10); }

// ---- reader ---------------------------------------------------------------------------------

class VolReader {
  public:
    VolReader(std::istream& in,
              std::uint64_t size,
              const std::string& name,
              const ReadOptions& options)
        : in_(in), size_(size), name_(name), options_(options) {}

    Scan read();

  private:
    // Reads n bytes at `offset`; throws truncated naming `what` if the file or stream is short.
    void read_at(std::uint64_t offset, void* dst, std::size_t n, const std::string& what);
    [[noreturn]] void corrupt(const Problem& p, std::uint64_t base) const {
        throw InputError::corrupt(name_, p.reason, base + p.field_offset);
    }
    void read_file_header(Scan& scan);
    void check_layout(const Scan& scan);
    void read_bscan(Scan& scan, std::uint32_t index);
    void read_grids(Scan& scan);
    std::optional<ThicknessGrid> read_grid(std::uint64_t offset,
                                           std::int32_t expected_type,
                                           bool from_header,
                                           std::string& why_not);

    std::istream& in_;
    std::uint64_t size_;
    const std::string& name_;
    ReadOptions options_;

    int version_ = 0;
    std::uint32_t size_x_ = 0;
    std::uint32_t size_z_ = 0;
    std::uint32_t num_bscans_ = 0;
    std::uint32_t hdr_size_ = 0;
    std::uint64_t slo_bytes_ = 0;
    std::uint64_t pixel_bytes_ = 0;  // per B-scan
    std::uint64_t bscans_start_ = 0;
    std::uint64_t bscans_end_ = 0;
    std::vector<Byte> hdr_buf_;
};

void VolReader::read_at(std::uint64_t offset, void* dst, std::size_t n, const std::string& what) {
    if (offset > size_ || n > size_ - offset) {
        throw InputError::truncated(name_,
                                    what + " needs " + std::to_string(n) +
                                        " bytes but the file "
                                        "ends at byte " +
                                        std::to_string(size_),
                                    offset);
    }
    if (n == 0) return;
    in_.clear();
    in_.seekg(static_cast<std::streamoff>(offset));
    in_.read(static_cast<char*>(dst), static_cast<std::streamsize>(n));
    const auto got = static_cast<std::uint64_t>(std::max<std::streamsize>(in_.gcount(), 0));
    if (!in_ || got != n) {
        throw InputError::truncated(name_, what + ": the stream ended early", offset + got);
    }
}

void VolReader::read_file_header(Scan& scan) {
    std::array<Byte, kVolFileHeaderSize> h{};
    const std::size_t have = static_cast<std::size_t>(std::min<std::uint64_t>(size_, h.size()));
    read_at(0, h.data(), have, "file header");
    // Magic first, so that a short file of another kind is called what it is.
    const std::size_t cmp = std::min(have, kMagicPrefix.size());
    if (std::memcmp(h.data(), kMagicPrefix.data(), cmp) != 0) {
        std::string found = quote_bytes(h.data(), std::min<std::size_t>(have, 12));
        throw InputError::unsupported(
            name_,
            "not a Heidelberg Spectralis .vol: magic " + found + ", expected \"HSF-OCT-10x\"" +
                (std::memcmp(h.data(), "ep-v", std::min<std::size_t>(have, 4)) == 0 && have >= 4
                     ? " (written by eyepy, not by a Spectralis device)"
                     : ""),
            0);
    }
    if (have < 12) {
        throw InputError::truncated(name_,
                                    "file header needs 2048 bytes but the file ends at "
                                    "byte " +
                                        std::to_string(size_),
                                    0);
    }
    const bool digits =
        h[8] == '1' && h[9] == '0' && h[10] >= '0' && h[10] <= '9' && (h[11] == 0 || h[11] == ' ');
    const int version = digits ? 100 + (h[10] - '0') : -1;
    if (version < kMinVersion || version > kMaxVersion) {
        throw InputError::unsupported(
            name_,
            "version " + quote_bytes(h.data(), 12) + " is not supported (HSF-OCT-100 ... 104 are)",
            0);
    }
    if (have < h.size()) {
        throw InputError::truncated(name_,
                                    "file header needs 2048 bytes but the file ends at "
                                    "byte " +
                                        std::to_string(size_),
                                    0);
    }
    version_ = version;
    ScanMeta& m = scan.meta;
    m.format = SourceFormat::kVol;
    m.version = load_printable(&h[fh::kVersion], 12);
    size_x_ = load_u32(&h[fh::kSizeX]);
    num_bscans_ = load_u32(&h[fh::kNumBScans]);
    size_z_ = load_u32(&h[fh::kSizeZ]);
    m.scale_x_mm = load_f64(&h[fh::kScaleX]);
    m.distance_mm = load_f64(&h[fh::kDistance]);
    m.scale_z_mm = load_f64(&h[fh::kScaleZ]);
    const std::uint32_t xs = load_u32(&h[fh::kSizeXSlo]);
    const std::uint32_t ys = load_u32(&h[fh::kSizeYSlo]);
    m.scale_x_slo_mm = load_f64(&h[fh::kScaleXSlo]);
    m.scale_y_slo_mm = load_f64(&h[fh::kScaleYSlo]);
    m.field_size_slo_deg = load_u32(&h[fh::kFieldSizeSlo]);
    m.scan_focus_dpt = load_f64(&h[fh::kScanFocus]);
    // Sides are checked against kMaxSloSide before any use; clamp so the int cast is defined.
    m.size_x_slo = static_cast<int>(std::min(xs, kMaxSloSide + 1));
    m.size_y_slo = static_cast<int>(std::min(ys, kMaxSloSide + 1));
    if (auto p = check_file_header(size_x_, num_bscans_, size_z_, m)) corrupt(*p, 0);
    m.size_x = static_cast<int>(size_x_);
    m.size_z = static_cast<int>(size_z_);

    m.scan_position_raw = load_printable(&h[fh::kScanPosition], 4);
    if (m.scan_position_raw == "OD") {
        m.laterality = Laterality::kOD;
    } else if (m.scan_position_raw == "OS") {
        m.laterality = Laterality::kOS;
    } else {
        m.laterality = Laterality::kUnknown;
        scan.notes.push_back("ScanPosition \"" + m.scan_position_raw +
                             "\" is neither OD nor OS: laterality unknown");
    }
    const std::uint64_t exam = load_u64(&h[fh::kExamTime]);
    if (exam != 0 && exam <= kMaxFiletime) {
        m.exam_time_filetime = exam;
    } else if (exam != 0) {
        scan.notes.push_back("ExamTime is not a valid date: ignored");
    }
    m.scan_pattern_code = load_i32(&h[fh::kScanPattern]);
    m.pattern = scan_pattern_from_code(m.scan_pattern_code);
    hdr_size_ = load_u32(&h[fh::kBScanHdrSize]);
    m.bscan_hdr_size = hdr_size_;
    if (hdr_size_ < bscan_fixed_end(version_) || hdr_size_ > kMaxBScanHdrSize) {
        throw InputError::corrupt(name_,
                                  "BScanHdrSize = " + std::to_string(hdr_size_) + " is not in " +
                                      std::to_string(bscan_fixed_end(version_)) + ".." +
                                      std::to_string(kMaxBScanHdrSize),
                                  fh::kBScanHdrSize);
    }

    Identifiers& ids = m.ids;
    ids.id = load_string(&h[fh::kId], fh::kIdLen);
    ids.reference_id = load_string(&h[fh::kReferenceId], fh::kIdLen);
    // Decision (unverified, no public v100 file): the block PID..VisitDate is v101+.
    if (version_ >= 101) {
        ids.pid = load_u32(&h[fh::kPid]);
        ids.patient_id = load_string(&h[fh::kPatientId], fh::kPatientIdLen);
        ids.vid = load_u32(&h[fh::kVid]);
        ids.visit_id = load_string(&h[fh::kVisitId], fh::kVisitIdLen);
        const auto ole = [&scan](double v, const char* field) -> std::optional<double> {
            if (v == 0.0) return std::nullopt;
            if (std::isfinite(v) && v >= kMinOleDate && v <= kMaxOleDate) return v;
            scan.notes.push_back(std::string(field) + " is not a valid date: ignored");
            return std::nullopt;
        };
        ids.dob_ole = ole(load_f64(&h[fh::kDob]), "DOB");
        m.visit_date_ole = ole(load_f64(&h[fh::kVisitDate]), "VisitDate");
    }
    if (version_ >= 102) {
        m.grid_type = load_i32(&h[fh::kGridType]);
        m.grid_offset = load_i32(&h[fh::kGridOffset]);
    }
    if (version_ >= 103) {
        m.grid_type1 = load_i32(&h[fh::kGridType1]);
        m.grid_offset1 = load_i32(&h[fh::kGridOffset1]);
    }
    m.prog_id = load_printable(&h[fh::kProgId], fh::kProgIdLen);
    if (version_ == 104) {
        scan.notes.push_back(
            "HSF-OCT-104: the B-scan BMO fields (BmoCoordLeft/Right) were read "
            "but their meaning is unverified (no public 104 file)");
    }
}

void VolReader::check_layout(const Scan& scan) {
    slo_bytes_ = static_cast<std::uint64_t>(scan.meta.size_x_slo) *
                 static_cast<std::uint64_t>(scan.meta.size_y_slo);
    pixel_bytes_ = static_cast<std::uint64_t>(size_x_) * size_z_ * sizeof(float);
    bscans_start_ = kVolFileHeaderSize + slo_bytes_;
    const std::uint64_t per_bscan = hdr_size_ + pixel_bytes_;
    // Bounded by the plausibility limits: no overflow (see the constants above).
    bscans_end_ = bscans_start_ + num_bscans_ * per_bscan;
    if (bscans_start_ > size_) {
        throw InputError::truncated(
            name_,
            "SLO image of " + std::to_string(slo_bytes_) + " bytes needs the file to reach byte " +
                std::to_string(bscans_start_) + " but it ends at byte " + std::to_string(size_),
            kVolFileHeaderSize);
    }
    // Contradictory header sizes (as in files written by other tools) are reported as such
    // before the total length, which they usually also break.
    if (bscans_start_ + 16 <= size_) {
        std::array<Byte, 16> b0{};
        read_at(bscans_start_, b0.data(), b0.size(), "B-scan 0 header");
        if (std::memcmp(b0.data(), kBScanMagicPrefix.data(), kBScanMagicPrefix.size()) != 0) {
            throw InputError::corrupt(name_,
                                      "B-scan 0 header magic is " + quote_bytes(b0.data(), 12) +
                                          ", expected \"HSF-BS-10x\"",
                                      bscans_start_);
        }
        const std::uint32_t own = load_u32(&b0[bh::kHdrSize]);
        if (own != hdr_size_) {
            throw InputError::corrupt(name_,
                                      "contradictory header sizes: the file header says "
                                      "BScanHdrSize " +
                                          std::to_string(hdr_size_) + ", B-scan 0 says " +
                                          std::to_string(own),
                                      bscans_start_ + bh::kHdrSize);
        }
    }
    if (bscans_end_ > size_) {
        const std::uint64_t k = (size_ - bscans_start_) / per_bscan;
        const std::uint64_t start = bscans_start_ + k * per_bscan;
        const bool in_header = size_ - start < hdr_size_;
        throw InputError::truncated(name_,
                                    "the header promises " + std::to_string(num_bscans_) +
                                        " B-scans of " + std::to_string(hdr_size_) + " + " +
                                        std::to_string(pixel_bytes_) + " bytes (" +
                                        std::to_string(bscans_end_) +
                                        " bytes in all) but the file "
                                        "ends at byte " +
                                        std::to_string(size_) + ", inside B-scan " +
                                        std::to_string(k) + (in_header ? " header" : " pixels"),
                                    in_header ? start : start + hdr_size_);
    }
}

void VolReader::read_bscan(Scan& scan, std::uint32_t index) {
    const std::uint64_t start = bscans_start_ + index * (hdr_size_ + pixel_bytes_);
    const std::string label = "B-scan " + std::to_string(index);
    const std::uint32_t fixed = bscan_fixed_end(version_);
    hdr_buf_.resize(fixed);
    read_at(start, hdr_buf_.data(), fixed, label + " header");
    const Byte* h = hdr_buf_.data();
    if (std::memcmp(h, kBScanMagicPrefix.data(), kBScanMagicPrefix.size()) != 0) {
        throw InputError::corrupt(
            name_, label + " header magic is " + quote_bytes(h, 12) + ", expected \"HSF-BS-10x\"",
            start);
    }
    const std::uint32_t own = load_u32(h + bh::kHdrSize);
    if (own != hdr_size_) {
        throw InputError::corrupt(name_,
                                  "contradictory header sizes: the file header says "
                                  "BScanHdrSize " +
                                      std::to_string(hdr_size_) + ", " + label + " says " +
                                      std::to_string(own),
                                  start + bh::kHdrSize);
    }
    BScan b;
    b.version = load_printable(h + bh::kVersion, 12);
    b.start_x_mm = load_f64(h + bh::kStartX);
    b.start_y_mm = load_f64(h + bh::kStartY);
    b.end_x_mm = load_f64(h + bh::kEndX);
    b.end_y_mm = load_f64(h + bh::kEndY);
    const std::int32_t num_seg = load_i32(h + bh::kNumSeg);
    b.off_seg = load_i32(h + bh::kOffSeg);
    if (version_ >= 101) b.quality = load_f32(h + bh::kQuality);
    if (version_ >= 102) b.shift = load_i32(h + bh::kShift);
    if (version_ >= 103) {
        for (std::size_t i = 0; i < 6; ++i) b.iv_trafo[i] = load_f32(h + bh::kIvTrafo + 4 * i);
    }
    if (version_ >= 104) {
        BmoFields bmo;
        for (std::size_t i = 0; i < 3; ++i) {
            bmo.left[i] = load_i32(h + bh::kBmoLeft + 4 * i);
            bmo.right[i] = load_i32(h + bh::kBmoRight + 4 * i);
        }
        b.bmo = bmo;
    }
    if (auto p = check_bscan_header(b, num_seg, size_x_, hdr_size_, version_)) {
        throw InputError::corrupt(name_, label + " " + p->reason, start + p->field_offset);
    }
    // Exactly NumSeg lines; the rest of the header may hold more FLT_MAX rows.
    const auto n_seg = static_cast<std::size_t>(num_seg);
    std::vector<float> seg(n_seg * size_x_);
    read_at(start + static_cast<std::uint64_t>(b.off_seg), seg.data(), seg.size() * sizeof(float),
            label + " segmentation");
    fix_endian(seg.data(), seg.size());
    b.seg.resize(n_seg);
    for (std::size_t k = 0; k < n_seg; ++k) {
        const float* src = seg.data() + k * size_x_;
        b.seg[k].resize(size_x_);
        std::transform(src, src + size_x_, b.seg[k].begin(), invalid_to_nan);
    }
    if (options_.pixels) {
        b.pixels.resize(static_cast<std::size_t>(size_x_) * size_z_);
        read_at(start + hdr_size_, b.pixels.data(), b.pixels.size() * sizeof(float),
                label + " pixels");
        fix_endian(b.pixels.data(), b.pixels.size());
        // Only kNoPixelData marks "no data": other non-finite values become it too.
        for (float& v : b.pixels) {
            if (!std::isfinite(v)) v = kNoPixelData;
        }
    }
    scan.bscans.push_back(std::move(b));
}

std::optional<ThicknessGrid> VolReader::read_grid(std::uint64_t offset,
                                                  std::int32_t expected_type,
                                                  bool from_header,
                                                  std::string& why_not) {
    const std::string what = "thickness grid (type " + std::to_string(expected_type) + ")";
    ThicknessGrid g;
    g.type = expected_type;
    g.file_offset = offset;
    g.from_header = from_header;
    const bool circular = g.is_circular();
    const std::size_t head_len = circular ? kCircularGridSize : kRectGridHeaderSize;
    if (offset > size_ || size_ - offset < head_len) {
        if (from_header) {
            throw InputError::truncated(name_,
                                        what + " needs " + std::to_string(head_len) +
                                            " bytes but the file ends at byte " +
                                            std::to_string(size_),
                                        offset);
        }
        why_not = "too short for a " + what;
        return std::nullopt;
    }
    std::array<Byte, kCircularGridSize> buf{};
    read_at(offset, buf.data(), head_len, what);
    const Byte* p = buf.data();
    const std::int32_t own_type = load_i32(p + gh::kType);
    if (own_type != expected_type) {
        if (from_header) {
            throw InputError::corrupt(
                name_, what + " at GridOffset starts with type " + std::to_string(own_type),
                offset);
        }
        why_not = "type mismatch";
        return std::nullopt;
    }
    if (circular) {
        for (std::size_t i = 0; i < 3; ++i)
            g.diameters_mm[i] = load_f64(p + gh::kDiameters + 8 * i);
        g.centre_x_slo_mm = load_f64(p + gh::kCentreX);
        g.centre_y_slo_mm = load_f64(p + gh::kCentreY);
        g.central_thickness_mm = invalid_to_nan(load_f32(p + gh::kCentralThickness));
        g.min_central_thickness_mm = invalid_to_nan(load_f32(p + gh::kMinCentralThickness));
        g.max_central_thickness_mm = invalid_to_nan(load_f32(p + gh::kMaxCentralThickness));
        g.total_volume_mm3 = invalid_to_nan(load_f32(p + gh::kTotalVolume));
        g.cells.resize(kCircularGridCells);
        for (std::size_t i = 0; i < kCircularGridCells; ++i) {
            const Byte* cell = p + gh::kCircularCells + gh::kCellBytes * i;
            g.cells[i].thickness_mm = invalid_to_nan(load_f32(cell));
            g.cells[i].volume_mm3 = invalid_to_nan(load_f32(cell + gh::kCellVolume));
        }
    } else {
        g.rows = load_i32(p + gh::kRows);
        g.cols = load_i32(p + gh::kCols);
        g.cell_width_mm = load_f32(p + gh::kCellWidth);
        g.cell_height_mm = load_f32(p + gh::kCellHeight);
        g.tilt = load_f32(p + gh::kTilt);
        g.centre_x_slo_mm = load_f64(p + gh::kRectCentreX);
        g.centre_y_slo_mm = load_f64(p + gh::kRectCentreY);
    }
    if (auto prob = check_grid(g)) {
        if (from_header) {
            throw InputError::corrupt(name_, what + ": " + prob->reason,
                                      offset + prob->field_offset);
        }
        why_not = prob->reason;
        return std::nullopt;
    }
    if (!circular) {
        // rows, cols <= 1024: the cell block is at most 8 MiB and is checked against the file.
        const std::uint64_t n_cells =
            static_cast<std::uint64_t>(g.rows) * static_cast<std::uint64_t>(g.cols);
        const std::uint64_t cells_at = offset + kRectGridHeaderSize;
        if (size_ - cells_at < n_cells * gh::kCellBytes) {
            if (from_header) {
                throw InputError::truncated(name_,
                                            what + " cells need " +
                                                std::to_string(n_cells * gh::kCellBytes) +
                                                " bytes but the file "
                                                "ends at byte " +
                                                std::to_string(size_),
                                            cells_at);
            }
            why_not = "too short for its cells";
            return std::nullopt;
        }
        std::vector<Byte> cells(n_cells * gh::kCellBytes);
        read_at(cells_at, cells.data(), cells.size(), what + " cells");
        g.cells.resize(n_cells);
        for (std::size_t i = 0; i < n_cells; ++i) {
            const Byte* cell = &cells[gh::kCellBytes * i];
            g.cells[i].thickness_mm = invalid_to_nan(load_f32(cell));
            g.cells[i].volume_mm3 = invalid_to_nan(load_f32(cell + gh::kCellVolume));
        }
    }
    return g;
}

void VolReader::read_grids(Scan& scan) {
    const ScanMeta& m = scan.meta;
    const std::array<std::pair<std::int32_t, std::int32_t>, 2> declared = {
        {{m.grid_type, m.grid_offset}, {m.grid_type1, m.grid_offset1}}};
    const std::array<std::size_t, 2> field = {fh::kGridOffset, fh::kGridOffset1};
    bool any_declared = false;
    for (std::size_t i = 0; i < declared.size(); ++i) {
        const auto [type, offset] = declared[i];
        if (type == 0) continue;
        any_declared = true;
        if (!is_known_grid_type(type)) {
            scan.notes.push_back("thickness grid of unknown type " + std::to_string(type) +
                                 " not read");
            continue;
        }
        const std::string field_name = i == 0 ? "GridOffset" : "GridOffset1";
        if (offset < static_cast<std::int64_t>(kVolFileHeaderSize)) {
            throw InputError::corrupt(
                name_, field_name + " = " + std::to_string(offset) + " points into the file header",
                field[i]);
        }
        if (static_cast<std::uint64_t>(offset) >= size_) {
            throw InputError::truncated(name_,
                                        field_name + " = " + std::to_string(offset) +
                                            " points past the end of the file (byte " +
                                            std::to_string(size_) + ")",
                                        field[i]);
        }
        std::string unused;
        if (auto g = read_grid(static_cast<std::uint64_t>(offset), type, true, unused)) {
            scan.grids.push_back(std::move(*g));
        }
    }
    // Real files (fovea_line_716_0.vol) carry a grid after the last B-scan with GridType 0.
    if (any_declared || size_ <= bscans_end_) return;
    const std::uint64_t trailing = size_ - bscans_end_;
    std::string why_not = "no grid type";
    if (trailing >= 4) {
        std::array<Byte, 4> t{};
        read_at(bscans_end_, t.data(), t.size(), "data after the last B-scan");
        const std::int32_t type = load_i32(t.data());
        if (is_known_grid_type(type)) {
            if (auto g = read_grid(bscans_end_, type, false, why_not)) {
                scan.notes.push_back("thickness grid (type " + std::to_string(type) +
                                     ") found after the last B-scan at byte " +
                                     std::to_string(bscans_end_) +
                                     " although GridType is 0; read as a hint");
                scan.grids.push_back(std::move(*g));
                return;
            }
        }
    }
    scan.notes.push_back(std::to_string(trailing) + " bytes after the last B-scan ignored (" +
                         why_not + ")");
}

Scan VolReader::read() {
    Scan scan;
    scan.source_path = name_;
    read_file_header(scan);
    check_layout(scan);
    scan.bscans.reserve(num_bscans_);
    for (std::uint32_t i = 0; i < num_bscans_; ++i) read_bscan(scan, i);
    if (options_.pixels) {
        scan.slo.resize(static_cast<std::size_t>(slo_bytes_));
        read_at(kVolFileHeaderSize, scan.slo.data(), scan.slo.size(), "SLO image");
        scan.pixels_loaded = true;
    }
    read_grids(scan);
    return scan;
}

// ---- writer ---------------------------------------------------------------------------------

[[noreturn]] void usage(const std::string& why) { throw UsageError("cannot write .vol: " + why); }

void put_string(Byte* dst, std::size_t field_len, const std::string& s, const char* field) {
    if (s.size() > field_len) {
        usage(std::string(field) + " \"" + s + "\" is longer than " + std::to_string(field_len) +
              " bytes");
    }
    if (s.find('\0') != std::string::npos) usage(std::string(field) + " contains a NUL byte");
    std::memcpy(dst, s.data(), s.size());
}

struct WritePlan {
    std::uint32_t hdr_size = 0;
    std::vector<const ThicknessGrid*> header_grids;
    const ThicknessGrid* trailing_grid = nullptr;
    std::uint64_t bscans_end = 0;
};

WritePlan plan_write(const Scan& scan) {
    const ScanMeta& m = scan.meta;
    const auto nb = static_cast<std::uint32_t>(scan.bscans.size());
    if (m.size_x < 1 || m.size_z < 1) usage("size_x and size_z must be positive");
    const auto sx = static_cast<std::uint32_t>(m.size_x);
    const auto sz = static_cast<std::uint32_t>(m.size_z);
    if (m.size_x_slo < 0 || m.size_y_slo < 0) usage("SLO sizes must not be negative");
    if (auto p = check_file_header(sx, nb, sz, m)) usage(p->reason);
    const std::uint64_t slo_bytes =
        static_cast<std::uint64_t>(m.size_x_slo) * static_cast<std::uint64_t>(m.size_y_slo);
    if (!scan.slo.empty() && scan.slo.size() != slo_bytes) {
        usage("slo holds " + std::to_string(scan.slo.size()) +
              " bytes, SizeXSlo x SizeYSlo = " + std::to_string(slo_bytes));
    }
    if (!m.scan_position_raw.empty() && m.laterality != Laterality::kUnknown &&
        m.scan_position_raw != to_string(m.laterality)) {
        usage("scan_position_raw \"" + m.scan_position_raw + "\" contradicts laterality " +
              std::string(to_string(m.laterality)));
    }
    if (m.exam_time_filetime &&
        (*m.exam_time_filetime == 0 || *m.exam_time_filetime > kMaxFiletime)) {
        usage("exam_time_filetime is not a valid date");
    }
    const auto check_ole = [](const std::optional<double>& v, const char* field) {
        if (v && (!std::isfinite(*v) || *v == 0.0 || *v < kMinOleDate || *v > kMaxOleDate)) {
            usage(std::string(field) + " is not a valid OLE date");
        }
    };
    check_ole(m.ids.dob_ole, "dob_ole");
    check_ole(m.visit_date_ole, "visit_date_ole");

    // Text fields: they must fit, and the two the reader returns as printable text must be.
    const std::array<std::tuple<const std::string*, std::size_t, const char*>, 6> texts = {{
        {&m.scan_position_raw, 4, "scan_position_raw"},
        {&m.prog_id, fh::kProgIdLen, "prog_id"},
        {&m.ids.id, fh::kIdLen, "ids.id"},
        {&m.ids.reference_id, fh::kIdLen, "ids.reference_id"},
        {&m.ids.patient_id, fh::kPatientIdLen, "ids.patient_id"},
        {&m.ids.visit_id, fh::kVisitIdLen, "ids.visit_id"},
    }};
    for (std::size_t i = 0; i < texts.size(); ++i) {
        const auto& [text, len, field] = texts[i];
        if (text->size() > len) {
            usage(std::string(field) + " is longer than " + std::to_string(len) + " bytes");
        }
        if (text->find('\0') != std::string::npos) usage(std::string(field) + " has a NUL byte");
        const bool must_print = i < 2;
        for (char c : *text) {
            const auto u = static_cast<unsigned char>(c);
            if (must_print && (u < 0x20 || u > 0x7e))
                usage(std::string(field) + " is not printable ASCII");
        }
    }

    WritePlan plan;
    std::uint64_t need = bscan_fixed_end(kWriteVersion);
    for (std::size_t i = 0; i < scan.bscans.size(); ++i) {
        const BScan& b = scan.bscans[i];
        for (const auto& line : b.seg) {
            if (line.size() != sx) {
                usage("B-scan " + std::to_string(i) + " has a line of " +
                      std::to_string(line.size()) + " values, size_x is " + std::to_string(sx));
            }
        }
        if (!b.pixels.empty() && b.pixels.size() != static_cast<std::size_t>(sx) * sz) {
            usage("B-scan " + std::to_string(i) + " has " + std::to_string(b.pixels.size()) +
                  " pixels, size_x x size_z is " +
                  std::to_string(static_cast<std::size_t>(sx) * sz));
        }
        if (b.off_seg < static_cast<std::int32_t>(bscan_fixed_end(kWriteVersion))) {
            usage("B-scan " + std::to_string(i) + " off_seg " + std::to_string(b.off_seg) +
                  " overlaps the fixed header fields (which end at byte " +
                  std::to_string(bscan_fixed_end(kWriteVersion)) + ")");
        }
        need = std::max<std::uint64_t>(
            need, static_cast<std::uint64_t>(b.off_seg) + b.seg.size() * std::uint64_t{sx} * 4U);
    }
    // The smallest multiple of 256 (the granularity of the observed 46080 and 55296 and of
    // OffSeg = 256) unless the scan's own size is large enough (keeps a file's layout).
    std::uint64_t hdr = (need + 255U) / 256U * 256U;
    if (m.bscan_hdr_size >= need) hdr = m.bscan_hdr_size;
    if (hdr > kMaxBScanHdrSize) usage("the segmentation needs a B-scan header over 64 MiB");
    plan.hdr_size = static_cast<std::uint32_t>(hdr);
    for (std::size_t i = 0; i < scan.bscans.size(); ++i) {
        const BScan& b = scan.bscans[i];
        if (auto p = check_bscan_header(b, static_cast<std::int64_t>(b.seg.size()), sx,
                                        plan.hdr_size, kWriteVersion)) {
            usage("B-scan " + std::to_string(i) + " " + p->reason);
        }
    }
    for (const ThicknessGrid& g : scan.grids) {
        if (auto p = check_grid(g)) usage(p->reason);
        const std::size_t cells =
            g.is_circular() ? kCircularGridCells
                            : static_cast<std::size_t>(g.rows) * static_cast<std::size_t>(g.cols);
        if (g.cells.size() != cells) {
            usage("a grid of type " + std::to_string(g.type) + " needs " + std::to_string(cells) +
                  " cells, it has " + std::to_string(g.cells.size()));
        }
        if (g.from_header) {
            plan.header_grids.push_back(&g);
        } else {
            if (plan.trailing_grid != nullptr) usage("more than one grid without a header entry");
            plan.trailing_grid = &g;
        }
    }
    if (plan.header_grids.size() > 2) usage("a .vol header holds at most two grids");
    if (!plan.header_grids.empty() && plan.trailing_grid != nullptr) {
        usage(
            "a grid without a header entry cannot be combined with header grids (the reader "
            "would not look for it)");
    }
    plan.bscans_end =
        kVolFileHeaderSize + slo_bytes + nb * (hdr + static_cast<std::uint64_t>(sx) * sz * 4U);
    std::uint64_t grids_end = plan.bscans_end;
    for (const ThicknessGrid* g : plan.header_grids) grids_end += grid_byte_size(*g);
    if (!plan.header_grids.empty() &&
        grids_end > static_cast<std::uint64_t>(std::numeric_limits<std::int32_t>::max())) {
        usage("grids after byte 2^31 cannot be addressed by the i32 GridOffset");
    }
    return plan;
}

std::vector<Byte> encode_grid(const ThicknessGrid& g) {
    std::vector<Byte> out(static_cast<std::size_t>(grid_byte_size(g)), 0);
    Byte* p = out.data();
    store_i32(p + gh::kType, g.type);
    if (g.is_circular()) {
        for (std::size_t i = 0; i < 3; ++i)
            store_f64(p + gh::kDiameters + 8 * i, g.diameters_mm[i]);
        store_f64(p + gh::kCentreX, g.centre_x_slo_mm);
        store_f64(p + gh::kCentreY, g.centre_y_slo_mm);
        store_f32(p + gh::kCentralThickness, nan_to_invalid(g.central_thickness_mm));
        store_f32(p + gh::kMinCentralThickness, nan_to_invalid(g.min_central_thickness_mm));
        store_f32(p + gh::kMaxCentralThickness, nan_to_invalid(g.max_central_thickness_mm));
        store_f32(p + gh::kTotalVolume, nan_to_invalid(g.total_volume_mm3));
        for (std::size_t i = 0; i < kCircularGridCells; ++i) {
            Byte* cell = p + gh::kCircularCells + gh::kCellBytes * i;
            store_f32(cell, nan_to_invalid(g.cells[i].thickness_mm));
            store_f32(cell + gh::kCellVolume, nan_to_invalid(g.cells[i].volume_mm3));
        }
        return out;
    }
    store_i32(p + gh::kRows, g.rows);
    store_i32(p + gh::kCols, g.cols);
    store_f32(p + gh::kCellWidth, g.cell_width_mm);
    store_f32(p + gh::kCellHeight, g.cell_height_mm);
    store_f32(p + gh::kTilt, g.tilt);
    store_f64(p + gh::kRectCentreX, g.centre_x_slo_mm);
    store_f64(p + gh::kRectCentreY, g.centre_y_slo_mm);
    for (std::size_t i = 0; i < g.cells.size(); ++i) {
        Byte* cell = p + gh::kRectCells + gh::kCellBytes * i;
        store_f32(cell, nan_to_invalid(g.cells[i].thickness_mm));
        store_f32(cell + gh::kCellVolume, nan_to_invalid(g.cells[i].volume_mm3));
    }
    return out;
}

void write_bytes(std::ostream& out, const void* p, std::size_t n) {
    out.write(static_cast<const char*>(p), static_cast<std::streamsize>(n));
}

}  // namespace

bool looks_like_vol(const char* head, std::size_t n) {
    return n >= kMagicPrefix.size() &&
           std::memcmp(head, kMagicPrefix.data(), kMagicPrefix.size()) == 0;
}

Scan read_vol(std::istream& in,
              std::uint64_t size,
              const std::string& name,
              const ReadOptions& options) {
    return VolReader(in, size, name, options).read();
}

void write_vol(const Scan& scan, std::ostream& out) {
    const WritePlan plan = plan_write(scan);
    const ScanMeta& m = scan.meta;
    const auto sx = static_cast<std::uint32_t>(m.size_x);
    const auto sz = static_cast<std::uint32_t>(m.size_z);

    std::vector<Byte> h(kVolFileHeaderSize, 0);
    std::memcpy(h.data(), "HSF-OCT-103", 11);
    store_u32(&h[fh::kSizeX], sx);
    store_u32(&h[fh::kNumBScans], static_cast<std::uint32_t>(scan.bscans.size()));
    store_u32(&h[fh::kSizeZ], sz);
    store_f64(&h[fh::kScaleX], m.scale_x_mm);
    store_f64(&h[fh::kDistance], m.distance_mm);
    store_f64(&h[fh::kScaleZ], m.scale_z_mm);
    store_u32(&h[fh::kSizeXSlo], static_cast<std::uint32_t>(m.size_x_slo));
    store_u32(&h[fh::kSizeYSlo], static_cast<std::uint32_t>(m.size_y_slo));
    store_f64(&h[fh::kScaleXSlo], m.scale_x_slo_mm);
    store_f64(&h[fh::kScaleYSlo], m.scale_y_slo_mm);
    store_u32(&h[fh::kFieldSizeSlo], m.field_size_slo_deg);
    store_f64(&h[fh::kScanFocus], m.scan_focus_dpt);
    const std::string position =
        !m.scan_position_raw.empty()
            ? m.scan_position_raw
            : (m.laterality == Laterality::kUnknown ? std::string()
                                                    : std::string(to_string(m.laterality)));
    put_string(&h[fh::kScanPosition], 4, position, "scan_position_raw");
    store_u64(&h[fh::kExamTime], m.exam_time_filetime.value_or(0));
    const std::int32_t pattern = scan_pattern_from_code(m.scan_pattern_code) == m.pattern
                                     ? m.scan_pattern_code
                                     : static_cast<std::int32_t>(m.pattern);
    store_i32(&h[fh::kScanPattern], pattern);
    store_u32(&h[fh::kBScanHdrSize], plan.hdr_size);
    put_string(&h[fh::kId], fh::kIdLen, m.ids.id, "ids.id");
    put_string(&h[fh::kReferenceId], fh::kIdLen, m.ids.reference_id, "ids.reference_id");
    store_u32(&h[fh::kPid], m.ids.pid);
    put_string(&h[fh::kPatientId], fh::kPatientIdLen, m.ids.patient_id, "ids.patient_id");
    store_f64(&h[fh::kDob], m.ids.dob_ole.value_or(0.0));
    store_u32(&h[fh::kVid], m.ids.vid);
    put_string(&h[fh::kVisitId], fh::kVisitIdLen, m.ids.visit_id, "ids.visit_id");
    store_f64(&h[fh::kVisitDate], m.visit_date_ole.value_or(0.0));
    std::uint64_t grid_at = plan.bscans_end;
    for (std::size_t i = 0; i < plan.header_grids.size(); ++i) {
        store_i32(&h[i == 0 ? fh::kGridType : fh::kGridType1], plan.header_grids[i]->type);
        store_i32(&h[i == 0 ? fh::kGridOffset : fh::kGridOffset1],
                  static_cast<std::int32_t>(grid_at));
        grid_at += grid_byte_size(*plan.header_grids[i]);
    }
    put_string(&h[fh::kProgId], fh::kProgIdLen, m.prog_id, "prog_id");
    write_bytes(out, h.data(), h.size());

    if (scan.slo.empty()) {
        const std::vector<Byte> zeros(static_cast<std::size_t>(m.size_x_slo), 0);
        for (int y = 0; y < m.size_y_slo; ++y) write_bytes(out, zeros.data(), zeros.size());
    } else {
        write_bytes(out, scan.slo.data(), scan.slo.size());
    }

    std::vector<Byte> bh_buf(plan.hdr_size);
    std::vector<float> row(static_cast<std::size_t>(sx) * sz);
    for (const BScan& b : scan.bscans) {
        std::fill(bh_buf.begin(), bh_buf.end(), Byte{0});
        Byte* p = bh_buf.data();
        std::memcpy(p, "HSF-BS-103", 10);
        store_u32(p + bh::kHdrSize, plan.hdr_size);
        store_f64(p + bh::kStartX, b.start_x_mm);
        store_f64(p + bh::kStartY, b.start_y_mm);
        store_f64(p + bh::kEndX, b.end_x_mm);
        store_f64(p + bh::kEndY, b.end_y_mm);
        store_i32(p + bh::kNumSeg, static_cast<std::int32_t>(b.seg.size()));
        store_i32(p + bh::kOffSeg, b.off_seg);
        store_f32(p + bh::kQuality, b.quality);
        store_i32(p + bh::kShift, b.shift);
        for (std::size_t i = 0; i < 6; ++i) store_f32(p + bh::kIvTrafo + 4 * i, b.iv_trafo[i]);
        std::size_t at = static_cast<std::size_t>(b.off_seg);
        for (const auto& line : b.seg) {
            for (float v : line) {
                store_f32(p + at, nan_to_invalid(v));
                at += 4;
            }
        }
        // Like the device: the unused rest of the header holds FLT_MAX rows.
        for (; at + 4 <= plan.hdr_size; at += 4) store_f32(p + at, kNoPixelData);
        write_bytes(out, p, bh_buf.size());
        if (b.pixels.empty()) {
            std::fill(row.begin(), row.end(), kNoPixelData);
        } else {
            std::copy(b.pixels.begin(), b.pixels.end(), row.begin());
        }
        fix_endian(row.data(), row.size());
        write_bytes(out, row.data(), row.size() * sizeof(float));
    }
    for (const ThicknessGrid* g : plan.header_grids) {
        const std::vector<Byte> bytes = encode_grid(*g);
        write_bytes(out, bytes.data(), bytes.size());
    }
    if (plan.trailing_grid != nullptr) {
        const std::vector<Byte> bytes = encode_grid(*plan.trailing_grid);
        write_bytes(out, bytes.data(), bytes.size());
    }
    out.flush();
    if (!out) throw OutputError("(stream)", "writing the .vol failed");
}

void write_vol_file(const Scan& scan, const std::string& path) {
    // Validate first, so that a scan that cannot be written leaves no temporary file behind.
    (void)plan_write(scan);
    write_file_atomically(path, [&scan](std::ostream& out) { write_vol(scan, out); });
}

}  // namespace octshape::io
