// Hostile and damaged .vol input (docs/formats.md "Validation", "Robustness evidence"): every
// truncation, wrong magic, absurd sizes, NaN and FLT_MAX in every floating-point field, seeded
// random mutations. The reader must throw InputError (never anything else, never crash) and never
// allocate more than the file allows.

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "io/alloc_probe.h"
#include "io/vol_test_util.h"
#include "octshape/error.h"
#include "octshape/io/vol.h"
#include "test_paths.h"

namespace octshape::test {
namespace {

using Kind = InputError::Kind;

// The small valid file: 2 B-scans x 8 A-scans x 6 px, a 4x4 SLO, 3 lines, a circular grid
// declared in the header. BScanHdrSize = 512 (256 + 3 x 8 x 4 = 352, rounded up).
constexpr std::size_t kSlo = 2048;
constexpr std::size_t kBScan0 = 2048 + 16;
constexpr std::size_t kHdr = 512;
constexpr std::size_t kPixels = 8 * 6 * 4;
constexpr std::size_t kBScan1 = kBScan0 + kHdr + kPixels;
constexpr std::size_t kGrid = kBScan1 + kHdr + kPixels;
constexpr std::size_t kFileSize = kGrid + 132;

const std::string& small_file() {
    static const std::string bytes = [] {
        io::Scan s = make_synthetic_scan(
            {.num_bscans = 2, .size_x = 8, .size_z = 6, .num_lines = 3, .slo_x = 4, .slo_y = 4});
        s.grids.push_back(make_circular_grid(true));
        return write_to_string(s);
    }();
    return bytes;
}

// Allocations a reader may make for a file of n bytes: the data it holds (at most n) and one
// BScan record (~200 bytes) per B-scan, each of which takes at least 60 bytes of file (a v101
// header with OffSeg = 56, one A-scan, one pixel): below 4n, plus the fixed 2 KiB header buffer.
std::size_t allowed_allocation(std::size_t n) { return 4 * n + 4096; }

// Checks what a successful read returns: sizes consistent, missing values NaN, no garbage.
void expect_sane(const io::Scan& s, bool pixels) {
    ASSERT_GE(s.num_bscans(), 1);
    EXPECT_GT(s.meta.scale_x_mm, 0.0);
    EXPECT_GT(s.meta.scale_z_mm, 0.0);
    EXPECT_TRUE(std::isfinite(s.meta.distance_mm));
    for (const io::BScan& b : s.bscans) {
        for (const auto& line : b.seg) {
            ASSERT_EQ(line.size(), static_cast<std::size_t>(s.meta.size_x));
            for (float v : line) {
                ASSERT_TRUE(std::isnan(v) || (std::isfinite(v) && std::fabs(v) < 1e30F)) << v;
            }
        }
        ASSERT_EQ(b.pixels.size(), pixels ? static_cast<std::size_t>(s.meta.size_x) *
                                                static_cast<std::size_t>(s.meta.size_z)
                                          : 0U);
        for (float v : b.pixels) ASSERT_TRUE(std::isfinite(v)) << v;
    }
    for (const io::ThicknessGrid& g : s.grids) {
        ASSERT_TRUE(g.is_circular() || g.is_rectangular());
        ASSERT_EQ(g.cells.size(), g.is_circular() ? 9U : static_cast<std::size_t>(g.rows * g.cols));
    }
}

enum class Outcome { kRead, kInputError };

// Reads `bytes` both ways under the allocation probe; fails the test on anything but a clean
// read or an InputError naming the file.
Outcome read_both_ways(const std::string& bytes, const std::string& label) {
    Outcome out = Outcome::kRead;
    for (const bool pixels : {false, true}) {
        std::istringstream in(bytes, std::ios::binary);
        io::ReadOptions opt;
        opt.pixels = pixels;
        AllocProbe probe;
        try {
            const io::Scan s = io::read_vol(in, bytes.size(), "hostile.vol", opt);
            EXPECT_LE(probe.largest(), allowed_allocation(bytes.size())) << label;
            expect_sane(s, pixels);
        } catch (const InputError& e) {
            EXPECT_LE(probe.largest(), allowed_allocation(bytes.size())) << label;
            EXPECT_EQ(e.path(), "hostile.vol");
            EXPECT_FALSE(e.reason().empty());
            out = Outcome::kInputError;
        } catch (const std::exception& e) {
            ADD_FAILURE() << label << ": not an InputError: " << e.what();
            out = Outcome::kInputError;
        }
    }
    return out;
}

// The InputError of reading `bytes` (fast path), or a test failure if it reads.
InputError expect_error(const std::string& bytes, const std::string& label, bool pixels = false) {
    std::istringstream in(bytes, std::ios::binary);
    io::ReadOptions opt;
    opt.pixels = pixels;
    AllocProbe probe;
    try {
        (void)io::read_vol(in, bytes.size(), "hostile.vol", opt);
    } catch (const InputError& e) {
        EXPECT_LE(probe.largest(), allowed_allocation(bytes.size())) << label;
        return e;
    }
    ADD_FAILURE() << label << ": read without error";
    return InputError(Kind::kCorrupt, "", "");
}

void expect_error_at(const std::string& bytes,
                     Kind kind,
                     std::uint64_t offset,
                     const std::string& reason_part,
                     const std::string& label) {
    const InputError e = expect_error(bytes, label);
    EXPECT_EQ(e.kind(), kind) << label << ": " << e.what();
    EXPECT_EQ(e.offset(), std::optional<std::uint64_t>(offset)) << label << ": " << e.what();
    EXPECT_NE(e.reason().find(reason_part), std::string::npos) << label << ": " << e.what();
    // One line, naming the file.
    EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos);
    EXPECT_EQ(std::string(e.what()).rfind("hostile.vol: ", 0), 0U) << e.what();
}

TEST(VolBadInput, TheSmallFileIsValid) {
    ASSERT_EQ(small_file().size(), kFileSize);
    const io::Scan s = read_from_string(small_file(), true);
    EXPECT_EQ(s.meta.bscan_hdr_size, kHdr);
    ASSERT_EQ(s.grids.size(), 1U);
    EXPECT_EQ(s.grids[0].file_offset, kGrid);
    EXPECT_TRUE(s.notes.empty());
}

TEST(VolBadInput, EveryTruncationLengthIsATruncatedError) {
    const std::string& f = small_file();
    std::size_t cases = 0;
    for (std::size_t len = 0; len < f.size(); ++len) {
        const std::string cut = f.substr(0, len);
        for (const bool pixels : {false, true}) {
            const InputError e = expect_error(cut, "length " + std::to_string(len), pixels);
            ASSERT_EQ(e.kind(), Kind::kTruncated) << "length " << len << ": " << e.what();
            ASSERT_TRUE(e.offset().has_value());
            ASSERT_LE(*e.offset(), len) << e.what();
            ++cases;
        }
    }
    std::cout << "[ vol truncation ] " << cases << " truncated files (" << f.size()
              << " lengths x 2 read modes): all InputError::kTruncated\n";
}

TEST(VolBadInput, AStreamShorterThanItsDeclaredSizeIsTruncated) {
    const std::string& f = small_file();
    std::istringstream in(f.substr(0, f.size() - 1), std::ios::binary);
    try {
        (void)io::read_vol(in, f.size(), "short.vol");
        FAIL() << "accepted";
    } catch (const InputError& e) {
        EXPECT_EQ(e.kind(), Kind::kTruncated);
        EXPECT_NE(e.reason().find("stream ended early"), std::string::npos) << e.what();
    }
}

TEST(VolBadInput, EmptyStreamAndDirectory) {
    std::istringstream empty("");
    try {
        (void)io::read_vol(empty, 0, "empty.vol");
        FAIL() << "accepted";
    } catch (const InputError& e) {
        EXPECT_EQ(e.kind(), Kind::kTruncated);
        EXPECT_EQ(e.offset(), std::optional<std::uint64_t>(0));
    }
    // A directory opened as a stream reads nothing, whatever size the caller believed.
    TempDir dir;
    std::ifstream d(dir.path(), std::ios::binary);
    EXPECT_THROW((void)io::read_vol(d, 4096, dir.path().string()), InputError);
}

TEST(VolBadInput, WrongMagicIsUnsupportedAndSaysWhatWasFound) {
    const std::vector<std::pair<std::string, std::string>> magics = {
        {"GIF89a", "GIF89a"},
        {"HSF-OCX-103", "HSF-OCX-103"},
        {"hsf-oct-103", "hsf-oct-103"},
        {"HSF-BS-103", "HSF-BS-103"},
        {std::string("\x89PNG\r\n\x1a\n", 8), "\\x89PNG\\x0d\\x0a\\x1a\\x0a"},
        {"ep-v0.6.8   ", "ep-v0.6.8"},
    };
    for (const auto& [magic, shown] : magics) {
        std::string f = small_file();
        f.replace(0, magic.size(), magic);
        expect_error_at(f, Kind::kUnsupported, 0, shown, "magic " + shown);
        // A short file of another kind is also called what it is.
        expect_error_at(f.substr(0, 9), Kind::kUnsupported, 0, "not a Heidelberg",
                        "short " + shown);
    }
}

struct Patch {
    std::string label;
    std::size_t offset;
    std::uint64_t value;
    int bytes;  // 4 or 8
    Kind kind;
    std::uint64_t error_offset;
    std::string reason_part;
};

TEST(VolBadInput, AbsurdSizesAndOffsetsAreRejectedBeforeAllocating) {
    const std::uint64_t u32max = 0xFFFFFFFFULL;
    const auto neg = [](std::int32_t v) {
        return static_cast<std::uint64_t>(static_cast<std::uint32_t>(v));
    };
    const std::vector<Patch> patches = {
        {"SizeX 2^31", 12, 1ULL << 31, 4, Kind::kCorrupt, 12, "SizeX"},
        {"SizeX 0", 12, 0, 4, Kind::kCorrupt, 12, "SizeX"},
        {"SizeX 65536", 12, 65536, 4, Kind::kTruncated, kBScan0 + kHdr, "B-scan 0 pixels"},
        {"NumBScans 2^32-1", 16, u32max, 4, Kind::kCorrupt, 16, "NumBScans"},
        {"NumBScans 0", 16, 0, 4, Kind::kCorrupt, 16, "NumBScans"},
        {"NumBScans 65536", 16, 65536, 4, Kind::kTruncated, kGrid, "B-scan 2 header"},
        {"SizeZ 2^32-1", 20, u32max, 4, Kind::kCorrupt, 20, "SizeZ"},
        {"SizeZ 65536", 20, 65536, 4, Kind::kTruncated, kBScan0 + kHdr, "B-scan 0 pixels"},
        {"SizeXSlo 2^32-1", 48, u32max, 4, Kind::kCorrupt, 48, "SizeXSlo"},
        {"SizeYSlo 16384 (x 4)", 52, 16384, 4, Kind::kTruncated, 2048, "SLO"},
        {"BScanHdrSize 2^32-1", 100, u32max, 4, Kind::kCorrupt, 100, "BScanHdrSize"},
        {"BScanHdrSize 8", 100, 8, 4, Kind::kCorrupt, 100, "BScanHdrSize"},
        {"BScanHdrSize 2^26", 100, 1ULL << 26, 4, Kind::kCorrupt, kBScan0 + 12,
         "contradictory header sizes"},
        {"B-scan 1 BScanHdrSize", kBScan1 + 12, 1024, 4, Kind::kCorrupt, kBScan1 + 12,
         "contradictory header sizes"},
        {"B-scan 1 magic", kBScan1, 0x4D454F57, 4, Kind::kCorrupt, kBScan1, "magic"},
        {"NumSeg -1", kBScan0 + 48, neg(-1), 4, Kind::kCorrupt, kBScan0 + 48, "NumSeg"},
        {"NumSeg 2^31-1", kBScan0 + 48, 0x7FFFFFFF, 4, Kind::kCorrupt, kBScan0 + 48, "NumSeg"},
        {"NumSeg 9 (too many)", kBScan1 + 48, 9, 4, Kind::kCorrupt, kBScan1 + 48, "do not fit"},
        {"OffSeg past header", kBScan0 + 52, kHdr + 4, 4, Kind::kCorrupt, kBScan0 + 52, "OffSeg"},
        {"OffSeg -1", kBScan0 + 52, neg(-1), 4, Kind::kCorrupt, kBScan0 + 52, "OffSeg"},
        {"OffSeg 0 (over the fixed fields)", kBScan0 + 52, 0, 4, Kind::kCorrupt, kBScan0 + 52,
         "OffSeg"},
        {"GridOffset past EOF", 212, kFileSize + 100, 4, Kind::kTruncated, 212, "GridOffset"},
        {"GridOffset 2^31-1", 212, 0x7FFFFFFF, 4, Kind::kTruncated, 212, "GridOffset"},
        {"GridOffset -5", 212, neg(-5), 4, Kind::kCorrupt, 212, "GridOffset"},
        {"GridOffset into header", 212, 100, 4, Kind::kCorrupt, 212, "GridOffset"},
        {"GridOffset 10 before EOF", 212, kFileSize - 10, 4, Kind::kTruncated, kFileSize - 10,
         "thickness grid"},
        {"GridType 9 at a circular grid", 208, 9, 4, Kind::kCorrupt, kGrid, "type"},
        {"GridType1 9 pointing at the circular grid", 216, 9, 4, Kind::kCorrupt, kGrid, "type"},
    };
    for (const Patch& p : patches) {
        std::string f = small_file();
        if (p.bytes == 4) {
            put_u32(f, p.offset, static_cast<std::uint32_t>(p.value));
        } else {
            put_u64(f, p.offset, p.value);
        }
        if (p.label.rfind("GridType1", 0) == 0) put_i32(f, 220, static_cast<std::int32_t>(kGrid));
        expect_error_at(f, p.kind, p.error_offset, p.reason_part, p.label);
        read_both_ways(f, p.label);  // the allocation bound in both modes
    }
}

TEST(VolBadInput, RectangularGridWithAbsurdSideIsRejected) {
    io::Scan s = make_synthetic_scan({.num_bscans = 1, .size_x = 4, .size_z = 2, .num_lines = 1});
    s.grids.push_back(make_rect_grid());
    std::string f = write_to_string(s);
    const std::size_t grid = static_cast<std::size_t>(get_u32(f, 212));
    put_u32(f, grid + 4, 1U << 30);  // rows
    expect_error_at(f, Kind::kCorrupt, grid + 4, "grid rows", "rows 2^30");
    put_u32(f, grid + 4, 1000);  // within bounds, but 1000 x 4 cells are not in the file
    expect_error_at(f, Kind::kTruncated, grid + 40, "cells", "rows 1000");
}

TEST(VolBadInput, UnknownGridTypeIsSkippedWithANote) {
    std::string f = small_file();
    put_i32(f, 208, 77);
    const io::Scan s = read_from_string(f, false);
    EXPECT_TRUE(s.grids.empty());
    EXPECT_EQ(s.meta.grid_type, 77);
    ASSERT_EQ(s.notes.size(), 1U);
    EXPECT_NE(s.notes[0].find("unknown type 77"), std::string::npos);
}

// ---- NaN, infinities and FLT_MAX in every floating-point field ------------------------------

struct FloatField {
    std::string name;
    std::size_t offset;
    bool is_f64;
    bool rejected;  // true: InputError::kCorrupt at this offset; false: read as missing
};

std::vector<FloatField> float_fields() {
    std::vector<FloatField> f = {
        {"ScaleX", 24, true, true},    {"Distance", 32, true, true},
        {"ScaleZ", 40, true, true},    {"ScaleXSlo", 56, true, true},
        {"ScaleYSlo", 64, true, true}, {"ScanFocus", 76, true, true},
        {"DOB", 164, true, false},     {"VisitDate", 200, true, false},
    };
    for (const std::size_t b : {kBScan0, kBScan1}) {
        const std::string n = b == kBScan0 ? "B-scan 0 " : "B-scan 1 ";
        f.push_back({n + "StartX", b + 16, true, true});
        f.push_back({n + "StartY", b + 24, true, true});
        f.push_back({n + "EndX", b + 32, true, true});
        f.push_back({n + "EndY", b + 40, true, true});
        f.push_back({n + "Quality", b + 56, false, true});
        for (std::size_t i = 0; i < 6; ++i) {
            f.push_back({n + "IVTrafo" + std::to_string(i), b + 64 + 4 * i, false, true});
        }
    }
    f.push_back({"grid diameter 0", kGrid + 4, true, true});
    f.push_back({"grid diameter 2", kGrid + 20, true, true});
    f.push_back({"grid centre X", kGrid + 28, true, true});
    f.push_back({"grid centre Y", kGrid + 36, true, true});
    for (std::size_t i = 0; i < 4 + 18; ++i) {
        f.push_back({"grid f32 " + std::to_string(i), kGrid + 44 + 4 * i, false, false});
    }
    return f;
}

TEST(VolBadInput, NanInfAndFltMaxInEveryFloatHeaderField) {
    const double dnan = std::numeric_limits<double>::quiet_NaN();
    const double dinf = std::numeric_limits<double>::infinity();
    const float fnan = std::numeric_limits<float>::quiet_NaN();
    const float finf = std::numeric_limits<float>::infinity();
    const float fmax = std::numeric_limits<float>::max();
    const std::vector<double> f64_values = {dnan,  -dnan, dinf,
                                            -dinf, fmax,  std::numeric_limits<double>::max()};
    const std::vector<float> f32_values = {fnan, -fnan, finf, -finf, fmax, -fmax};
    const io::Scan good = read_from_string(small_file(), false);
    std::size_t cases = 0;
    for (const FloatField& field : float_fields()) {
        const std::size_t n = field.is_f64 ? f64_values.size() : f32_values.size();
        for (std::size_t i = 0; i < n; ++i) {
            std::string f = small_file();
            if (field.is_f64) {
                put_f64(f, field.offset, f64_values[i]);
            } else {
                put_f32(f, field.offset, f32_values[i]);
            }
            const std::string label = field.name + " value #" + std::to_string(i);
            ++cases;
            if (field.rejected) {
                expect_error_at(f, Kind::kCorrupt, field.offset, "", label);
                continue;
            }
            const io::Scan s = read_from_string(f, false);
            if (field.name == "DOB") {
                EXPECT_FALSE(s.meta.ids.dob_ole.has_value()) << label;
                EXPECT_EQ(s.notes.size(), 1U) << label;
            } else if (field.name == "VisitDate") {
                EXPECT_FALSE(s.meta.visit_date_ole.has_value()) << label;
                EXPECT_EQ(s.notes.size(), 1U) << label;
            } else {
                // Grid thickness/volume values: missing (NaN), like invalid segmentation.
                const std::size_t k = (field.offset - kGrid - 44) / 4;
                const io::ThicknessGrid& g = s.grids.at(0);
                const float got =
                    k < 4 ? std::array<float, 4>{g.central_thickness_mm, g.min_central_thickness_mm,
                                                 g.max_central_thickness_mm, g.total_volume_mm3}[k]
                          : (k % 2 == 0 ? g.cells[(k - 4) / 2].thickness_mm
                                        : g.cells[(k - 4) / 2].volume_mm3);
                EXPECT_TRUE(std::isnan(got)) << label;
            }
            // Everything else is read as before.
            EXPECT_EQ(s.meta.scale_x_mm, good.meta.scale_x_mm);
            EXPECT_EQ(s.num_bscans(), good.num_bscans());
        }
    }
    std::cout << "[ vol NaN/inf/FLT_MAX ] " << cases << " patched header fields\n";
}

TEST(VolBadInput, NegativeOrAbsurdScalesAreRejected) {
    const std::vector<std::pair<std::size_t, double>> bad = {
        {24, -0.01}, {24, 0.0},  {24, 1e6}, {32, -0.1}, {32, 1e9},
        {40, 0.0},   {40, -1.0}, {40, 5.0}, {56, -1.0}, {76, 1e4}};
    for (const auto& [off, v] : bad) {
        std::string f = small_file();
        put_f64(f, off, v);
        expect_error_at(f, Kind::kCorrupt, off, "", "f64 at " + std::to_string(off));
    }
}

TEST(VolBadInput, EveryInvalidSegmentationValueIsMissing) {
    const float fnan = std::numeric_limits<float>::quiet_NaN();
    const float finf = std::numeric_limits<float>::infinity();
    const float fmax = std::numeric_limits<float>::max();
    const std::vector<float> invalid = {fnan, -fnan, finf, -finf, fmax, -fmax, 1e30F, -1e30F};
    const io::Scan good = read_from_string(small_file(), false);
    std::size_t cases = 0;
    for (std::size_t b = 0; b < 2; ++b) {
        for (std::size_t k = 0; k < 3; ++k) {
            for (std::size_t a = 0; a < 8; ++a) {
                for (const float v : invalid) {
                    std::string f = small_file();
                    put_f32(f, (b == 0 ? kBScan0 : kBScan1) + 256 + (k * 8 + a) * 4, v);
                    const io::Scan s = read_from_string(f, false);
                    ++cases;
                    for (std::size_t bb = 0; bb < 2; ++bb) {
                        for (std::size_t kk = 0; kk < 3; ++kk) {
                            for (std::size_t aa = 0; aa < 8; ++aa) {
                                const float got = s.bscans[bb].seg[kk][aa];
                                if (bb == b && kk == k && aa == a) {
                                    ASSERT_TRUE(std::isnan(got));
                                } else {
                                    ASSERT_TRUE(same_float(got, good.bscans[bb].seg[kk][aa]));
                                }
                            }
                        }
                    }
                }
            }
        }
    }
    std::cout << "[ vol segmentation ] " << cases << " invalid values, all read as missing\n";
}

// ---- random mutations ---------------------------------------------------------------------

TEST(VolBadInput, RandomMutationsNeverCrash) {
    const std::string& base = small_file();
    std::mt19937_64 rng(20240611);
    std::size_t tried = 0;
    std::size_t read_ok = 0;
    std::size_t errors = 0;
    const auto count = [&](Outcome o) {
        ++tried;
        (o == Outcome::kRead ? read_ok : errors) += 1;
    };
    // Every byte set to 0x00, 0xFF and a random value.
    for (std::size_t i = 0; i < base.size(); ++i) {
        for (const int v : {0x00, 0xFF, static_cast<int>(rng() & 0xFFU)}) {
            if (static_cast<unsigned char>(base[i]) == v) continue;
            std::string f = base;
            f[i] = static_cast<char>(v);
            count(read_both_ways(f, "byte " + std::to_string(i)));
        }
    }
    // Dense sample of multi-byte damage: 1..16 random bytes, some in the header (where sizes
    // live), some anywhere, optionally followed by a random truncation or extension.
    for (int t = 0; t < 100000; ++t) {
        std::string f = base;
        const std::size_t n = 1 + rng() % 16;
        for (std::size_t j = 0; j < n; ++j) {
            const std::size_t span = (rng() % 2 == 0) ? 256 : f.size();
            f[rng() % span] = static_cast<char>(rng() & 0xFFU);
        }
        switch (rng() % 4) {
            case 0:
                f.resize(rng() % f.size());
                break;
            case 1:
                f.append(rng() % 300, static_cast<char>(rng() & 0xFFU));
                break;
            default:
                break;
        }
        count(read_both_ways(f, "mutation " + std::to_string(t)));
    }
    std::cout << "[ vol mutations ] " << tried
              << " mutated files tried (x 2 read modes): " << read_ok << " read cleanly, " << errors
              << " gave InputError, 0 crashes\n";
    EXPECT_EQ(tried, read_ok + errors);
    // Both outcomes occur: the sample reaches past the header checks into the data.
    EXPECT_GT(read_ok, 10000U);
    EXPECT_GT(errors, 10000U);
}

}  // namespace
}  // namespace octshape::test
