#include "octshape/retina/phantom_common.h"

#include <cmath>
#include <numeric>

#include <gtest/gtest.h>

#include "octshape/error.h"
#include "octshape/retina/scan_geometry.h"

namespace octshape::retina::phantom {
namespace {

struct Moments {
    double mean = 0.0;
    double var = 0.0;
};

template <typename F>
Moments sample(int n, F draw) {
    double s = 0.0;
    double s2 = 0.0;
    for (int i = 0; i < n; ++i) {
        const double x = draw();
        s += x;
        s2 += x * x;
    }
    const double mean = s / n;
    return {mean, s2 / n - mean * mean};
}

TEST(PhantomRng, SameSeedSameSequenceOtherStreamDiffers) {
    Rng a(42, 7);
    Rng b(42, 7);
    Rng c(42, 8);
    int same_as_c = 0;
    for (int i = 0; i < 100; ++i) {
        const std::uint64_t x = a.next();
        EXPECT_EQ(x, b.next());
        same_as_c += x == c.next() ? 1 : 0;
    }
    EXPECT_EQ(same_as_c, 0);
}

TEST(PhantomRng, NormalAndGammaMoments) {
    constexpr int kN = 200000;
    Rng rng(1);
    // Tolerances: 5 standard errors. Mean SE = sd/sqrt(n); variance SE ~ var*sqrt((kurt-1)/n)
    // (kurtosis 3 for the normal, 3 + 6/k for Gamma(k)).
    const Moments nrm = sample(kN, [&] { return rng.normal(); });
    EXPECT_NEAR(nrm.mean, 0.0, 5.0 / std::sqrt(kN));
    EXPECT_NEAR(nrm.var, 1.0, 5.0 * std::sqrt(2.0 / kN));
    for (const double k : {0.5, 1.0, 3.0}) {
        const Moments g = sample(kN, [&] { return rng.gamma(k); });
        EXPECT_NEAR(g.mean, k, 5.0 * std::sqrt(k / kN)) << "shape " << k;
        EXPECT_NEAR(g.var, k, 5.0 * k * std::sqrt((2.0 + 6.0 / k) / kN)) << "shape " << k;
    }
    const Moments u = sample(kN, [&] { return rng.uniform(); });
    EXPECT_NEAR(u.mean, 0.5, 5.0 * std::sqrt(1.0 / 12.0 / kN));
}

TEST(PhantomFrame, RightEyeXNasalLeftEyeXTemporalYSuperior) {
    VolumeLayout od;
    const GridFrame f = grid_frame(od);
    EXPECT_NEAR(f.anatomical_angle_deg(1, 0), 0.0, 1e-12);
    EXPECT_NEAR(f.anatomical_angle_deg(0, 1), 90.0, 1e-12);
    VolumeLayout os = od;
    os.laterality = io::Laterality::kOS;
    const GridFrame g = grid_frame(os);
    EXPECT_NEAR(g.anatomical_angle_deg(-1, 0), 0.0, 1e-12);
    EXPECT_NEAR(g.anatomical_angle_deg(0, 1), 90.0, 1e-12);
    for (const double deg : {0.0, 37.0, 90.0, 200.0, 359.0}) {
        const Eigen::Vector2d d = g.grid_direction(deg);
        EXPECT_NEAR(g.anatomical_angle_deg(d.x(), d.y()), deg, 1e-9);
    }
}

TEST(PhantomFrame, ScanFramePlacesFirstBscanInferiorAscansLeftToRight) {
    VolumeLayout l;
    l.size_x = 64;
    l.num_bscans = 5;
    l.distance_mm = 0.5;
    l.scale_x_mm = 0.1;
    const io::Scan s = make_scan_frame(l);
    ASSERT_EQ(s.num_bscans(), 5);
    EXPECT_EQ(s.num_lines(), l.num_seg);
    EXPECT_EQ(s.valid_fraction(0), 0.0);
    for (int b = 0; b < 5; ++b) {
        const io::BScan& bs = s.bscans[static_cast<std::size_t>(b)];
        EXPECT_NEAR(bs.end_x_mm - bs.start_x_mm, 63 * 0.1, 1e-12);
        EXPECT_EQ(bs.start_y_mm, bs.end_y_mm);
        if (b > 0) {
            // Each later B-scan lies `distance` higher on the SLO (smaller y).
            EXPECT_NEAR(s.bscans[static_cast<std::size_t>(b - 1)].start_y_mm - bs.start_y_mm,
                        0.5, 1e-12);
        }
    }
    // The grid centre is the SLO centre.
    const double slo_mid = s.meta.size_x_slo * s.meta.scale_x_slo_mm / 2;
    EXPECT_NEAR((s.bscans[0].start_x_mm + s.bscans[0].end_x_mm) / 2, slo_mid, 1e-12);
    EXPECT_NEAR((s.bscans[0].start_y_mm + s.bscans[4].start_y_mm) / 2, slo_mid, 1e-12);
    EXPECT_EQ(s.meta.scan_position_raw, "OD");
    EXPECT_GE(s.meta.bscan_hdr_size, 256U + 17U * 64U * 4U);
}

// The analysis reads the orientation back from the B-scan positions (ScanGeometry); it must find
// the frame the phantom was built in. (The phantom never uses ScanGeometry itself.)
TEST(PhantomFrame, ScanGeometryRecoversThePlacement) {
    for (const auto eye : {io::Laterality::kOD, io::Laterality::kOS}) {
        VolumeLayout l;
        l.laterality = eye;
        const io::Scan s = make_scan_frame(l);
        const ScanGeometry g(s);
        const GridFrame f = grid_frame(l);
        EXPECT_TRUE(g.oriented_from_positions());
        EXPECT_TRUE(g.grid_to_anatomical().isApprox(f.grid_to_anatomical, 1e-12));
        EXPECT_TRUE(g.spacing().uniform);
        EXPECT_TRUE(g.spacing().matches_header);
    }
}

TEST(PhantomFrame, ValidateNamesTheField) {
    VolumeLayout l;
    l.num_bscans = 1;
    try {
        l.validate();
        FAIL() << "a one-B-scan volume was accepted";
    } catch (const UsageError& e) {
        EXPECT_NE(std::string(e.what()).find("num_bscans"), std::string::npos);
    }
}

TEST(PhantomLayers, ColumnIsThePixelAverageOfTheProfile) {
    RetinaLayers layers;
    const double scale_z = 0.0038717;
    const ColumnBoundaries b = retina_boundaries(100.3, 190.0, scale_z, layers);
    EXPECT_DOUBLE_EQ(b.depth_px[0], 100.3);
    EXPECT_DOUBLE_EQ(b.depth_px[10], 190.0);
    for (std::size_t k = 1; k < b.depth_px.size(); ++k) EXPECT_GE(b.depth_px[k], b.depth_px[k - 1]);
    std::vector<float> col(300);
    layered_retina_column(b, scale_z, layers, col);
    // Pixel 100 covers [99.5, 100.5): 0.8 px vitreous and 0.2 px RNFL (the RNFL is > 1 px thick
    // at this thickness: inner retina 0.148 mm, RNFL 20 % = 7.6 px).
    EXPECT_NEAR(col[100], 0.8 * layers.vitreous + 0.2 * layers.rnfl, 1e-6);
    EXPECT_NEAR(col[50], layers.vitreous, 1e-7);
    // Deep in the choroid the value decays as exp(-depth / decay).
    const double k = scale_z / layers.choroid_decay_mm;
    const double expect = layers.choroid / k * (std::exp(-k * 59.5) - std::exp(-k * 60.5));
    EXPECT_NEAR(col[250], expect, 1e-6);
}

TEST(PhantomRender, SpeckleHasMeanOneAndIsDeterministic) {
    constexpr int kX = 64;
    constexpr int kZ = 64;
    auto flat = [](int, std::span<float> c) { std::fill(c.begin(), c.end(), 0.1F); };
    io::BScan a;
    io::BScan b;
    SpeckleParams sp;
    render_bscan(a, kX, kZ, flat, sp, 5, 3);
    render_bscan(b, kX, kZ, flat, sp, 5, 3);
    EXPECT_EQ(a.pixels, b.pixels);
    const double mean =
        std::accumulate(a.pixels.begin(), a.pixels.end(), 0.0) / static_cast<double>(kX * kZ);
    // Gamma(L, 1/L) speckle: SD of a pixel = 0.1/sqrt(L); 5 standard errors of the mean.
    EXPECT_NEAR(mean, 0.1, 5.0 * 0.1 / std::sqrt(sp.looks * kX * kZ));
}

}  // namespace
}  // namespace octshape::retina::phantom
