#include "octshape/io/scan.h"

#include <cfloat>
#include <cmath>
#include <limits>

#include <gtest/gtest.h>

#include "octshape/error.h"

namespace octshape::io {
namespace {

TEST(LayerNames, RoundTripEveryKnownLayer) {
    for (int k = 0; k < kNumKnownLayers; ++k) {
        const auto back = layer_from_name(layer_name(k));
        ASSERT_TRUE(back.has_value()) << layer_name(k);
        EXPECT_EQ(*back, k);
    }
    EXPECT_EQ(layer_name(0), "ILM");
    EXPECT_EQ(layer_name(1), "BM");
    EXPECT_EQ(layer_name(16), "RPE");
    EXPECT_EQ(layer_name(17), "LINE17");
}

TEST(LayerNames, CaseInsensitiveAndAliases) {
    EXPECT_EQ(layer_from_name("ilm"), 0);
    EXPECT_EQ(layer_from_name("EZ"), static_cast<int>(Layer::kPR1));
    EXPECT_EQ(layer_from_name("IZ"), static_cast<int>(Layer::kPR2));
    EXPECT_FALSE(layer_from_name("NOPE").has_value());
}

TEST(RawValidity, DeviceInvalidMarkersAreMissing) {
    EXPECT_FALSE(is_valid_raw(FLT_MAX));
    EXPECT_FALSE(is_valid_raw(1e30F));
    EXPECT_FALSE(is_valid_raw(-FLT_MAX));
    EXPECT_FALSE(is_valid_raw(std::numeric_limits<float>::quiet_NaN()));
    EXPECT_FALSE(is_valid_raw(std::numeric_limits<float>::infinity()));
    EXPECT_TRUE(is_valid_raw(0.0F));
    EXPECT_TRUE(is_valid_raw(123.25F));
    EXPECT_TRUE(is_valid_raw(9.9e29F));
}

TEST(Scan, ValidFractionCountsMissingAndAbsentLines) {
    Scan s;
    s.meta.size_x = 4;
    const float nan = std::numeric_limits<float>::quiet_NaN();
    BScan a;
    a.seg = {{1, 2, nan, 4}, {5, 6, 7, 8}};
    BScan b;
    b.seg = {{nan, nan, 3, 4}};  // this B-scan has no BM line at all
    s.bscans = {a, b};
    EXPECT_DOUBLE_EQ(s.valid_fraction(0), 5.0 / 8.0);
    EXPECT_DOUBLE_EQ(s.valid_fraction(1), 4.0 / 8.0);
    EXPECT_DOUBLE_EQ(s.valid_fraction(2), 0.0);
    EXPECT_EQ(s.num_lines(), 1);
    EXPECT_TRUE(std::isnan(s.depth_px(1, 1, 0)));
    EXPECT_TRUE(std::isnan(s.depth_px(0, 0, 2)));
    EXPECT_FLOAT_EQ(s.depth_px(0, 0, 3), 4.0F);
    EXPECT_TRUE(std::isnan(s.depth_px(0, 5, 0)));
    EXPECT_TRUE(std::isnan(s.depth_px(0, 0, 9)));
}

TEST(Dates, FiletimeAndOleKnownValues) {
    // 1970-01-01T00:00:00Z is 116444736000000000 ticks after 1601-01-01.
    EXPECT_EQ(filetime_to_iso(116444736000000000ULL), "1970-01-01T00:00:00Z");
    // 2000-02-29T12:34:56Z = 951827696 s after the Unix epoch.
    EXPECT_EQ(filetime_to_iso(116444736000000000ULL + 951827696ULL * 10000000ULL),
              "2000-02-29T12:34:56Z");
    EXPECT_EQ(ole_date_to_iso_date(25569.0), "1970-01-01");
    EXPECT_EQ(ole_date_to_iso_date(2.0), "1900-01-01");
    // 36526 is 2000-01-01 (a known anchor); +31 (January) +28 days gives 29 February.
    EXPECT_EQ(ole_date_to_iso_date(36526.0), "2000-01-01");
    EXPECT_EQ(ole_date_to_iso_date(36526.0 + 59.5), "2000-02-29");
    EXPECT_EQ(ole_date_to_iso_date(std::numeric_limits<double>::quiet_NaN()), "invalid");
}

TEST(Errors, MessageNamesFileReasonAndOffset) {
    const InputError e = InputError::truncated("a.vol", "B-scan 3 header", 4242);
    EXPECT_EQ(std::string(e.what()), "a.vol: file truncated: B-scan 3 header (at byte 4242)");
    EXPECT_EQ(e.exit_code(), ExitCode::kDataError);
    EXPECT_EQ(e.offset(), 4242U);
    EXPECT_EQ(InputError::missing("x").exit_code(), ExitCode::kNoInput);
    EXPECT_EQ(InputError::not_regular("d").exit_code(), ExitCode::kNoInput);
    EXPECT_EQ(InputError::unsupported("u", "v").exit_code(), ExitCode::kDataError);
    EXPECT_EQ(OutputError("o", "disk full").exit_code(), ExitCode::kCantCreate);
    EXPECT_EQ(AnalysisError("no BM").exit_code(), ExitCode::kAnalysisFailed);
}

}  // namespace
}  // namespace octshape::io
