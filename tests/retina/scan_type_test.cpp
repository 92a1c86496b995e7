// The scan-type classifier (libretina scan_type.h): macula phantoms of both families, with
// dropouts, noise and vessels, are macula; the ONH phantom is ONH with the longest BM gap its
// BMO ellipse implies; radial scans are classified by the same rule; circle scans are refused;
// and the rule's two thresholds bite exactly.

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "octshape/io/scan_reader.h"
#include "octshape/retina/phantom_macula.h"
#include "octshape/error.h"
#include "octshape/retina/scan_type.h"
#include "test_paths.h"

namespace octshape::retina {
namespace {

constexpr int kBm = static_cast<int>(io::Layer::kBM);

io::Scan small_macula(MaculaFamily family, std::uint64_t seed) {
    MaculaPhantomParams p;
    p.family = family;
    p.num_bscans = 25;
    p.size_x = 192;
    p.size_z = 128;
    p.scale_z_mm = 0.0154868;
    p.pixels = false;
    p.noise_um = 3.9;
    p.missing_fraction = 0.02;
    p.vessels = 3;
    p.seed = seed;
    return make_macula_phantom(p).scan;
}

TEST(ScanType, MaculaPhantomsAreMacula) {
    for (const auto family : {MaculaFamily::kBezier, MaculaFamily::kScheibe}) {
        for (std::uint64_t seed = 1; seed <= 3; ++seed) {
            const io::Scan scan = small_macula(family, seed);
            const auto r = classify_scan(scan);
            EXPECT_EQ(r.type, ScanType::kMacula) << r.reason;
            EXPECT_EQ(r.bscans_with_gap, 0);
            // 2 % random dropouts: runs of a few A-scans (ScaleX 47 um), far below 0.5 mm.
            EXPECT_LT(r.longest_gap_mm, 0.25);
        }
    }
}

TEST(ScanType, OnhPhantomIsOnhWithTheGapOfItsBmoEllipse) {
    // (phantom_onh.h and phantom_macula.h cannot share a translation unit: the ONH phantom is
    // made by the command, with the generator's defaults for the BMO ellipse.)
    test::TempDir dir;
    const auto made = test::run_octshape("phantom onh --bscans 25 --ascans 96 -o '" +
                                         (dir / "onh.vol").string() + "'");
    ASSERT_EQ(made.exit_code, 0) << made.err;
    const io::Scan scan = io::read_scan((dir / "onh.vol").string());
    const auto r = classify_scan(scan);
    struct {
        double bmo_rotation_deg = 80.0;  // OnhPhantomParams defaults (phantom_onh.h)
        double bmo_semi_major_mm = 0.92;
        double bmo_semi_minor_mm = 0.76;
    } p;
    EXPECT_EQ(r.type, ScanType::kOnh) << r.reason;
    // Widest chord of the ellipse along grid x: W = 2 sqrt(a^2 cos^2 t + b^2 sin^2 t). The
    // nearest B-scan is at most Distance/2 = 0.09 mm from that chord's y, which shortens it by
    // < 1 % (the ellipse's y half-extent is ~0.9 mm); A-scan sampling adds +-1 ScaleX.
    const double t = p.bmo_rotation_deg * std::acos(-1.0) / 180.0;
    const double a = p.bmo_semi_major_mm;
    const double b = p.bmo_semi_minor_mm;
    const double w = 2.0 * std::sqrt(a * a * std::cos(t) * std::cos(t) +
                                     b * b * std::sin(t) * std::sin(t));
    const double sx = scan.meta.scale_x_mm;
    EXPECT_GE(r.longest_gap_mm, 0.99 * w - 2.0 * sx);
    EXPECT_LE(r.longest_gap_mm, w + sx);
    // B-scans whose chord is >= 0.5 mm: those within |dy| <= Y sqrt(1 - (0.5/W)^2) of the
    // widest chord, Y >= b: at least 2 * 0.76 * 0.94 / Distance(0.18 mm) - 1 ~ 7.
    EXPECT_GE(r.bscans_with_gap, 7);
}

// Radial scans are classified by the same rule as volumes: every line of a radial ONH scan
// crosses the BMO through its centre, so each has an interior gap as long as the ellipse's
// chord along it (between the minor and the major diameter); a radial macula scan has none.
TEST(ScanType, RadialScansAreClassifiedByTheirBmGaps) {
    test::TempDir dir;
    const auto onh = test::run_octshape("phantom onh --pattern radial --lines 12 --ascans 192 -o '" +
                                        (dir / "onh_radial.vol").string() + "'");
    ASSERT_EQ(onh.exit_code, 0) << onh.err;
    const io::Scan scan = io::read_scan((dir / "onh_radial.vol").string());
    ASSERT_EQ(scan.meta.pattern, io::ScanPattern::kRadial);
    const auto r = classify_scan(scan);
    EXPECT_EQ(r.type, ScanType::kOnh) << r.reason;
    EXPECT_EQ(r.bscans_with_gap, 12);  // every line holds the BMO centre
    // The generator's default ellipse (a = 0.92, b = 0.76 mm): the longest chord through the
    // centre is at most the major diameter; A-scan sampling adds +-1 ScaleX.
    const double sx = scan.meta.scale_x_mm;
    EXPECT_LE(r.longest_gap_mm, 2.0 * 0.92 + sx);
    EXPECT_GE(r.longest_gap_mm, 2.0 * 0.76 - 2.0 * sx);

    MaculaPhantomParams p;
    p.radial = true;
    p.radial_lines = 12;
    p.size_x = 256;
    p.size_z = 128;
    p.scale_z_mm = 0.0154868;
    p.pixels = false;
    p.noise_um = 3.9;
    p.missing_fraction = 0.02;
    p.seed = 5;
    const io::Scan mac = make_macula_phantom(p).scan;
    ASSERT_EQ(mac.meta.pattern, io::ScanPattern::kRadial);
    const auto m = classify_scan(mac);
    EXPECT_EQ(m.type, ScanType::kMacula) << m.reason;
    EXPECT_EQ(m.bscans_with_gap, 0);
}

TEST(ScanType, RealScans) {
    SKIP_UNLESS_SHARED("realdata/fovea_line_716_0.vol", "realdata/onh_circle_716_2.vol", "realdata/onh_circle_716_4.vol", "realdata/onh_circle_valid.vol");
    for (const char* name :
         {"onh_circle_716_2.vol", "onh_circle_716_4.vol", "onh_circle_valid.vol"}) {
        const auto r = classify_scan(io::read_scan(test::realdata(name).string()));
        EXPECT_EQ(r.type, ScanType::kUnsupported) << name;
        EXPECT_NE(r.reason.find("circle"), std::string::npos) << r.reason;
    }
    // A horizontal line through the fovea whose BM ends at the disc near the right end: the
    // gap touches the end of the B-scan, so it is not a BMO crossing.
    const auto line = classify_scan(io::read_scan(test::realdata("fovea_line_716_0.vol").string()));
    EXPECT_EQ(line.type, ScanType::kMacula) << line.reason;
}

// Removes BM over [a0, a0 + n) in B-scan b.
void cut_bm(io::Scan& s, int b, int a0, int n) {
    auto& line = s.bscans[static_cast<std::size_t>(b)].seg[static_cast<std::size_t>(kBm)];
    for (int a = a0; a < a0 + n; ++a) {
        line[static_cast<std::size_t>(a)] = std::numeric_limits<float>::quiet_NaN();
    }
}

TEST(ScanType, ThresholdsAreExact) {
    io::Scan base = small_macula(MaculaFamily::kBezier, 7);
    // No dropouts in this copy, so the cuts alone decide.
    for (auto& b : base.bscans) {
        for (auto& v : b.seg[static_cast<std::size_t>(kBm)]) {
            if (!io::is_valid(v)) v = 100.0F;
        }
    }
    const double sx = base.meta.scale_x_mm;
    ScanTypeParams params;
    const int n_gap = static_cast<int>(std::ceil(params.min_gap_mm / sx));  // just >= 0.5 mm

    io::Scan one = base;
    cut_bm(one, 12, 50, n_gap);
    EXPECT_EQ(classify_scan(one).type, ScanType::kMacula);  // one B-scan is not enough
    EXPECT_EQ(classify_scan(one).bscans_with_gap, 1);

    io::Scan two = one;
    cut_bm(two, 13, 50, n_gap);
    EXPECT_EQ(classify_scan(two).type, ScanType::kOnh);

    io::Scan short_gaps = base;
    cut_bm(short_gaps, 12, 50, n_gap - 1);  // (n-1) ScaleX < 0.5 mm
    cut_bm(short_gaps, 13, 50, n_gap - 1);
    EXPECT_EQ(classify_scan(short_gaps).type, ScanType::kMacula);

    io::Scan edge = base;  // long runs that reach the end of the B-scan are not interior
    const int nx = base.meta.size_x;
    for (int b = 0; b < base.num_bscans(); ++b) cut_bm(edge, b, nx - 2 * n_gap, 2 * n_gap);
    EXPECT_EQ(classify_scan(edge).type, ScanType::kMacula);

    io::Scan line = base;  // a single B-scan needs one gap
    line.bscans.resize(1);
    cut_bm(line, 0, 50, n_gap);
    EXPECT_EQ(classify_scan(line).type, ScanType::kOnh);

    io::Scan circle = base;
    circle.meta.pattern = io::ScanPattern::kCircle;
    EXPECT_EQ(classify_scan(circle).type, ScanType::kUnsupported);

    params.min_gap_mm = 0.0;
    EXPECT_THROW((void)classify_scan(base, params), UsageError);
}

}  // namespace
}  // namespace octshape::retina
