// .vol reader and writer: exact round trip, version branching on files crafted byte by byte,
// and the real Spectralis files in ../shared/realdata (values from docs/formats.md and the
// realdata README, each checked independently of the reader: geometry, format rules).

#include "octshape/io/vol.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <numbers>
#include <sstream>
#include <string>

#include "io/vol_test_util.h"
#include "octshape/error.h"
#include "test_paths.h"

namespace octshape::test {
namespace {

using octshape::InputError;

io::Scan read_file(const std::filesystem::path& p, bool pixels) {
    std::ifstream in(p, std::ios::binary);
    EXPECT_TRUE(in.good()) << p;
    io::ReadOptions opt;
    opt.pixels = pixels;
    return io::read_vol(in, std::filesystem::file_size(p), p.string(), opt);
}

bool has_note_containing(const io::Scan& s, const std::string& text) {
    return std::any_of(s.notes.begin(), s.notes.end(),
                       [&](const std::string& n) { return n.find(text) != std::string::npos; });
}

// ---- round trip --------------------------------------------------------------------------

TEST(VolRoundTrip, EveryFieldSegmentationValueAndPixelIsExact) {
    io::Scan s = make_synthetic_scan();
    s.grids.push_back(make_circular_grid(true));
    s.grids.push_back(make_rect_grid());
    const std::string bytes = write_to_string(s);
    const io::Scan r = read_from_string(bytes, true);
    expect_same_scan(s, r, true);
    EXPECT_TRUE(r.pixels_loaded);
    // Derived fields: 17 lines x 16 A-scans x 4 bytes at OffSeg 256 = 1344 -> 1536 (6 x 256).
    EXPECT_EQ(r.meta.bscan_hdr_size, 1536U);
    EXPECT_EQ(r.meta.grid_type, 3);
    EXPECT_EQ(r.meta.grid_type1, 9);
    const std::uint64_t end = 2048 + 10 * 8 + 3 * (1536 + 16 * 12 * 4);
    EXPECT_EQ(static_cast<std::uint64_t>(r.meta.grid_offset), end);
    EXPECT_EQ(static_cast<std::uint64_t>(r.meta.grid_offset1), end + 132);
    EXPECT_EQ(bytes.size(), end + 132 + 40 + 12 * 8);
    EXPECT_TRUE(r.notes.empty());
    // Writing what was read gives the same bytes.
    EXPECT_EQ(write_to_string(r), bytes);
}

TEST(VolRoundTrip, MissingValuesAreWrittenAsFltMax) {
    io::Scan s = make_synthetic_scan({.num_bscans = 1, .size_x = 8, .size_z = 4, .num_lines = 2});
    s.bscans[0].seg[1][3] = std::numeric_limits<float>::quiet_NaN();
    const std::string bytes = write_to_string(s);
    // Line 1, A-scan 3 of B-scan 0: header at 2048 + SLO, OffSeg 256.
    const std::size_t at = 2048 + 80 + 256 + (8 + 3) * 4;
    EXPECT_EQ(get_f32(bytes, at), std::numeric_limits<float>::max());
    EXPECT_TRUE(std::isnan(read_from_string(bytes, false).bscans[0].seg[1][3]));
}

TEST(VolRoundTrip, KeepsALargerBScanHeaderSizeAndChoosesTheSmallestOtherwise) {
    io::Scan s = make_synthetic_scan({.num_bscans = 2, .size_x = 8, .size_z = 4, .num_lines = 3});
    // 256 + 3 x 8 x 4 = 352 -> 512.
    EXPECT_EQ(read_from_string(write_to_string(s), false).meta.bscan_hdr_size, 512U);
    s.meta.bscan_hdr_size = 46080;
    EXPECT_EQ(read_from_string(write_to_string(s), false).meta.bscan_hdr_size, 46080U);
    s.meta.bscan_hdr_size = 300;  // too small for the lines: ignored
    EXPECT_EQ(read_from_string(write_to_string(s), false).meta.bscan_hdr_size, 512U);
}

TEST(VolRoundTrip, WithoutPixelsWritesNoDataAndZeroSlo) {
    io::Scan s = make_synthetic_scan(
        {.num_bscans = 2, .size_x = 8, .size_z = 4, .num_lines = 3, .pixels = false});
    const io::Scan r = read_from_string(write_to_string(s), true);
    expect_same_scan(s, r, false);
    for (const io::BScan& b : r.bscans) {
        ASSERT_EQ(b.pixels.size(), 32U);
        for (float v : b.pixels) EXPECT_EQ(v, io::kNoPixelData);
    }
    ASSERT_EQ(r.slo.size(), 80U);
    for (auto v : r.slo) EXPECT_EQ(v, 0);
}

TEST(VolRoundTrip, TrailingGridWithoutHeaderEntryIsFoundAgain) {
    io::Scan s = make_synthetic_scan({.num_bscans = 1, .size_x = 8, .size_z = 4, .num_lines = 2});
    s.grids.push_back(make_circular_grid(false));
    const io::Scan r = read_from_string(write_to_string(s), false);
    EXPECT_EQ(r.meta.grid_type, 0);
    ASSERT_EQ(r.grids.size(), 1U);
    EXPECT_FALSE(r.grids[0].from_header);
    expect_same_grid(s.grids[0], r.grids[0]);
    EXPECT_TRUE(has_note_containing(r, "after the last B-scan"));
}

TEST(VolRoundTrip, FastPathEqualsFullReadWithoutPixels) {
    io::Scan s = make_synthetic_scan();
    s.grids.push_back(make_circular_grid(true));
    const std::string bytes = write_to_string(s);
    const io::Scan full = read_from_string(bytes, true);
    const io::Scan fast = read_from_string(bytes, false);
    expect_same_scan(full, fast, false);
    EXPECT_FALSE(fast.pixels_loaded);
    EXPECT_TRUE(fast.slo.empty());
    for (const io::BScan& b : fast.bscans) EXPECT_TRUE(b.pixels.empty());
    EXPECT_EQ(full.notes, fast.notes);
}

TEST(VolRoundTrip, WriteVolFileIsAtomicAndReadable) {
    TempDir dir;
    const io::Scan s = make_synthetic_scan();
    const auto path = dir / "out.vol";
    io::write_vol_file(s, path.string());
    expect_same_scan(s, read_file(path, true), true);
    // Only the file itself is left in the directory (no temporary).
    int entries = 0;
    for ([[maybe_unused]] const auto& e : std::filesystem::directory_iterator(dir.path()))
        ++entries;
    EXPECT_EQ(entries, 1);
}

TEST(VolRoundTrip, UnwritableScanThrowsUsageErrorAndCreatesNoFile) {
    TempDir dir;
    io::Scan s = make_synthetic_scan();
    s.bscans[1].seg[0].pop_back();  // a line shorter than size_x
    const auto path = dir / "bad.vol";
    EXPECT_THROW(io::write_vol_file(s, path.string()), UsageError);
    EXPECT_TRUE(std::filesystem::is_empty(dir.path()));
    io::Scan t = make_synthetic_scan();
    t.meta.scale_x_mm = std::numeric_limits<double>::quiet_NaN();
    std::ostringstream out;
    EXPECT_THROW(io::write_vol(t, out), UsageError);
    io::Scan u = make_synthetic_scan();
    u.meta.ids.patient_id = std::string(25, 'x');  // PatientID holds 24 bytes
    EXPECT_THROW(io::write_vol(u, out), UsageError);
}

TEST(VolRoundTrip, UnwritableDestinationThrowsOutputError) {
    TempDir dir;
    const io::Scan s = make_synthetic_scan({.num_bscans = 1, .size_x = 4, .size_z = 2});
    EXPECT_THROW(io::write_vol_file(s, (dir / "no" / "such" / "dir.vol").string()), OutputError);
}

TEST(Vol, LooksLikeVol) {
    EXPECT_TRUE(io::looks_like_vol("HSF-OCT-103", 11));
    EXPECT_FALSE(io::looks_like_vol("HSF-OCT", 7));
    EXPECT_FALSE(io::looks_like_vol("ep-v0.6.8   ", 12));
}

// ---- versions, crafted byte by byte (independently of write_vol) --------------------------

// One B-scan of 4 A-scans x 3 px, 2 lines, a 2x2 SLO, BScanHdrSize 512, then a circular grid
// (132 bytes) and a rectangular 1x2 grid; GridType/GridType1 point at them.
std::string craft_vol(int version) {
    const std::string v = std::to_string(version);
    std::string f(2048, '\0');
    f.replace(0, 11, "HSF-OCT-" + v);
    put_u32(f, 12, 4);
    put_u32(f, 16, 1);
    put_u32(f, 20, 3);
    put_f64(f, 24, 0.01);
    put_f64(f, 32, 0.0);
    put_f64(f, 40, 0.0039);
    put_u32(f, 48, 2);
    put_u32(f, 52, 2);
    put_f64(f, 56, 0.02);
    put_f64(f, 64, 0.03);
    put_u32(f, 72, 30);
    put_f64(f, 76, 1.5);
    f.replace(84, 2, "OD");
    put_u64(f, 88, 130000000000000000ULL);
    put_u32(f, 96, 1);
    put_u32(f, 100, 512);
    f.replace(104, 1, "A");
    f.replace(120, 1, "B");
    put_u32(f, 136, 7);
    f.replace(140, 1, "P");
    put_f64(f, 164, 20000.5);
    put_u32(f, 172, 9);
    f.replace(176, 1, "V");
    put_f64(f, 200, 40000.25);
    const std::size_t bscan = 2048 + 4;
    const std::size_t grid0 = bscan + 512 + 4 * 3 * 4;
    put_i32(f, 208, 3);
    put_i32(f, 212, static_cast<std::int32_t>(grid0));
    put_i32(f, 216, 8);
    put_i32(f, 220, static_cast<std::int32_t>(grid0 + 132));
    f.replace(224, 7, "crafted");
    f += std::string("\x01\x02\x03\x04", 4);  // SLO
    std::string b(512, '\0');
    b.replace(0, 10, "HSF-BS-" + v);
    put_u32(b, 12, 512);
    put_f64(b, 16, 1.0);
    put_f64(b, 24, 2.0);
    put_f64(b, 32, 3.0);
    put_f64(b, 40, 2.0);
    put_i32(b, 48, 2);
    put_i32(b, 52, 256);
    put_f32(b, 56, 33.5F);
    put_i32(b, 60, -7);
    for (std::size_t i = 0; i < 6; ++i) put_f32(b, 64 + 4 * i, static_cast<float>(i + 1));
    for (std::size_t i = 0; i < 6; ++i) put_i32(b, 88 + 4 * i, static_cast<std::int32_t>(11 + i));
    const float inf = std::numeric_limits<float>::infinity();
    const float seg[8] = {1.5F,
                          std::numeric_limits<float>::max(),
                          2.5F,
                          inf,
                          std::numeric_limits<float>::quiet_NaN(),
                          3.25F,
                          -std::numeric_limits<float>::max(),
                          1e30F};
    for (std::size_t i = 0; i < 8; ++i) put_f32(b, 256 + 4 * i, seg[i]);
    f += b;
    for (int i = 0; i < 12; ++i) {
        std::string px(4, '\0');
        put_f32(px, 0, static_cast<float>(i) / 11.0F);
        f += px;
    }
    std::string g(132, '\0');
    put_i32(g, 0, 3);
    put_f64(g, 4, 1.0);
    put_f64(g, 12, 3.0);
    put_f64(g, 20, 6.0);
    put_f64(g, 28, 2.0);
    put_f64(g, 36, 2.0);
    put_f32(g, 44, 0.25F);
    f += g;
    std::string r(40 + 16, '\0');
    put_i32(r, 0, 8);
    put_i32(r, 4, 1);
    put_i32(r, 8, 2);
    put_f32(r, 12, 0.5F);
    put_f32(r, 16, 0.5F);
    put_f64(r, 24, 2.0);
    put_f64(r, 32, 2.5);
    put_f32(r, 40, 0.3F);
    put_f32(r, 48, 0.4F);
    f += r;
    return f;
}

class VolVersion : public ::testing::TestWithParam<int> {};

TEST_P(VolVersion, ReadsExactlyTheFieldsOfItsVersion) {
    const int v = GetParam();
    const std::string f = craft_vol(v);
    const io::Scan s = read_from_string(f, true);
    EXPECT_EQ(s.meta.version, "HSF-OCT-" + std::to_string(v));
    EXPECT_EQ(s.meta.size_x, 4);
    EXPECT_EQ(s.meta.size_z, 3);
    EXPECT_EQ(s.meta.laterality, io::Laterality::kOD);
    EXPECT_EQ(s.meta.pattern, io::ScanPattern::kLine);
    EXPECT_EQ(s.meta.ids.id, "A");
    EXPECT_EQ(s.meta.ids.reference_id, "B");
    EXPECT_EQ(s.meta.prog_id, "crafted");
    ASSERT_EQ(s.num_bscans(), 1);
    const io::BScan& b = s.bscans[0];
    EXPECT_EQ(b.version, "HSF-BS-" + std::to_string(v));
    // Fields of later versions are not read from older files, even though the bytes are set.
    EXPECT_EQ(s.meta.ids.pid, v >= 101 ? 7U : 0U);
    EXPECT_EQ(s.meta.ids.patient_id, v >= 101 ? "P" : "");
    EXPECT_EQ(s.meta.ids.dob_ole, v >= 101 ? std::optional<double>(20000.5) : std::nullopt);
    EXPECT_EQ(s.meta.visit_date_ole, v >= 101 ? std::optional<double>(40000.25) : std::nullopt);
    EXPECT_EQ(b.quality, v >= 101 ? 33.5F : 0.0F);
    EXPECT_EQ(b.shift, v >= 102 ? -7 : 0);
    EXPECT_EQ(b.iv_trafo[5], v >= 103 ? 6.0F : 0.0F);
    EXPECT_EQ(b.bmo.has_value(), v >= 104);
    if (b.bmo) {
        EXPECT_EQ(b.bmo->left, (std::array<std::int32_t, 3>{11, 12, 13}));
        EXPECT_EQ(b.bmo->right, (std::array<std::int32_t, 3>{14, 15, 16}));
    }
    EXPECT_EQ(has_note_containing(s, "unverified"), v >= 104);
    EXPECT_EQ(s.meta.grid_type, v >= 102 ? 3 : 0);
    EXPECT_EQ(s.meta.grid_type1, v >= 103 ? 8 : 0);
    // v100/101 have no GridType: the grid after the B-scan is found as a trailing grid.
    // v102 has GridType only; v103+ both.
    const std::size_t n_grids = v >= 103 ? 2U : 1U;
    ASSERT_EQ(s.grids.size(), n_grids);
    EXPECT_EQ(s.grids[0].type, 3);
    EXPECT_EQ(s.grids[0].from_header, v >= 102);
    EXPECT_EQ(s.grids[0].file_offset, 2048U + 4 + 512 + 48);
    EXPECT_EQ(s.grids[0].diameters_mm[2], 6.0);
    EXPECT_EQ(s.grids[0].central_thickness_mm, 0.25F);
    if (n_grids == 2) {
        EXPECT_EQ(s.grids[1].rows, 1);
        EXPECT_EQ(s.grids[1].cols, 2);
        ASSERT_EQ(s.grids[1].cells.size(), 2U);
        EXPECT_EQ(s.grids[1].cells[0].thickness_mm, 0.3F);
        EXPECT_EQ(s.grids[1].cells[1].thickness_mm, 0.4F);
        EXPECT_EQ(s.grids[1].centre_y_slo_mm, 2.5);
    }
    // Segmentation: exactly the two lines; FLT_MAX, inf, NaN, -FLT_MAX and 1e30 are missing.
    ASSERT_EQ(b.num_seg(), 2);
    EXPECT_EQ(b.seg[0][0], 1.5F);
    EXPECT_TRUE(std::isnan(b.seg[0][1]));
    EXPECT_EQ(b.seg[0][2], 2.5F);
    EXPECT_TRUE(std::isnan(b.seg[0][3]));
    EXPECT_TRUE(std::isnan(b.seg[1][0]));
    EXPECT_EQ(b.seg[1][1], 3.25F);
    EXPECT_TRUE(std::isnan(b.seg[1][2]));
    EXPECT_TRUE(std::isnan(b.seg[1][3]));
    ASSERT_EQ(b.pixels.size(), 12U);
    EXPECT_EQ(b.pixels[11], 1.0F);
    EXPECT_EQ(s.slo, (std::vector<std::uint8_t>{1, 2, 3, 4}));
}

INSTANTIATE_TEST_SUITE_P(All, VolVersion, ::testing::Values(100, 101, 102, 103, 104));

TEST(VolVersion, UnknownVersionsAreUnsupported) {
    for (const char* magic : {"HSF-OCT-105", "HSF-OCT-099", "HSF-OCT-1A3", "HSF-OCT-200"}) {
        std::string f = craft_vol(103);
        f.replace(0, 11, magic);
        try {
            (void)read_from_string(f, false);
            ADD_FAILURE() << magic << " was accepted";
        } catch (const InputError& e) {
            EXPECT_EQ(e.kind(), InputError::Kind::kUnsupported) << e.what();
            EXPECT_NE(e.reason().find(magic), std::string::npos) << e.what();
        }
    }
}

// ---- real files ---------------------------------------------------------------------------

// Fraction of valid values of line k in the first B-scan, and whether A-scans 0 and last are
// missing.
struct LineStats {
    double valid = 0.0;
    bool first_missing = false;
    bool last_missing = false;
};
LineStats line_stats(const io::Scan& s, int k) {
    const auto& line = s.bscans.at(0).seg.at(static_cast<std::size_t>(k));
    LineStats st;
    st.valid = s.valid_fraction(k);
    st.first_missing = !io::is_valid(line.front());
    st.last_missing = !io::is_valid(line.back());
    return st;
}

void expect_valid_depths_inside_bscan(const io::Scan& s) {
    for (const io::BScan& b : s.bscans) {
        for (const auto& line : b.seg) {
            for (float v : line) {
                if (io::is_valid(v)) {
                    EXPECT_GE(v, 0.0F);
                    EXPECT_LT(v, static_cast<float>(s.meta.size_z));
                }
            }
        }
    }
}

void expect_pixels_are_reflectance(const io::Scan& s) {
    // Format doc: linear reflectance in [0, 1], FLT_MAX = no data.
    std::size_t bad = 0;
    for (const io::BScan& b : s.bscans) {
        ASSERT_EQ(b.pixels.size(), static_cast<std::size_t>(s.meta.size_x) *
                                       static_cast<std::size_t>(s.meta.size_z));
        for (float v : b.pixels) bad += (v == io::kNoPixelData || (v >= 0.0F && v <= 1.0F)) ? 0 : 1;
    }
    EXPECT_EQ(bad, 0U);
    EXPECT_EQ(s.slo.size(), static_cast<std::size_t>(s.meta.size_x_slo) *
                                static_cast<std::size_t>(s.meta.size_y_slo));
}

void expect_fast_equals_full(const std::filesystem::path& p) {
    const io::Scan full = read_file(p, true);
    const io::Scan fast = read_file(p, false);
    expect_same_scan(full, fast, false);
    EXPECT_EQ(full.notes, fast.notes);
    EXPECT_EQ(full.meta.bscan_hdr_size, fast.meta.bscan_hdr_size);
    expect_pixels_are_reflectance(full);
}

TEST(VolRealData, FoveaLineScan) {
    SKIP_UNLESS_SHARED("realdata/fovea_line_716_0.vol");
    const auto p = realdata("fovea_line_716_0.vol");
    const io::Scan s = read_file(p, false);
    EXPECT_EQ(s.meta.version, "HSF-OCT-103");
    EXPECT_EQ(s.meta.laterality, io::Laterality::kOD);
    EXPECT_EQ(s.meta.pattern, io::ScanPattern::kLine);
    EXPECT_EQ(s.meta.size_x, 768);
    EXPECT_EQ(s.meta.size_z, 496);
    EXPECT_EQ(s.num_bscans(), 1);
    EXPECT_NEAR(s.meta.scale_x_mm, 0.011821, 1e-6);
    EXPECT_NEAR(s.meta.scale_z_mm, 0.0038717, 1e-7);
    EXPECT_EQ(s.meta.distance_mm, 0.0);  // a single line
    // The line runs from Start to End over SizeX A-scans of ScaleX: |End - Start| = the
    // field the header states, to the rounding of the stored values (< 1e-5 mm).
    const io::BScan& b = s.bscans[0];
    EXPECT_NEAR(std::hypot(b.end_x_mm - b.start_x_mm, b.end_y_mm - b.start_y_mm),
                s.meta.scale_x_mm * s.meta.size_x, 1e-5);
    EXPECT_EQ(b.start_y_mm, b.end_y_mm);  // horizontal line
    // ILM and BM valid except at the edges; BM also ends at the disc near the right end, so
    // it is held to a lower (still high) fraction than the ILM.
    ASSERT_GE(s.num_lines(), 2);
    const LineStats ilm = line_stats(s, 0);
    const LineStats bm = line_stats(s, 1);
    EXPECT_GT(ilm.valid, 0.95);
    EXPECT_LT(ilm.valid, 1.0);
    EXPECT_GT(bm.valid, 0.75);
    EXPECT_TRUE(ilm.first_missing && ilm.last_missing);
    EXPECT_TRUE(bm.first_missing && bm.last_missing);
    // BM lies below the ILM wherever both are valid.
    for (int a = 0; a < 768; ++a) {
        if (io::is_valid(b.seg[0][a]) && io::is_valid(b.seg[1][a])) {
            EXPECT_GT(b.seg[1][a], b.seg[0][a]) << "A-scan " << a;
        }
    }
    expect_valid_depths_inside_bscan(s);
    // The ETDRS grid after the last B-scan although GridType is 0.
    EXPECT_EQ(s.meta.grid_type, 0);
    ASSERT_EQ(s.grids.size(), 1U);
    const io::ThicknessGrid& g = s.grids[0];
    EXPECT_FALSE(g.from_header);
    EXPECT_EQ(g.type, 3);
    EXPECT_EQ(g.file_offset, 2048U + 768 * 768 + 55296 + 768 * 496 * 4);
    EXPECT_EQ(g.diameters_mm, (std::array<double, 3>{1.0, 3.0, 6.0}));  // ETDRS 1/3/6 mm
    // Default grid position: the scan centre, i.e. the middle of the line.
    EXPECT_NEAR(g.centre_x_slo_mm, 0.5 * (b.start_x_mm + b.end_x_mm), 1e-9);
    EXPECT_NEAR(g.centre_y_slo_mm, b.start_y_mm, 1e-9);
    EXPECT_TRUE(has_note_containing(s, "after the last B-scan"));
    expect_fast_equals_full(p);
}

void expect_circle_scan(const io::Scan& s) {
    EXPECT_EQ(s.meta.version, "HSF-OCT-103");
    EXPECT_EQ(s.meta.pattern, io::ScanPattern::kCircle);
    EXPECT_EQ(s.meta.laterality, io::Laterality::kOD);
    EXPECT_EQ(s.num_bscans(), 1);
    EXPECT_EQ(s.meta.distance_mm, 0.0);
    const io::BScan& b = s.bscans[0];
    // Circle: Start is on the circle, End is the centre; ScaleX x SizeX is the circumference.
    // Start and centre are SLO positions, so the radius is known to about one SLO pixel.
    const double r = std::hypot(b.start_x_mm - b.end_x_mm, b.start_y_mm - b.end_y_mm);
    const double tol = 2.0 * std::numbers::pi * s.meta.scale_x_slo_mm;
    EXPECT_NEAR(s.meta.scale_x_mm * s.meta.size_x, 2.0 * std::numbers::pi * r, tol);
    expect_valid_depths_inside_bscan(s);
}

TEST(VolRealData, PeripapillaryCircleScansOfRadius1p8) {
    SKIP_UNLESS_SHARED("realdata/onh_circle_716_2.vol", "realdata/onh_circle_716_4.vol");
    for (const char* name : {"onh_circle_716_2.vol", "onh_circle_716_4.vol"}) {
        SCOPED_TRACE(name);
        const auto p = realdata(name);
        const io::Scan s = read_file(p, false);
        expect_circle_scan(s);
        const io::BScan& b = s.bscans[0];
        // README: radius 1.80 mm (two decimals: +-0.005 mm).
        EXPECT_NEAR(std::hypot(b.start_x_mm - b.end_x_mm, b.start_y_mm - b.end_y_mm), 1.80, 0.005);
        EXPECT_NEAR(s.meta.scale_x_mm * s.meta.size_x, 2.0 * std::numbers::pi * 1.80,
                    2.0 * std::numbers::pi * 0.005);
        EXPECT_EQ(s.meta.bscan_hdr_size, 55296U);
        expect_fast_equals_full(p);
    }
}

TEST(VolRealData, CircleScanWithShiftAndInvalidIlm) {
    SKIP_UNLESS_SHARED("realdata/onh_circle_valid.vol");
    const auto p = realdata("onh_circle_valid.vol");
    const io::Scan s = read_file(p, false);
    expect_circle_scan(s);
    EXPECT_EQ(s.meta.bscan_hdr_size, 46080U);
    EXPECT_EQ(s.bscans[0].shift, -9);
    // ILM invalid in places, but not everywhere.
    const double ilm = s.valid_fraction(0);
    EXPECT_GT(ilm, 0.0);
    EXPECT_LT(ilm, 1.0);
    // The file ends with the last B-scan: no grid, nothing ignored.
    EXPECT_TRUE(s.grids.empty());
    EXPECT_EQ(std::filesystem::file_size(p), 2048U + 768 * 768 + 46080 + 768 * 496 * 4);
    expect_fast_equals_full(p);
}

TEST(VolRealData, RealFileRoundTripsThroughTheWriter) {
    SKIP_UNLESS_SHARED("realdata/onh_circle_valid.vol");
    // Read with pixels, write, read again: identical, and byte-identical to the original file
    // for everything the writer does not derive (the file has no ProgID and no BMO fields).
    const auto p = realdata("onh_circle_valid.vol");
    const io::Scan s = read_file(p, true);
    const std::string bytes = write_to_string(s);
    expect_same_scan(s, read_from_string(bytes, true), true);
    const std::string original = slurp(p);
    ASSERT_EQ(bytes.size(), original.size());
    // The file header and the B-scan's fixed fields and segmentation are identical.
    EXPECT_EQ(bytes.substr(0, 2048), original.substr(0, 2048));
    const std::size_t bscan = 2048 + 768 * 768;
    EXPECT_EQ(bytes.substr(bscan, 256 + 3 * 768 * 4), original.substr(bscan, 256 + 3 * 768 * 4));
    EXPECT_EQ(bytes.substr(bscan + 46080), original.substr(bscan + 46080));
}

TEST(VolRealData, EyepyWrittenFileIsRefusedClearly) {
    SKIP_UNLESS_SHARED("realdata/not_spectralis_eyepy_written.vol");
    const auto p = realdata("not_spectralis_eyepy_written.vol");
    try {
        (void)read_file(p, false);
        FAIL() << "accepted";
    } catch (const InputError& e) {
        EXPECT_EQ(e.kind(), InputError::Kind::kUnsupported);
        EXPECT_NE(e.reason().find("ep-v0.6.8"), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find(p.string()), std::string::npos);
        EXPECT_EQ(e.offset(), std::optional<std::uint64_t>(0));
    }
    // Even with a Spectralis magic, its header sizes contradict each other.
    std::string f = slurp(p);
    f.replace(0, 12, std::string("HSF-OCT-103\0", 12));
    try {
        (void)read_from_string(f, false);
        FAIL() << "accepted";
    } catch (const InputError& e) {
        EXPECT_EQ(e.kind(), InputError::Kind::kCorrupt);
        EXPECT_NE(e.reason().find("B-scan 0 header magic is \"ep-v0.6.8\""), std::string::npos)
            << e.what();
        EXPECT_EQ(e.offset(), std::optional<std::uint64_t>(2048 + 50 * 50));
    }
    // And with Spectralis B-scan magics too (eyepy writes its own at each B-scan start).
    for (std::size_t at = 2048 + 50 * 50; at + 12 <= f.size(); ++at) {
        if (f.compare(at, 9, "ep-v0.6.8") == 0)
            f.replace(at, 12, std::string("HSF-BS-103\0\0", 12));
    }
    try {
        (void)read_from_string(f, false);
        FAIL() << "accepted";
    } catch (const InputError& e) {
        EXPECT_EQ(e.kind(), InputError::Kind::kCorrupt);
        EXPECT_NE(e.reason().find("contradictory header sizes"), std::string::npos) << e.what();
        EXPECT_NE(e.reason().find("61440"), std::string::npos) << e.what();
    }
}

}  // namespace
}  // namespace octshape::test
