#include "octshape/io/topcon.h"

#include <openjpeg.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <optional>
#include <ostream>
#include <sstream>
#include <vector>

#include "octshape/error.h"
#include "octshape/io/atomic_file.h"

// Layout, the validation rules and how the contours were identified: docs/formats.md
// "Topcon .fda / .fds". Keep the two in step.

namespace octshape::io {
namespace {

constexpr std::size_t kHeaderSize = 15;     // "FOCT", "FDA"/"FDS"/"FAA", u32, u32
constexpr std::size_t kContourHeader = 34;  // id[20], u16 type, u32 width, u32 height, u32 size
constexpr std::size_t kMaxChunks = 1U << 16;
// Far above any Topcon protocol (at most 1024 A-scans, 885 px per A-scan, 512 B-scans), far
// below anything that could overflow a size product in 64 bits.
constexpr std::uint32_t kMaxSide = 1U << 15;
constexpr double kMaxScanMm = 50.0;    // scan width / height on the fundus
constexpr double kMaxPixelUm = 100.0;  // axial pixel size
constexpr double kMinSize = 1e-3;      // mm of a scan side, um of a pixel

struct Chunk {
    std::string name;
    std::uint64_t offset = 0;  // of the data, in the file
    std::uint32_t size = 0;
};

// Bounds-checked little-endian reads of one chunk's data; errors name the file offset.
class ChunkReader {
  public:
    ChunkReader(std::string_view file, const Chunk& c, const std::string& path)
        : data_(file.substr(c.offset, c.size)), base_(c.offset), name_(c.name), path_(path) {}

    void need(std::size_t at, std::size_t n, const char* what) const {
        if (at > data_.size() || n > data_.size() - at) {
            throw InputError::corrupt(path_,
                                      name_ + " (" + std::to_string(data_.size()) +
                                          " bytes) is too short for its " + what,
                                      base_ + std::min<std::uint64_t>(at, data_.size()));
        }
    }
    template <typename T>
    [[nodiscard]] T get(std::size_t at, const char* what) const {
        need(at, sizeof(T), what);
        T v{};
        std::memcpy(&v, data_.data() + at, sizeof(T));
        return v;  // the build targets little-endian machines only (as the .vol reader)
    }
    [[nodiscard]] std::string text(std::size_t at, std::size_t n, const char* what) const {
        need(at, n, what);
        std::string s(data_.substr(at, n));
        s.resize(std::strlen(s.c_str()));
        // Shown in messages and notes: one line of printable ASCII.
        for (char& c : s) {
            if (c < 0x20 || c > 0x7E) c = '?';
        }
        return s;
    }
    [[nodiscard]] std::uint64_t offset(std::size_t at) const { return base_ + at; }
    [[nodiscard]] std::size_t size() const { return data_.size(); }
    [[nodiscard]] const char* bytes(std::size_t at) const { return data_.data() + at; }
    [[nodiscard]] const std::string& name() const { return name_; }

