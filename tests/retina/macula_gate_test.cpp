// The macula analysis refuses what no eye can be, and keeps impossible segmentations out of the
// numbers: hostile scales, segmentation outside the image, ILM below BM, fields smaller than
// the model. Each case starts from a phantom the analysis handles (truth in phantom_macula.h)
// and changes the one thing under test.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "octshape/error.h"
#include "octshape/retina/cube.h"
#include "octshape/retina/phantom_macula.h"

namespace octshape::test {
namespace {

using retina::CubeResult;

// A small, fast volume: 31 B-scans x 384 A-scans over the usual 8.97 x 7.5 mm field.
io::Scan small_volume() {
    retina::MaculaPhantomParams p;
    p.num_bscans = 31;
    p.size_x = 384;
    p.pixels = false;
    return retina::make_macula_phantom(p).scan;
}

std::string analysis_error(const io::Scan& s, const retina::CubeParams& params = {}) {
    try {
        (void)retina::analyse_macula(s, params);
    } catch (const AnalysisError& e) {
        return e.what();
    }
    return "";
}

bool has_flag(const CubeResult& r, const std::string& f) {
    return std::find(r.qc_flags.begin(), r.qc_flags.end(), f) != r.qc_flags.end();
}

// Every number the result reports is finite and physically possible.
void expect_possible(const CubeResult& r, const io::Scan& s) {
    const double depth = s.meta.size_z * s.meta.scale_z_mm;
    EXPECT_GT(r.cft_mm, 0.0);
    EXPECT_LE(r.cft_mm, depth);
    EXPECT_GE(r.rim_height_mm, r.cft_mm);
    EXPECT_LE(r.rim_height_mm, depth);
    EXPECT_GE(r.pit_depth_mm, 0.0);
    EXPECT_TRUE(std::isfinite(r.rmse_um));
    for (const double v : {r.rim_volume_mm3, r.inner_rim_volume_mm3, r.pit_volume_mm3}) {
        EXPECT_TRUE(std::isnan(v) || v >= 0.0) << v;
    }
}

TEST(MaculaGate, ScalesNoSpectralisHasAreRefusedBeforeAllocating) {
    // ScaleX 1e-8 mm asked for 2e8 samples per half-line (17 GB); 1e-21 overflowed an int.
    for (const double sx : {1e-21, 1e-8, 0.5}) {
        io::Scan s = small_volume();
        s.meta.scale_x_mm = sx;
        const std::string e = analysis_error(s);
        EXPECT_NE(e.find("ScaleX"), std::string::npos) << sx << ": " << e;
        EXPECT_NE(e.find("expected"), std::string::npos) << e;
    }
    io::Scan s = small_volume();
    s.meta.distance_mm = 1e-9;
    EXPECT_NE(analysis_error(s).find("Distance"), std::string::npos);
    s = small_volume();
    s.meta.scale_z_mm = 2.0;
    EXPECT_NE(analysis_error(s).find("ScaleZ"), std::string::npos);
}

TEST(MaculaGate, SampleSpacingBelowATenthOfAMicronIsAUsageError) {
    retina::CubeParams p;
    p.sample_spacing_mm = 1e-9;  // 2e9 samples per half-line
    EXPECT_THROW(p.validate(), UsageError);
    p.sample_spacing_mm = 1e-4;
    EXPECT_NO_THROW(p.validate());
}

TEST(MaculaGate, SegmentationOutsideTheImageIsMissingAndFlagged) {
    io::Scan s = small_volume();
    // BM at 1e6 px on one B-scan far from the fovea (it gave CFT 11,999.6 mm when everywhere).
    auto& bm = s.bscans[2].seg[static_cast<int>(io::Layer::kBM)];
    std::fill(bm.begin(), bm.end(), 1e6F);
    const CubeResult r = retina::analyse_macula(s);
    EXPECT_EQ(r.map.num_outside_image, s.meta.size_x);
    EXPECT_TRUE(has_flag(r, "segmentation outside the image"));
    expect_possible(r, s);
    // Everywhere: nothing is left to analyse, and the message says why.
    for (auto& b : s.bscans) {
        auto& line = b.seg[static_cast<int>(io::Layer::kBM)];
        std::fill(line.begin(), line.end(), 1e6F);
    }
    const std::string e = analysis_error(s);
    EXPECT_NE(e.find("outside the image"), std::string::npos) << e;
}

TEST(MaculaGate, IlmBelowBmIsMissingAndFlagged) {
    io::Scan s = small_volume();
    const int ilm = static_cast<int>(io::Layer::kILM);
    const int bm = static_cast<int>(io::Layer::kBM);
    for (int a = 0; a < 40; ++a) std::swap(s.bscans[3].seg[ilm][a], s.bscans[3].seg[bm][a]);
    const CubeResult r = retina::analyse_macula(s);
    EXPECT_EQ(r.map.num_inverted, 40);
    EXPECT_TRUE(has_flag(r, "ILM below BM"));
    expect_possible(r, s);
    // Everywhere (it gave CFT -0.36 mm): refused.
    s = small_volume();
    for (auto& b : s.bscans) std::swap(b.seg[ilm], b.seg[bm]);
    const std::string e = analysis_error(s);
    EXPECT_NE(e.find("ILM below the BM"), std::string::npos) << e;
}

TEST(MaculaGate, AFieldSmallerThanTheModelIsRefused) {
    // The shared XML export is 0.58 x 0.28 mm against half-lines of 2 mm: it "succeeded" with
    // CFT = rim height. Here: the phantom's ScaleX shrunk so that the field is 1.9 mm wide.
    io::Scan s = small_volume();
    s.meta.scale_x_mm = 1.9 / (s.meta.size_x - 1);
    const std::string e = analysis_error(s);
    EXPECT_NE(e.find("smaller than the model"), std::string::npos) << e;
    retina::CubeParams p;
    p.radius_mm = 0.9;  // what the message suggests: a smaller --radius-mm is accepted
    EXPECT_EQ(analysis_error(s, p).find("smaller than the model"), std::string::npos);
}

TEST(MaculaGate, ThePhantomsPassTheGateUnchanged) {
    // The gate refuses no real eye: both families, both eyes, a line scan.
    for (const auto family : {retina::MaculaFamily::kBezier, retina::MaculaFamily::kScheibe}) {
        for (const auto eye : {io::Laterality::kOD, io::Laterality::kOS}) {
            for (const bool line : {false, true}) {
                retina::MaculaPhantomParams p;
                p.family = family;
                p.eye = eye;
                p.line = line;
                p.num_bscans = 31;
                p.size_x = 384;
                p.pixels = false;
                const io::Scan s = retina::make_macula_phantom(p).scan;
                const CubeResult r = retina::analyse_macula(s);
                EXPECT_FALSE(has_flag(r, "segmentation outside the image"));
                EXPECT_FALSE(has_flag(r, "ILM below BM"));
                expect_possible(r, s);
            }
        }
    }
}

}  // namespace
}  // namespace octshape::test
