// Speckle statistics (docs/phantoms.md, "Speckle"): measured on real Spectralis B-scans, and
// the phantom's speckle against its own definition.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include "octshape/error.h"
#include "octshape/io/scan_reader.h"
#include "octshape/retina/phantom_common.h"
#include "octshape/retina/phantom_speckle.h"
#include "test_paths.h"

namespace octshape::retina::phantom {
namespace {

// top_row[a] = round(line k at A-scan a) + offset, -1 where the line is missing or where `keep`
// says no.
template <class Keep>
std::vector<int> band_top(const io::Scan& scan, int k, int offset, Keep keep) {
    std::vector<int> top(static_cast<std::size_t>(scan.meta.size_x), -1);
    for (int a = 0; a < scan.meta.size_x; ++a) {
        const double d = scan.depth_px(k, 0, a);
        if (std::isfinite(d) && keep(a)) top[a] = static_cast<int>(std::lround(d)) + offset;
    }
    return top;
}

io::ReadOptions with_pixels() {
    io::ReadOptions o;
    o.pixels = true;
    return o;
}

void print(const char* what, const SpeckleStats& s) {
    std::printf("%s: n %zu, mean %.4g, contrast %.3f, shape %.2f, axial ACF %.2f %.2f %.2f "
                "half-width %.2f px, lateral ACF %.2f %.2f %.2f half-width %.2f px\n",
                what, s.count, s.mean_raw, s.contrast, s.shape, s.acf_axial[1], s.acf_axial[2],
                s.acf_axial[3], s.half_width_axial_px, s.acf_lateral[1], s.acf_lateral[2],
                s.acf_lateral[3], s.half_width_lateral_px);
}

// The figures of docs/phantoms.md ("Speckle"), table "measured", reproduced from the files
// themselves: each value is asserted to the rounding it is given with there (+- half its last
// digit), so a change of the estimator or of the reader shows here before the doc is wrong.
TEST(SpeckleRealSpectralis, FoveaLineOuterNuclearLayer) {
    SKIP_UNLESS_SHARED("realdata/fovea_line_716_0.vol");
    const io::Scan scan =
        io::read_scan(test::realdata("fovea_line_716_0.vol").string(), with_pixels());
    ASSERT_EQ(scan.meta.size_x, 768);
    // ONL: 32-44 px (124-170 um) above BM, 1.3-3.2 mm from the fovea on both sides (A-scans
    // 250-329 and 440-519), where the ONL is thick and flat.
    auto parafovea = [](int a) { return (a >= 250 && a < 330) || (a >= 440 && a < 520); };
    const SpeckleStats s = speckle_statistics(scan.bscans[0], scan.meta.size_x,
                                              scan.meta.size_z,
                                              band_top(scan, 1, -44, parafovea), 12);
    print("fovea_line_716_0 ONL", s);
    EXPECT_NEAR(s.contrast, 0.34, 0.005);
    EXPECT_NEAR(s.shape, 8.7, 0.05);
    EXPECT_NEAR(s.half_width_axial_px, 1.6, 0.05);
    EXPECT_NEAR(s.half_width_lateral_px, 1.4, 0.05);
}

TEST(SpeckleRealSpectralis, CircleScanNerveFibreLayer) {
    SKIP_UNLESS_SHARED("realdata/onh_circle_716_2.vol");
    const io::Scan scan =
        io::read_scan(test::realdata("onh_circle_716_2.vol").string(), with_pixels());
    ASSERT_EQ(scan.meta.size_x, 768);
    // RNFL: 5-13 px below the ILM wherever the device's RNFL is at least 18 px thick.
    auto thick = [&](int a) {
        return scan.depth_px(2, 0, a) - scan.depth_px(0, 0, a) >= 18.0;
    };
    const SpeckleStats s = speckle_statistics(scan.bscans[0], scan.meta.size_x,
                                              scan.meta.size_z, band_top(scan, 0, 5, thick), 8);
    print("onh_circle_716_2 RNFL", s);
    EXPECT_NEAR(s.contrast, 0.35, 0.005);
    EXPECT_NEAR(s.shape, 8.4, 0.05);
    EXPECT_NEAR(s.half_width_axial_px, 2.0, 0.05);
    EXPECT_NEAR(s.half_width_lateral_px, 0.9, 0.05);
}

// The phantom's speckle today: independent Gamma(looks, 1/looks) per pixel. On a uniform
// reflectance the box-normalised contrast is 1/sqrt(looks) times sqrt(1 - 1/81) (dividing by
// the mean of a 9 x 9 box of independent pixels removes 1/81 of the variance), and the
// autocorrelation at lag 1 is -1/80 (the shared box), i.e. white. Sampling: ~22 000 independent
// pixels; the relative SE of a variance is sqrt((2 + 6/looks)/n) = 1.3 % for looks 3, so the
// contrast's is 0.7 %: 0.02 (4 %) is > 5 SE; the SE of an autocorrelation is 1/sqrt(n) = 0.007,
// so 0.04 is > 5 SE.
TEST(SpecklePhantom, IndependentGammaPixels) {
    const int nx = 192, nz = 128;
    for (const double looks : {3.0, 9.0}) {
        SCOPED_TRACE(looks);
        io::BScan b;
        SpeckleParams sp;
        sp.looks = looks;
        render_bscan(
            b, nx, nz, [](int, std::span<float> c) { std::fill(c.begin(), c.end(), 0.1F); }, sp,
            7, 0);
        const std::vector<int> top(nx, 4);
        const SpeckleStats s = speckle_statistics(b, nx, nz, top, nz - 8);
        print("phantom", s);
        const double expected = std::sqrt((1.0 - 1.0 / 81.0) / looks);
        EXPECT_NEAR(s.contrast / expected, 1.0, 0.02);
        EXPECT_NEAR(s.acf_axial[1], -1.0 / 80.0, 0.04);
        EXPECT_NEAR(s.acf_lateral[1], -1.0 / 80.0, 0.04);
    }
}

// The grain (SpeckleParams half-widths): 7 looks, 1.9 px along the A-scan and 1.6 A-scans
// across (the settings docs/phantoms.md gives for real Spectralis, chosen so that the same
// box-normalised estimator reads the real ONL's figures) give the real ONL's contrast and
// half-widths within the real estimate's sampling error: contrast 0.34 +- 0.02 and half-widths
// +- 0.2 px (1 SE: ~170 independent values; the SE of an autocorrelation, 1/sqrt(170) = 0.08,
// over its slope at the half-width, ~0.4 per px). The phantom's own sampling error is ~10 times
// smaller (45 632 pixels correlated over ~10). Without a grain the bits are unchanged (the
// expression is the same), which every pixel-reading phantom test relies on.
TEST(SpecklePhantom, GrainMatchesTheRealOuterNuclearLayer) {
    const int nx = 256, nz = 192;
    io::BScan b;
    SpeckleParams sp;
    sp.looks = 7;
    sp.axial_half_width_px = 1.9;
    sp.lateral_half_width_px = 1.6;
    render_bscan(
        b, nx, nz, [](int, std::span<float> c) { std::fill(c.begin(), c.end(), 0.1F); }, sp, 7,
        0);
    const std::vector<int> top(nx, 4);
    const SpeckleStats s = speckle_statistics(b, nx, nz, top, nz - 8);
    print("phantom grain", s);
    EXPECT_NEAR(s.contrast, 0.34, 0.02);
    EXPECT_NEAR(s.half_width_axial_px, 1.6, 0.2);
    EXPECT_NEAR(s.half_width_lateral_px, 1.4, 0.2);
    // and a grain needs whole looks
    sp.looks = 7.5;
    EXPECT_THROW(render_bscan(
                     b, nx, nz, [](int, std::span<float>) {}, sp, 7, 0),
                 UsageError);
}

}  // namespace
}  // namespace octshape::retina::phantom