  private:
    std::string_view data_;
    std::uint64_t base_;
    std::string name_;
    const std::string& path_;
};

std::uint32_t u32_at(std::string_view d, std::size_t at) {
    std::uint32_t v = 0;
    std::memcpy(&v, d.data() + at, 4);
    return v;
}

// The chunk directory: name length (u8, 0 = end), name, u32 size, data.
std::vector<Chunk> list_chunks(std::string_view d,
                               const std::string& path,
                               std::vector<std::string>& notes) {
    std::vector<Chunk> chunks;
    std::size_t p = kHeaderSize;
    while (p < d.size()) {
        const auto len = static_cast<unsigned char>(d[p]);
        if (len == 0) {
            if (d.size() - p > 1) {
                notes.push_back(std::to_string(d.size() - p - 1) +
                                " bytes after the end-of-chunks mark ignored");
            }
            return chunks;
        }
        if (d.size() - p < 1U + len + 4U) {
            throw InputError::truncated(path, "file ends inside a chunk name or size", p);
        }
        std::string name(d.substr(p + 1, len));
        const bool printable =
            std::all_of(name.begin(), name.end(), [](char c) { return c > 0x20 && c < 0x7F; });
        if (name.front() != '@' || !printable) {
            throw InputError::corrupt(path, "chunk name is not an '@NAME' (damaged directory)", p);
        }
        const std::uint32_t size = u32_at(d, p + 1 + len);
        const std::uint64_t data_at = p + 1U + len + 4U;
        if (size > d.size() - data_at) {
            throw InputError::truncated(path,
                                        name + " declares " + std::to_string(size) +
                                            " bytes, the file ends " +
                                            std::to_string(d.size() - data_at) + " bytes later",
                                        data_at);
        }
        if (chunks.size() >= kMaxChunks) {
            throw InputError::corrupt(path, "more than 65536 chunks", p);
        }
        chunks.push_back({std::move(name), data_at, size});
        p = static_cast<std::size_t>(data_at + size);
    }
    throw InputError::truncated(path, "file ends without the end-of-chunks mark", d.size());
}

const Chunk* find_chunk(const std::vector<Chunk>& chunks, std::string_view name) {
    for (const Chunk& c : chunks) {
        if (c.name == name) return &c;
    }
    return nullptr;
}

// The B-scan image chunk's sizes: @IMG_JPEG (JPEG 2000 frames) or @IMG_SCAN_03 /
// @IMG_MOT_COMP_03 (raw 16-bit).
struct ImageInfo {
    std::string chunk;
    int type = -1;  // @IMG_JPEG's scan type (2 = rectangular volume), -1 for raw chunks
    std::uint32_t width = 0;
    std::uint32_t height = 0;
    std::uint32_t frames = 0;
    // @IMG_JPEG: each frame's codestream (views into the file's bytes).
    std::vector<std::string_view> codestreams;
    std::vector<std::uint64_t> frame_offsets;
};

void check_side(const ChunkReader& r,
                std::size_t at,
                std::uint32_t v,
                const char* what,
                const std::string& path) {
    if (v == 0 || v > kMaxSide) {
        throw InputError::corrupt(path,
                                  r.name() + " " + what + " " + std::to_string(v) + " outside 1.." +
                                      std::to_string(kMaxSide),
                                  r.offset(at));
    }
}

ImageInfo read_jpeg_header(const ChunkReader& r, const std::string& path) {
    ImageInfo im{r.name(),
                 r.get<std::uint8_t>(0, "scan type"),
                 r.get<std::uint32_t>(9, "width"),
                 r.get<std::uint32_t>(13, "height"),
                 r.get<std::uint32_t>(17, "frame count"),
                 {},
                 {}};
    check_side(r, 9, im.width, "width", path);
    check_side(r, 13, im.height, "height", path);
    if (im.frames > kMaxSide) {
        throw InputError::corrupt(
            path, r.name() + " frame count " + std::to_string(im.frames) + " is implausible",
            r.offset(17));
    }
    // Each frame: u32 size, then its JPEG 2000 codestream. Walk them so that a frame that runs
    // past the chunk is found here (the frames are not decoded: docs/formats.md).
    std::size_t p = 25;
    for (std::uint32_t f = 0; f < im.frames; ++f) {
        const auto n = r.get<std::uint32_t>(p, "frame size");
        r.need(p + 4, n, "B-scan frame");
        if (n < 2 || static_cast<unsigned char>(*r.bytes(p + 4)) != 0xFF ||
            static_cast<unsigned char>(*r.bytes(p + 5)) != 0x4F) {
            throw InputError::corrupt(
                path, "B-scan frame " + std::to_string(f) + " is not a JPEG 2000 codestream",
                r.offset(p + 4));
        }
        im.codestreams.emplace_back(r.bytes(p + 4), n);
        im.frame_offsets.push_back(r.offset(p + 4));
        p += 4U + n;
    }
    return im;
}

ImageInfo read_raw_header(const ChunkReader& r, const std::string& path) {
    ImageInfo im{r.name(),
                 -1,
                 r.get<std::uint32_t>(1, "width"),
                 r.get<std::uint32_t>(5, "height"),
                 r.get<std::uint32_t>(13, "frame count"),
                 {},
                 {}};
    check_side(r, 1, im.width, "width", path);
    check_side(r, 5, im.height, "height", path);
    check_side(r, 13, im.frames, "frame count", path);
    const auto bits = r.get<std::uint32_t>(9, "bits per pixel");
    if (bits != 16) {
        throw InputError::unsupported(
            path, r.name() + " with " + std::to_string(bits) + " bits per pixel (16 is read)",
            r.offset(9));
    }
    const std::uint64_t bytes = std::uint64_t{im.width} * im.height * im.frames * 2U;
    r.need(22, static_cast<std::size_t>(std::min<std::uint64_t>(bytes, r.size() + 1U)),
           "raw B-scans");
    return im;
}

ImageInfo read_image_info(std::string_view d,
                          const std::vector<Chunk>& chunks,
                          const std::string& path) {
    if (const Chunk* c = find_chunk(chunks, "@IMG_JPEG")) {
        return read_jpeg_header(ChunkReader(d, *c, path), path);
    }
    for (const char* raw : {"@IMG_SCAN_03", "@IMG_MOT_COMP_03"}) {
        if (const Chunk* c = find_chunk(chunks, raw)) {
            return read_raw_header(ChunkReader(d, *c, path), path);
        }
    }
    throw InputError::unsupported(path, "no B-scan image chunk (@IMG_JPEG, @IMG_SCAN_03)");
}

// @PARAM_SCAN_04 / _02: scan width and height on the fundus (mm) and the axial pixel (um).
struct ScanParams {
    double width_mm = 0.0;
    double height_mm = 0.0;
    double pixel_um = 0.0;
};

ScanParams read_scan_params(std::string_view d,
                            const std::vector<Chunk>& chunks,
                            const std::string& path) {
    std::size_t at = 0;
    const Chunk* c = find_chunk(chunks, "@PARAM_SCAN_04");
    if (c != nullptr) {
        at = 12;
    } else if ((c = find_chunk(chunks, "@PARAM_SCAN_02")) != nullptr) {
        at = 21;
    } else {
        throw InputError::unsupported(path, "no scan parameters (@PARAM_SCAN_04 or _02)");
    }
    const ChunkReader r(d, *c, path);
    ScanParams p{r.get<double>(at, "scan width"), r.get<double>(at + 8, "scan height"),
                 r.get<double>(at + 16, "axial pixel size")};
    // A lower bound too: a denormal size would divide down to 0. The bounds are widened by a
    // rounding's width so that what write_topcon writes from a read scan reads back.
    auto check = [&](double v, double max, std::size_t off, const char* what) {
        if (!std::isfinite(v) || v < kMinSize * (1.0 - 1e-9) || v > max * (1.0 + 1e-9)) {
            throw InputError::corrupt(
                path, r.name() + " " + what + " " + std::to_string(v) + " is not a size",
                r.offset(off));
        }
    };
    check(p.width_mm, kMaxScanMm, at, "scan width (mm)");
    check(p.height_mm, kMaxScanMm, at + 8, "scan height (mm)");
    check(p.pixel_um, kMaxPixelUm, at + 16, "axial pixel size (um)");
    return p;
}

struct Contour {
    std::string id;
    std::uint64_t offset = 0;
    std::uint32_t width = 0;
    std::uint32_t height = 0;
    const char* values = nullptr;  // u16[height][width], heights in pixels above the bottom
};

std::vector<Contour> read_contours(std::string_view d,
                                   const std::vector<Chunk>& chunks,
                                   const std::string& path) {
    std::vector<Contour> out;
    for (const Chunk& c : chunks) {
        if (c.name != "@CONTOUR_INFO") continue;
        const ChunkReader r(d, c, path);
        Contour k{r.text(0, 20, "contour id"), c.offset, r.get<std::uint32_t>(22, "width"),
                  r.get<std::uint32_t>(26, "height"), nullptr};
        const auto type = r.get<std::uint16_t>(20, "contour type");
        if (type != 0) continue;  // 0x100: f64 cornea contours of anterior scans
        check_side(r, 22, k.width, "width", path);
        check_side(r, 26, k.height, "height", path);
        const std::uint64_t bytes = std::uint64_t{k.width} * k.height * 2U;
        if (r.get<std::uint32_t>(30, "data size") != bytes) {
            throw InputError::corrupt(path,
                                      "contour " + k.id + " states " +
                                          std::to_string(r.get<std::uint32_t>(30, "")) +
                                          " data bytes for " + std::to_string(k.width) + " x " +
                                          std::to_string(k.height) + " values",
                                      r.offset(30));
        }
        r.need(kContourHeader, static_cast<std::size_t>(bytes), "contour values");
        k.values = r.bytes(kContourHeader);
        out.push_back(std::move(k));
    }
    return out;
}

// The seconds of a calendar date and time as FILETIME (100 ns since 1601-01-01), or nullopt
// for an impossible date.
std::optional<std::uint64_t> to_filetime(const std::array<std::uint16_t, 6>& t) {
    if (t[0] < 1601 || t[0] > 9999 || t[1] < 1 || t[1] > 12 || t[2] < 1 || t[2] > 31 || t[3] > 23 ||
        t[4] > 59 || t[5] > 60) {
        return std::nullopt;
    }
    const long long days = days_from_civil(t[0], t[1], t[2]) + 134774LL;  // 1601 -> 1970
    const long long secs = days * 86400LL + t[3] * 3600LL + t[4] * 60LL + t[5];
    return static_cast<std::uint64_t>(secs) * 10000000ULL;
}

// @CAPTURE_INFO_02: eye (u8, 0 right, 1 left), capture date and time (u16[6] at 106).
void read_capture(std::string_view d,
                  const std::vector<Chunk>& chunks,
                  const std::string& path,
                  Scan& scan) {
    ScanMeta& m = scan.meta;
    const Chunk* c = find_chunk(chunks, "@CAPTURE_INFO_02");
    if (c == nullptr) {
        scan.notes.push_back("no @CAPTURE_INFO_02: eye and exam date unknown");
        return;
    }
    const ChunkReader r(d, *c, path);
    const auto eye = r.get<std::uint8_t>(0, "eye");
    m.laterality = eye == 0 ? Laterality::kOD : eye == 1 ? Laterality::kOS : Laterality::kUnknown;
    m.scan_position_raw = eye <= 1 ? std::string(eye == 0 ? "R" : "L") : std::to_string(eye);
    if (r.size() >= 118) {
        std::array<std::uint16_t, 6> t{};
        for (std::size_t i = 0; i < 6; ++i) t[i] = r.get<std::uint16_t>(106 + 2 * i, "date");
        m.exam_time_filetime = to_filetime(t);  // local time of the device, zone unknown
    }
}

// @PATIENT_INFO_02: patient ID (char[32]) and birth date (u16[3] at 105); private fields.
void read_patient(std::string_view d,
                  const std::vector<Chunk>& chunks,
                  const std::string& path,
                  Scan& scan) {
    const Chunk* c = find_chunk(chunks, "@PATIENT_INFO_02");
    if (c == nullptr) return;
    const ChunkReader r(d, *c, path);
    if (r.size() < 111) return;
    scan.meta.ids.patient_id = r.text(0, 32, "patient ID");
    const auto y = r.get<std::uint16_t>(105, "birth year");
    const auto mo = r.get<std::uint16_t>(107, "birth month");
    const auto day = r.get<std::uint16_t>(109, "birth day");
    if (y >= 1800 && y <= 9999 && mo >= 1 && mo <= 12 && day >= 1 && day <= 31) {
        scan.meta.ids.dob_ole = static_cast<double>(days_from_civil(y, mo, day) + 25569LL);
    }
}

void read_device(std::string_view d,
                 const std::vector<Chunk>& chunks,
                 const std::string& path,
                 Scan& scan,
                 std::string_view kind) {
    std::string model = "unknown model";
    std::string software;
    if (const Chunk* c = find_chunk(chunks, "@HW_INFO_03")) {
        const ChunkReader r(d, *c, path);
        if (r.size() >= 80) {
            model = r.text(0, 16, "model name");
            software = r.text(64, 16, "version");
        }
    }
    scan.meta.version = "Topcon " + std::string(kind) + " (" + model +
                        (software.empty() ? std::string() : ", version " + software) + ")";
    scan.meta.prog_id = model;
}

// The contours of `id` or nullptr.
const Contour* contour(const std::vector<Contour>& cs, std::string_view id) {
    for (const Contour& c : cs) {
        if (c.id == id) return &c;
    }
    return nullptr;
}

// Fills the lines: ILM, BM, then the other contours. Contour row r is B-scan r (row 0 is the
// inferior edge of the scan: images have their origin at the lower left); a value v is a height
// above the bottom of the B-scan, depth from the top = size_z - 1 - v. 0 and values outside the
// B-scan are missing.
void set_lines(Scan& scan, const std::vector<Contour>& cs, IowaBm bm, const std::string& path) {
    const Contour* ilm = contour(cs, "RETINA_1");
    const Contour* bm_c = contour(cs, bm == IowaBm::kOuterRpe ? "RETINA_4" : "RETINA_3");
    if (ilm == nullptr || bm_c == nullptr) {
        std::string ids;
        for (const Contour& c : cs) ids += (ids.empty() ? "" : ", ") + c.id;
        throw InputError::unsupported(
            path, "no RETINA_1 and " +
                      std::string(bm == IowaBm::kOuterRpe ? "RETINA_4" : "RETINA_3") +
                      " contours (found: " + (ids.empty() ? "none" : ids) +
                      "): the device segmentation is needed");
    }
    std::vector<const Contour*> order{ilm, bm_c};
    scan.line_names = {"ILM", "BM"};
    for (const Contour& c : cs) {
        if (&c == ilm || &c == bm_c) continue;
        order.push_back(&c);
        scan.line_names.push_back(c.id);
    }
    const int nx = scan.meta.size_x;
    const int nz = scan.meta.size_z;
    std::size_t missing = 0;
    for (const Contour* c : order) {
        if (c->width != static_cast<std::uint32_t>(nx) || c->height != scan.bscans.size()) {
            throw InputError::corrupt(path,
                                      "contour " + c->id + " is " + std::to_string(c->width) +
                                          " x " + std::to_string(c->height) + ", the scan " +
                                          std::to_string(nx) + " x " +
                                          std::to_string(scan.bscans.size()),
                                      c->offset + 22);
        }
    }
    for (std::size_t b = 0; b < scan.bscans.size(); ++b) {
        BScan& bs = scan.bscans[b];
        bs.seg.assign(order.size(), std::vector<float>(static_cast<std::size_t>(nx)));
        for (std::size_t k = 0; k < order.size(); ++k) {
            for (int a = 0; a < nx; ++a) {
                std::uint16_t v = 0;
                std::memcpy(&v,
                            order[k]->values + 2 * (b * static_cast<std::size_t>(nx) +
                                                    static_cast<std::size_t>(a)),
                            2);
                const bool ok = v > 0 && v < nz;
                missing += ok ? 0 : 1;
                bs.seg[k][static_cast<std::size_t>(a)] =
                    ok ? static_cast<float>(nz - 1 - v) : std::numeric_limits<float>::quiet_NaN();
            }
        }
    }
    if (missing > 0) {
        scan.notes.push_back(std::to_string(missing) +
                             " contour values 0 or outside the B-scan: missing");
    }
}

// The ILM must lie above BM (RETINA_1 above RETINA_4) where both are present: the check that the
// heights-from-the-bottom reading holds for this file (docs/formats.md).
void check_order(const Scan& scan, const std::string& path) {
    std::size_t both = 0;
    std::size_t inverted = 0;
    for (const BScan& bs : scan.bscans) {
        for (std::size_t a = 0; a < bs.seg[0].size(); ++a) {
            const float ilm = bs.seg[0][a];
            const float bm = bs.seg[1][a];
            if (!is_valid(ilm) || !is_valid(bm)) continue;
            ++both;
            inverted += ilm > bm ? 1 : 0;
        }
    }
    if (both > 0 && inverted * 100 > both) {
        throw InputError::corrupt(
            path, "RETINA_1 lies below the RPE contour at " + std::to_string(inverted) + " of " +
                      std::to_string(both) + " A-scans: the contours are not read as documented");
    }
}

void set_geometry(Scan& scan, const ImageInfo& im, const ScanParams& p, std::size_t bscans) {
    ScanMeta& m = scan.meta;
    m.size_x = static_cast<int>(im.width);
    m.size_z = static_cast<int>(im.height);
    m.scale_x_mm = p.width_mm / im.width;
    m.scale_z_mm = p.pixel_um / 1000.0;
    m.distance_mm = bscans > 1 ? p.height_mm / static_cast<double>(bscans - 1) : 0.0;
    m.pattern = bscans > 1 ? ScanPattern::kVolume : ScanPattern::kLine;
    m.scan_pattern_code = im.type;
    scan.bscans.resize(bscans);
    // On the fundus (mm, x right, y down, origin at the scan's upper left): A-scans left to
    // right, B-scan 0 at the bottom (inferior edge), the last at the top.
    const double last_x = (m.size_x - 1) * m.scale_x_mm;
    for (std::size_t b = 0; b < bscans; ++b) {
        BScan& bs = scan.bscans[b];
        bs.version = "TOPCON";
        bs.start_x_mm = 0.0;
        bs.end_x_mm = last_x;
        bs.start_y_mm = bs.end_y_mm = static_cast<double>(bscans - 1 - b) * m.distance_mm;
    }
}

// ---- JPEG 2000 B-scans (OpenJPEG) ------------------------------------------------------------

// A codestream in memory as an OpenJPEG stream.
struct MemoryStream {
    std::string_view bytes;
    std::size_t at = 0;
};

OPJ_SIZE_T stream_read(void* buffer, OPJ_SIZE_T n, void* user) {
    auto* m = static_cast<MemoryStream*>(user);
    if (m->at >= m->bytes.size()) return static_cast<OPJ_SIZE_T>(-1);
    const std::size_t k = std::min<std::size_t>(n, m->bytes.size() - m->at);
    std::memcpy(buffer, m->bytes.data() + m->at, k);
    m->at += k;
    return k;
}

OPJ_OFF_T stream_skip(OPJ_OFF_T n, void* user) {
    auto* m = static_cast<MemoryStream*>(user);
    if (n < 0 || static_cast<std::size_t>(n) > m->bytes.size() - m->at) return -1;
    m->at += static_cast<std::size_t>(n);
    return n;
}

OPJ_BOOL stream_seek(OPJ_OFF_T n, void* user) {
    auto* m = static_cast<MemoryStream*>(user);
    if (n < 0 || static_cast<std::size_t>(n) > m->bytes.size()) return OPJ_FALSE;
    m->at = static_cast<std::size_t>(n);
    return OPJ_TRUE;
}

void quiet(const char*, void*) {}  // OpenJPEG's messages: the error says what matters

// Owns OpenJPEG's objects for one frame.
struct J2kFrame {
    opj_stream_t* stream = nullptr;
    opj_codec_t* codec = nullptr;
    opj_image_t* image = nullptr;
    J2kFrame() = default;
    J2kFrame(const J2kFrame&) = delete;
    J2kFrame& operator=(const J2kFrame&) = delete;
    ~J2kFrame() {
        if (image != nullptr) opj_image_destroy(image);
        if (codec != nullptr) opj_destroy_codec(codec);
        if (stream != nullptr) opj_stream_destroy(stream);
    }
};

// Decodes frame `f` into `out` (height x width, row 0 at the top as the codestream stores it),
// grey values g of p bits as (g / (2^p - 1))^4: the device stores display values, and the QC
// pictures show v^0.25 of a linear reflectance. The sides are checked against the chunk's
// before anything is decoded, so OpenJPEG allocates no more than one B-scan.
void decode_frame(const ImageInfo& im,
                  std::size_t f,
                  const std::string& path,
                  std::vector<float>& out) {
    const auto fail = [&](const std::string& what) {
        throw InputError::corrupt(path, "B-scan frame " + std::to_string(f) + ": " + what,
                                  im.frame_offsets[f]);
    };
    MemoryStream mem{im.codestreams[f], 0};
    J2kFrame j;
    j.stream = opj_stream_default_create(OPJ_TRUE);
    j.codec = opj_create_decompress(OPJ_CODEC_J2K);
    if (j.stream == nullptr || j.codec == nullptr) fail("the JPEG 2000 decoder cannot start");
    opj_stream_set_read_function(j.stream, stream_read);
    opj_stream_set_skip_function(j.stream, stream_skip);
    opj_stream_set_seek_function(j.stream, stream_seek);
    opj_stream_set_user_data(j.stream, &mem, nullptr);
    opj_stream_set_user_data_length(j.stream, mem.bytes.size());
    opj_set_error_handler(j.codec, quiet, nullptr);
    opj_set_warning_handler(j.codec, quiet, nullptr);
    opj_set_info_handler(j.codec, quiet, nullptr);
    opj_dparameters_t params;
    opj_set_default_decoder_parameters(&params);
    if (!opj_setup_decoder(j.codec, &params) || !opj_read_header(j.stream, j.codec, &j.image) ||
        j.image == nullptr) {
        fail("damaged JPEG 2000 header");
    }
    const opj_image_t& h = *j.image;
    if (h.numcomps < 1 || h.x1 - h.x0 != im.width || h.y1 - h.y0 != im.height) {
        fail("JPEG 2000 image of " + std::to_string(h.x1 - h.x0) + " x " +
             std::to_string(h.y1 - h.y0) + " px, the chunk says " + std::to_string(im.width) +
             " x " + std::to_string(im.height));
    }
    if (!opj_decode(j.codec, j.stream, j.image) || !opj_end_decompress(j.codec, j.stream)) {
        fail("damaged JPEG 2000 codestream");
    }
    const opj_image_comp_t& c = j.image->comps[0];
    if (c.data == nullptr || c.w != im.width || c.h != im.height || c.prec < 1 || c.prec > 16) {
        fail("unexpected JPEG 2000 component");
    }
    const double max = std::ldexp(1.0, static_cast<int>(c.prec)) - 1.0;
    const std::size_t n = std::size_t{im.width} * im.height;
    out.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
        const double v = std::clamp(static_cast<double>(c.data[i]) / max, 0.0, 1.0);
        out[i] = static_cast<float>(v * v * v * v);
    }
}

// Pixels when asked and the file holds a frame for every B-scan (frame k is B-scan k: checked
// on the real file, docs/formats.md); otherwise a note says why there are none.
void load_pixels(Scan& scan, const ImageInfo& im, const std::string& path) {
    if (im.codestreams.empty() && im.frames > 0) {
        scan.notes.push_back("raw B-scans (" + im.chunk +
                             ") not decoded: their row order is "
                             "unverified");
        return;
    }
    // Compressed frames can claim far more pixels than the file has bytes: at most 2^24 px a
    // B-scan and 2^28 px (1 GiB of floats) a scan. A UK Biobank cube is 512 x 650 x 128 =
    // 2^25.3 px; 512 x 885 x 256 = 2^26.8.
    const std::uint64_t per_frame = std::uint64_t{im.width} * im.height;
    if (per_frame > (std::uint64_t{1} << 24) ||
        per_frame * scan.bscans.size() > (std::uint64_t{1} << 28)) {
        throw InputError::unsupported(path, "B-scan images of " + std::to_string(im.width) + " x " +
                                                std::to_string(im.height) + " px x " +
                                                std::to_string(scan.bscans.size()) +
                                                " B-scans: more pixels than this reader decodes");
    }
    if (im.codestreams.size() != scan.bscans.size()) {
        scan.notes.push_back("B-scan pixels not loaded: the file holds " +
                             std::to_string(im.codestreams.size()) + " of " +
                             std::to_string(scan.bscans.size()) + " B-scan images");
        return;
    }
    for (std::size_t b = 0; b < scan.bscans.size(); ++b) {
        decode_frame(im, b, path, scan.bscans[b].pixels);
    }
    scan.pixels_loaded = true;
}

}  // namespace

