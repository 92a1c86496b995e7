#include "octshape/io/heyex_xml.h"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <gtest/gtest.h>

#include "octshape/error.h"
#include "test_paths.h"

namespace octshape::io {
namespace {

namespace fs = std::filesystem;

fs::path dummy_dir() { return test::realdata("heyex_xml_dummy"); }
std::string dummy_xml() { return (dummy_dir() / "test_dummy.xml").string(); }

std::string read_all(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    std::ostringstream ss;
    ss << in.rdbuf();
    return ss.str();
}

// Values below are read by eye from test_dummy.xml (10 OCT images 50x40, Start y from 6.807 to
// 6.524 mm in 9 equal steps, laterality R, 11 segmentation lines, an ETDRS grid of 9 zones).
TEST(HeyexXml, DummyExportMetadata) {
    SKIP_UNLESS_SHARED("realdata/heyex_xml_dummy/test_dummy.xml");
    const Scan s = read_heyex_xml(dummy_xml());
    EXPECT_EQ(s.meta.format, SourceFormat::kHeyexXml);
    EXPECT_EQ(s.meta.laterality, Laterality::kOD);
    EXPECT_EQ(s.meta.pattern, ScanPattern::kVolume);
    EXPECT_EQ(s.num_bscans(), 10);
    EXPECT_EQ(s.meta.size_x, 50);
    EXPECT_EQ(s.meta.size_z, 40);
    EXPECT_DOUBLE_EQ(s.meta.scale_x_mm, 0.011819);
    EXPECT_DOUBLE_EQ(s.meta.scale_z_mm, 0.003872);
    EXPECT_NEAR(s.meta.distance_mm, (6.807 - 6.524) / 9.0, 1e-12);
    EXPECT_DOUBLE_EQ(s.bscans.front().start_y_mm, 6.807);
    EXPECT_DOUBLE_EQ(s.bscans.front().end_x_mm, 7.564);
    EXPECT_EQ(s.meta.size_x_slo, 50);
    EXPECT_EQ(s.meta.size_y_slo, 50);
    EXPECT_EQ(s.meta.field_size_slo_deg, 30U);
    EXPECT_FALSE(s.pixels_loaded);
    EXPECT_TRUE(s.slo.empty());
    EXPECT_TRUE(s.bscans.front().pixels.empty());
    ASSERT_TRUE(s.meta.visit_date_ole.has_value());
    EXPECT_EQ(ole_date_to_iso_date(*s.meta.visit_date_ole), "2000-01-01");
    // Identifiers are read (kept private), names never are.
    EXPECT_EQ(s.meta.ids.patient_id, "Study-01");
}

TEST(HeyexXml, SegmentationByNameWithMissingValues) {
    SKIP_UNLESS_SHARED("realdata/heyex_xml_dummy/test_dummy.xml");
    const Scan s = read_heyex_xml(dummy_xml());
    // ILM is "3e+038 3e+038 9.6 ..." in B1: the first two A-scans are missing.
    const BScan& b = s.bscans.front();
    ASSERT_GE(b.num_seg(), static_cast<int>(Layer::kRPE) + 1);
    EXPECT_TRUE(std::isnan(b.seg[0][0]));
    EXPECT_TRUE(std::isnan(b.seg[0][1]));
    EXPECT_FLOAT_EQ(b.seg[0][2], 9.6F);
    EXPECT_FLOAT_EQ(b.seg[static_cast<int>(Layer::kBM)][2], 30.2F);
    EXPECT_FLOAT_EQ(b.seg[static_cast<int>(Layer::kELM)][0], 22.2F);
    // ONL is not in the export: present as all-missing, and said so.
    EXPECT_DOUBLE_EQ(s.valid_fraction(static_cast<int>(Layer::kONL)), 0.0);
    bool noted = false;
    for (const auto& n : s.notes) noted |= n.find("ONL") != std::string::npos;
    EXPECT_TRUE(noted);
    // 380 of the 500 ILM values are below 1e30 (counted with a script over the XML text).
    EXPECT_DOUBLE_EQ(s.valid_fraction(0), 380.0 / 500.0);
}

TEST(HeyexXml, ThicknessGrid) {
    SKIP_UNLESS_SHARED("realdata/heyex_xml_dummy/test_dummy.xml");
    const Scan s = read_heyex_xml(dummy_xml());
    ASSERT_EQ(s.grids.size(), 1U);
    const ThicknessGrid& g = s.grids.front();
    EXPECT_EQ(g.type, 3);
    EXPECT_TRUE(g.is_circular());
    EXPECT_DOUBLE_EQ(g.diameters_mm[2], 6.0);
    EXPECT_EQ(g.cells.size(), 9U);
    EXPECT_FLOAT_EQ(g.central_thickness_mm, 0.256F);
    EXPECT_FLOAT_EQ(g.cells[0].thickness_mm, 0.319F);
    EXPECT_NEAR(g.centre_x_slo_mm, 370 * 0.0118, 1e-9);
}

TEST(HeyexXml, PixelsOnlyWhenAsked) {
    SKIP_UNLESS_SHARED("realdata/heyex_xml_dummy/test_dummy.xml");
    const Scan s = read_heyex_xml(dummy_xml(), ReadOptions{.pixels = true});
    EXPECT_TRUE(s.pixels_loaded);
    EXPECT_EQ(s.slo.size(), 50U * 50U);
    for (const BScan& b : s.bscans) {
        ASSERT_EQ(b.pixels.size(), 50U * 40U);
        for (float v : b.pixels) {
            ASSERT_GE(v, 0.0F);
            ASSERT_LE(v, 1.0F);
            // Linear values come from 8-bit display values: v^0.25*255 is an integer.
            const double display = std::pow(static_cast<double>(v), 0.25) * 255.0;
            ASSERT_NEAR(display, std::round(display), 1e-3);
        }
    }
}

TEST(HeyexXml, DetectedFromContent) {
    SKIP_UNLESS_SHARED("realdata/heyex_xml_dummy/test_dummy.xml");
    const std::string doc = read_all(dummy_xml());
    EXPECT_TRUE(looks_like_heyex_xml(doc.data(), std::min<std::size_t>(doc.size(), 512)));
    const std::string other = "<?xml version=\"1.0\"?><!-- c --><svg></svg>";
    EXPECT_FALSE(looks_like_heyex_xml(other.data(), other.size()));
    const std::string vol = "HSF-OCT-103";
    EXPECT_FALSE(looks_like_heyex_xml(vol.data(), vol.size()));
}

// Writes `doc` as an XML export in a temp dir (with copies of the images) and reads it.
class HostileXml : public ::testing::Test {
protected:
    void SetUp() override {
        SKIP_UNLESS_SHARED("realdata/heyex_xml_dummy/test_dummy.xml");
        for (const auto& e : fs::directory_iterator(dummy_dir())) {
            if (e.path().extension() == ".tif") fs::copy_file(e.path(), dir_ / e.path().filename().string());
        }
        original_ = read_all(dummy_xml());
    }
    void expect_error(const std::string& doc, const std::string& needle,
                      bool pixels = false) {
        const auto p = dir_ / "export.xml";
        std::ofstream(p, std::ios::binary | std::ios::trunc) << doc;
        try {
            (void)read_heyex_xml(p.string(), ReadOptions{.pixels = pixels});
            FAIL() << "expected InputError containing '" << needle << "'";
        } catch (const InputError& e) {
            EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
            EXPECT_NE(std::string(e.what()).find("xml"), std::string::npos) << e.what();
        }
    }
    std::string replaced(const std::string& from, const std::string& to) const {
        std::string s = original_;
        const auto at = s.find(from);
        EXPECT_NE(at, std::string::npos) << from;
        return s.replace(at, from.size(), to);
    }
    test::TempDir dir_;
    std::string original_;
};

TEST_F(HostileXml, DoctypeIsRefused) {
    expect_error("<?xml version=\"1.0\"?><!DOCTYPE x [<!ENTITY a \"aaaa\">]><HEDX/>", "DOCTYPE");
}

TEST_F(HostileXml, DeepNestingIsRefused) {
    std::string doc;
    for (int i = 0; i < 10000; ++i) doc += "<a>";
    expect_error(doc, "nested too deeply");
}

TEST_F(HostileXml, WrongRootIsUnsupported) {
    expect_error("<svg><g/></svg>", "not a Heidelberg export");
}

TEST_F(HostileXml, SegmentationLengthMustMatchWidth) {
    expect_error(replaced("<Array n=\"50\" type=\"real\">3e+038 3e+038 9.6",
                          "<Array n=\"50\" type=\"real\">3e+038 9.6"),
                 "segmentation line has 49 values");
}

TEST_F(HostileXml, AbsurdWidthIsRefusedBeforeAllocating) {
    expect_error(replaced("<Width>50</Width>", "<Width>2147483648</Width>"), "Width");
}

TEST_F(HostileXml, NanScaleIsRefused) {
    expect_error(replaced("<ScaleX>0.011819</ScaleX>", "<ScaleX>nan</ScaleX>"), "ScaleX");
}

TEST_F(HostileXml, MissingImageFileIsNamed) {
    fs::remove(dir_ / "B3.tif");
    expect_error(original_, "B3.tif", /*pixels=*/true);
}

TEST_F(HostileXml, ImageOfTheWrongSizeIsRefused) {
    fs::copy_file(dir_ / "NIR1.tif", dir_ / "B2.tif", fs::copy_options::overwrite_existing);
    expect_error(original_, "the XML says 50x40", /*pixels=*/true);
}

// Every truncation of the document (a dense sample: all of the first 512 bytes, then every
// 97th length) is an InputError, never a crash or a silent partial read.
TEST_F(HostileXml, TruncationsAreErrors) {
    const auto p = dir_ / "export.xml";
    int tried = 0;
    for (std::size_t len = 0; len < original_.size(); len += (len < 512 ? 1 : 97)) {
        std::ofstream(p, std::ios::binary | std::ios::trunc) << original_.substr(0, len);
        EXPECT_THROW((void)read_heyex_xml(p.string()), InputError) << "length " << len;
        ++tried;
    }
    std::cout << "[          ] truncated XML documents tried: " << tried << '\n';
    EXPECT_GT(tried, 1000);
}

}  // namespace
}  // namespace octshape::io