bool looks_like_topcon(const char* head, std::size_t n) {
    if (n < 7 || std::memcmp(head, "FOCT", 4) != 0) return false;
    const std::string_view kind(head + 4, 3);
    return kind == "FDA" || kind == "FDS" || kind == "FAA";
}

Scan parse_topcon(std::string_view d, const std::string& path, const ReadOptions& options) {
    if (d.size() < kHeaderSize)
        throw InputError::truncated(path, "file ends inside the header", d.size());
    if (!looks_like_topcon(d.data(), d.size())) {
        throw InputError::unsupported(path, "not a Topcon file (no FOCT header)", 0);
    }
    Scan scan;
    scan.source_path = path;
    scan.meta.format = SourceFormat::kTopcon;
    const std::string kind(d.substr(4, 3));
    const std::vector<Chunk> chunks = list_chunks(d, path, scan.notes);
    read_device(d, chunks, path, scan,
                kind == "FDS"   ? ".fds"
                : kind == "FAA" ? ".fda (external fixation)"
                                : ".fda");
    const ImageInfo im = read_image_info(d, chunks, path);
    if (im.type > 2) {
        throw InputError::unsupported(path, "Topcon scan type " + std::to_string(im.type) +
                                                " (only line (0) and rectangular volume (2) scans "
                                                "are read)");
    }
    const ScanParams params = read_scan_params(d, chunks, path);
    const std::vector<Contour> contours = read_contours(d, chunks, path);
    if (contours.empty()) {
        throw InputError::unsupported(path,
                                      "no layer contours (@CONTOUR_INFO): the device "
                                      "segmentation is needed");
    }
    set_geometry(scan, im, params, contours.front().height);
    if (im.frames != contours.front().height) {
        scan.notes.push_back("the file holds " + std::to_string(im.frames) + " of " +
                             std::to_string(contours.front().height) + " B-scan images");
    }
    read_capture(d, chunks, path, scan);
    read_patient(d, chunks, path, scan);
    set_lines(scan, contours, options.iowa_bm, path);
    check_order(scan, path);
    scan.notes.push_back("segmentation: the device's contours, BM = " +
                         std::string(options.iowa_bm == IowaBm::kOuterRpe
                                         ? "RETINA_4 (outer boundary of the RPE)"
                                         : "RETINA_3 (inner boundary of the RPE)"));
    if (options.pixels) load_pixels(scan, im, path);
    if (scan.meta.laterality == Laterality::kUnknown) scan.notes.push_back("laterality not stated");
    return scan;
}

Scan read_topcon(const std::string& path, const ReadOptions& options) {
    std::error_code ec;
    const auto size = std::filesystem::file_size(path, ec);
    if (ec) throw InputError::unreadable(path, ec.message());
    if (size > kTopconMaxFileBytes) {
        throw InputError::unsupported(path,
                                      "larger than 1 GiB: not a Topcon scan this reader takes", 0);
    }
    std::ifstream in(path, std::ios::binary);
    if (!in) throw InputError::unreadable(path, "cannot open");
    std::string data(static_cast<std::size_t>(size), '\0');
    in.read(data.data(), static_cast<std::streamsize>(size));
    if (static_cast<std::uint64_t>(in.gcount()) != size) {
        throw InputError::truncated(path, "file shorter than its size while read",
                                    static_cast<std::uint64_t>(in.gcount()));
    }
    return parse_topcon(data, path, options);
}

namespace {

void put_chunk(std::ostream& out, std::string_view name, const std::string& data) {
    out.put(static_cast<char>(name.size()));
    out.write(name.data(), static_cast<std::streamsize>(name.size()));
    const auto n = static_cast<std::uint32_t>(data.size());
    out.write(reinterpret_cast<const char*>(&n), 4);
    out.write(data.data(), static_cast<std::streamsize>(data.size()));
}

template <typename T>
void put(std::string& s, std::size_t at, T v) {
    std::memcpy(s.data() + at, &v, sizeof(T));
}

// One contour chunk: heights above the bottom of the B-scan, 0 for a missing value.
std::string contour_chunk(const Scan& scan, std::string_view id, int line, int shift_px) {
    const auto nx = static_cast<std::size_t>(scan.meta.size_x);
    const int nz = scan.meta.size_z;
    const std::size_t n = nx * scan.bscans.size();
    std::string c(kContourHeader + 2 * n + 32, '\0');
    std::memcpy(c.data(), id.data(), id.size());
    put<std::uint32_t>(c, 22, static_cast<std::uint32_t>(nx));
    put<std::uint32_t>(c, 26, static_cast<std::uint32_t>(scan.bscans.size()));
    put<std::uint32_t>(c, 30, static_cast<std::uint32_t>(2 * n));
    for (std::size_t b = 0; b < scan.bscans.size(); ++b) {
        for (std::size_t a = 0; a < nx; ++a) {
            const float depth = scan.bscans[b].seg[static_cast<std::size_t>(line)][a];
            std::uint16_t v = 0;
            if (is_valid(depth)) {
                const long h = nz - 1 - std::lround(depth) + shift_px;
                if (h <= 0 || h >= nz) {
                    throw UsageError("write_topcon: a depth of " + std::to_string(depth) +
                                     " px lies outside the B-scan's " + std::to_string(nz) +
                                     " px (a Topcon contour cannot hold it)");
                }
                v = static_cast<std::uint16_t>(h);
            }
            put<std::uint16_t>(c, kContourHeader + 2 * (b * nx + a), v);
        }
    }
    std::memcpy(c.data() + kContourHeader + 2 * n, "octshape", 8);
    return c;
}

}  // namespace

void write_topcon(const Scan& scan, std::ostream& out, int inner_rpe_px) {
    const ScanMeta& m = scan.meta;
    if (scan.bscans.size() < 2 || m.size_x < 1 || m.size_z < 2 || m.size_z > 65535 ||
        m.size_x > static_cast<int>(kMaxSide) || scan.bscans.size() > kMaxSide ||
        !(m.scale_x_mm > 0.0) || !(m.scale_z_mm > 0.0) || !(m.distance_mm > 0.0)) {
        throw UsageError("write_topcon: needs a volume of at least 2 B-scans with its sizes");
    }
    for (const BScan& b : scan.bscans) {
        if (b.num_seg() < 2 || b.seg[0].size() != static_cast<std::size_t>(m.size_x) ||
            b.seg[1].size() != static_cast<std::size_t>(m.size_x)) {
            throw UsageError("write_topcon: every B-scan needs its ILM and BM lines");
        }
    }
    out.write("FOCTFDA", 7);
    const std::array<std::uint32_t, 2> version{2, 1000};
    out.write(reinterpret_cast<const char*>(version.data()), 8);
    std::string hw(100, '\0');
    std::memcpy(hw.data(), "octshape", 8);
    put_chunk(out, "@HW_INFO_03", hw);
    std::string capture(118, '\0');
    capture[0] = static_cast<char>(m.laterality == Laterality::kOS ? 1 : 0);
    if (m.laterality == Laterality::kUnknown) capture[0] = 2;
    put_chunk(out, "@CAPTURE_INFO_02", capture);
    std::string param(61, '\0');
    put<double>(param, 12, m.scale_x_mm * m.size_x);
    put<double>(param, 20, m.distance_mm * static_cast<double>(scan.bscans.size() - 1));
    put<double>(param, 28, m.scale_z_mm * 1000.0);
    put_chunk(out, "@PARAM_SCAN_04", param);
    std::string jpeg(25, '\0');
    jpeg[0] = 2;  // rectangular volume
    put<std::uint32_t>(jpeg, 9, static_cast<std::uint32_t>(m.size_x));
    put<std::uint32_t>(jpeg, 13, static_cast<std::uint32_t>(m.size_z));
    put<std::uint32_t>(jpeg, 21, 0xA02U);
    put_chunk(out, "@IMG_JPEG", jpeg);
    put_chunk(out, "@CONTOUR_INFO", contour_chunk(scan, "RETINA_1", 0, 0));
    put_chunk(out, "@CONTOUR_INFO", contour_chunk(scan, "RETINA_3", 1, std::max(1, inner_rpe_px)));
    put_chunk(out, "@CONTOUR_INFO", contour_chunk(scan, "RETINA_4", 1, 0));
    out.put('\0');
    if (!out) throw OutputError("", "write_topcon: the stream failed");
}

void write_topcon_file(const Scan& scan, const std::string& path) {
    // Validate first (into a discarded buffer), so that a scan that cannot be written leaves no
    // temporary file behind.
    std::ostringstream probe;
    write_topcon(scan, probe);
    write_file_atomically(path, [&probe](std::ostream& out) { out << probe.str(); });
}

}  // namespace octshape::io
