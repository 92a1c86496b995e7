// Iowa surfaces XML: the real OCTLayerSeg file of a real Spectralis volume read alone, its
// values checked against the file's own text (counted here independently of the reader), its
// round trip through our .vol writer, its lines laid over an export, and every kind of damage
// refused with a typed error naming the file.

#include "octshape/io/iowa_surfaces.h"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <sstream>
#include <string>

#include "fixtures/iowa_xml.h"
#include "octshape/error.h"
#include "octshape/io/scan_reader.h"
#include "octshape/io/vol.h"
#include "test_paths.h"

namespace octshape::test {
namespace {

const std::string kReal = "T566581_Surfaces_Iowa.xml";

std::string slurp(const std::filesystem::path& p) {
    std::ifstream in(p, std::ios::binary);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
}

// The <y> values of the surface with `label`, read with plain string search (not the reader).
std::vector<int> raw_values(const std::string& doc, int label) {
    const std::string tag = "<label>" + std::to_string(label) + "</label>";
    std::size_t pos = doc.find(tag);
    const std::size_t end = doc.find("</surface>", pos);
    std::vector<int> out;
    while ((pos = doc.find("<y>", pos)) != std::string::npos && pos < end) {
        pos += 3;
        out.push_back(std::stoi(doc.substr(pos, doc.find('<', pos) - pos)));
    }
    return out;
}

TEST(IowaSurfaces, RealFileReadsWithItsStatedSizesAndSurfaces) {
    SKIP_UNLESS_SHARED("realdata/T566581_Surfaces_Iowa.xml");
    const auto path = realdata(kReal).string();
    const io::IowaSurfaces s = io::read_iowa_surfaces(path);
    // The sizes the realdata README states for this file.
    EXPECT_EQ(s.size_x, 512);
    EXPECT_EQ(s.size_y, 496);
    EXPECT_EQ(s.size_z, 19);
    EXPECT_DOUBLE_EQ(s.voxel_x_mm, 0.011680);
    EXPECT_DOUBLE_EQ(s.voxel_y_mm, 0.003872);
    EXPECT_DOUBLE_EQ(s.voxel_z_mm, 0.249175);
    EXPECT_EQ(s.laterality, io::Laterality::kOD);
    EXPECT_EQ(s.executable, "OCTLayerSeg");
    EXPECT_EQ(s.executable_version, "3.8.0");
    ASSERT_EQ(s.surfaces.size(), 11U);
    EXPECT_EQ(s.num_undefined, 84);
    const std::vector<int> labels = {10, 20, 30, 40, 50, 60, 100, 110, 120, 140, 150};
    const std::string doc = slurp(realdata(kReal));
    std::size_t undefined = 0;
    for (std::size_t k = 0; k < labels.size(); ++k) {
        const io::IowaSurface& surface = s.surfaces[k];
        EXPECT_EQ(surface.label, labels[k]);
        const std::vector<int> raw = raw_values(doc, labels[k]);
        ASSERT_EQ(raw.size(), 512U * 19U);
        ASSERT_EQ(surface.depth_px.size(), raw.size());
        std::size_t nan = 0;
        for (std::size_t i = 0; i < raw.size(); ++i) {
            if (std::isnan(surface.depth_px[i])) {
                ++nan;
            } else {
                ASSERT_EQ(surface.depth_px[i], static_cast<float>(raw[i])) << labels[k] << " " << i;
            }
        }
        // Every surface is undefined exactly at the listed A-scans.
        EXPECT_EQ(nan, 84U) << labels[k];
        undefined = nan;
    }
    EXPECT_EQ(undefined, 84U);
    // Anatomy, as a check that rows are depths from the top: the ILM lies above both RPE
    // boundaries, and the RPE's inner boundary above its outer one, at every defined A-scan.
    const auto& ilm = s.find(10)->depth_px;
    const auto& ib = s.find(140)->depth_px;
    const auto& ob = s.find(150)->depth_px;
    double rpe_sum = 0.0;
    int n = 0;
    for (std::size_t i = 0; i < ilm.size(); ++i) {
        if (std::isnan(ilm[i])) continue;
        ASSERT_LT(ilm[i], ib[i]);
        ASSERT_LE(ib[i], ob[i]);
        rpe_sum += ob[i] - ib[i];
        ++n;
    }
    // The RPE's thickness between the two boundaries (docs/formats.md cites this number).
    std::printf("RPE IB-OB mean %.2f px = %.1f um over %d A-scans\n", rpe_sum / n,
                rpe_sum / n * 3.872, n);
}

TEST(IowaSurfaces, ReadAloneIsAScanOfSegmentationOnly) {
    SKIP_UNLESS_SHARED("realdata/T566581_Surfaces_Iowa.xml");
    const auto path = realdata(kReal).string();
    EXPECT_EQ(io::detect_format(path), io::FileFormat::kIowaSurfaces);
    const io::IowaSurfaces s = io::read_iowa_surfaces(path);
    const io::Scan scan = io::read_scan(path);
    EXPECT_EQ(scan.meta.format, io::SourceFormat::kIowaSurfaces);
    EXPECT_EQ(scan.meta.pattern, io::ScanPattern::kVolume);
    EXPECT_EQ(scan.num_bscans(), 19);
    EXPECT_EQ(scan.meta.size_x, 512);
    EXPECT_EQ(scan.meta.size_z, 496);
    EXPECT_DOUBLE_EQ(scan.meta.scale_x_mm, 0.011680);
    EXPECT_DOUBLE_EQ(scan.meta.scale_z_mm, 0.003872);
    EXPECT_DOUBLE_EQ(scan.meta.distance_mm, 0.249175);
    EXPECT_FALSE(scan.pixels_loaded);
    ASSERT_EQ(scan.num_lines(), 11);
    EXPECT_EQ(scan.line_name(0), "ILM");
    EXPECT_EQ(scan.line_name(1), "BM");
    EXPECT_EQ(scan.find_line("IB_RPE"), std::optional<int>(10));
    EXPECT_EQ(scan.find_line("RNFL-GCL"), std::optional<int>(2));
    EXPECT_EQ(scan.find_line("bm"), std::optional<int>(1));
    const auto& ob = s.find(150)->depth_px;
    const auto& ib = s.find(140)->depth_px;
    for (int b = 0; b < 19; ++b) {
        for (int a = 0; a < 512; ++a) {
            const std::size_t i = static_cast<std::size_t>(b) * 512 + static_cast<std::size_t>(a);
            const float bm = scan.depth_px(1, b, a);
            ASSERT_TRUE((std::isnan(bm) && std::isnan(ob[i])) || bm == ob[i]);
        }
    }
    // The inner boundary on request.
    io::ReadOptions inner;
    inner.iowa_bm = io::IowaBm::kInnerRpe;
    const io::Scan scan140 = io::read_scan(path, inner);
    EXPECT_EQ(scan140.depth_px(1, 9, 256), ib[9 * 512 + 256]);
    EXPECT_EQ(scan140.find_line("OB_RPE"), std::optional<int>(10));
}

TEST(IowaSurfaces, VolRoundTripKeepsEverySegmentationValue) {
    SKIP_UNLESS_SHARED("realdata/T566581_Surfaces_Iowa.xml");
    TempDir dir;
    const io::Scan scan = io::read_scan(realdata(kReal).string());
    const auto vol = (dir / "iowa.vol").string();
    io::write_vol_file(scan, vol);
    const io::Scan back = io::read_scan(vol);
    ASSERT_EQ(back.num_bscans(), scan.num_bscans());
    ASSERT_EQ(back.num_lines(), scan.num_lines());
    EXPECT_EQ(back.meta.laterality, io::Laterality::kOD);
    EXPECT_DOUBLE_EQ(back.meta.distance_mm, scan.meta.distance_mm);
    for (int k = 0; k < scan.num_lines(); ++k) {
        for (int b = 0; b < scan.num_bscans(); ++b) {
            for (int a = 0; a < scan.meta.size_x; ++a) {
                const float x = scan.depth_px(k, b, a);
                const float y = back.depth_px(k, b, a);
                ASSERT_TRUE((std::isnan(x) && std::isnan(y)) || x == y) << k << " " << b << " " << a;
            }
        }
    }
}

// A written small document, read through read_scan as a user's file would be.
std::string write_doc(const TempDir& dir, const IowaDoc& d, const std::string& name = "s.xml") {
    const auto p = (dir / name).string();
    std::ofstream(p, std::ios::binary) << iowa_xml(d);
    return p;
}

TEST(IowaSurfaces, SmallDocumentValuesAndUndefinedAScans) {
    TempDir dir;
    const IowaDoc d;
    const io::Scan s = io::read_scan(write_doc(dir, d));
    ASSERT_EQ(s.num_bscans(), 3);
    ASSERT_EQ(s.num_lines(), 3);
    EXPECT_EQ(s.depth_px(0, 0, 4), 10.0F + 4 % 3);
    EXPECT_EQ(s.depth_px(1, 2, 2), 34.0F + 2);  // BM = label 150
    EXPECT_EQ(s.depth_px(2, 2, 2), 30.0F + 2);  // IB_RPE after it
    for (int k = 0; k < 3; ++k) EXPECT_TRUE(std::isnan(s.depth_px(k, 1, 5)));
    EXPECT_FALSE(std::isnan(s.depth_px(0, 0, 5)));
}

// Each damage: the error's kind and a phrase of its message; every message names the file.
struct Damage {
    std::string what;
    IowaDoc doc;
    InputError::Kind kind;
    std::string phrase;
};

std::vector<Damage> damages() {
    std::vector<Damage> v;
    auto add = [&](std::string what, auto change, InputError::Kind kind, std::string phrase) {
        IowaDoc d;
        change(d);
        v.push_back({std::move(what), d, kind, std::move(phrase)});
    };
    using K = InputError::Kind;
    add("fewer values than size x", [](IowaDoc& d) { d.drop_values = 1; }, K::kCorrupt,
        "<y> values");
    add("surface_size differs", [](IowaDoc& d) { d.surface_size_x = 7; }, K::kCorrupt,
        "<surface_size>");
    add("surface_num differs", [](IowaDoc& d) { d.surface_num = 5; }, K::kCorrupt,
        "<surface_num>");
    add("no ILM", [](IowaDoc& d) { d.labels = {20, 140, 150}; }, K::kUnsupported, "label 10");
    add("no OB_RPE", [](IowaDoc& d) { d.labels = {10, 140, 160}; }, K::kUnsupported, "label 150");
    add("label twice", [](IowaDoc& d) { d.labels = {10, 140, 150, 150}; d.base = {10, 30, 34, 34}; },
        K::kCorrupt, "twice");
    add("non-numeric value", [](IowaDoc& d) { d.override_value = "abc"; }, K::kCorrupt,
        "not a number");
    add("infinite value", [](IowaDoc& d) { d.override_value = "inf"; }, K::kCorrupt,
        "not a number");
    add("absurd row", [](IowaDoc& d) { d.override_value = "1e300"; }, K::kCorrupt, "not a depth");
    add("absurd size", [](IowaDoc& d) { d.size_x_text = "1000000000"; }, K::kCorrupt, "not a size");
    add("zero size", [](IowaDoc& d) { d.size_z = 0; }, K::kCorrupt, "not a size");
    add("voxel size zero", [](IowaDoc& d) { d.voxel_y = "0"; }, K::kCorrupt, "voxel size");
    add("voxel size text", [](IowaDoc& d) { d.voxel_x = "wide"; }, K::kCorrupt, "not a number");
    add("undefined outside", [](IowaDoc& d) { d.undefined = {{6, 0}}; }, K::kCorrupt,
        "outside the");
    add("DOCTYPE", [](IowaDoc& d) { d.prologue = "<!DOCTYPE surfaces [<!ENTITY a \"b\">]>\n"; },
        K::kCorrupt, "DOCTYPE");
    return v;
}

TEST(IowaSurfaces, DamagedDocumentsAreRefusedWithTypedErrors) {
    TempDir dir;
    for (const Damage& d : damages()) {
        const auto path = write_doc(dir, d.doc, "damaged.xml");
        try {
            (void)io::read_scan(path);
            ADD_FAILURE() << d.what << ": read";
        } catch (const InputError& e) {
            EXPECT_EQ(e.kind(), d.kind) << d.what << ": " << e.what();
            EXPECT_NE(std::string(e.what()).find(d.phrase), std::string::npos)
                << d.what << ": " << e.what();
            EXPECT_EQ(std::string(e.what()).rfind(path, 0), 0U) << d.what << ": " << e.what();
        }
    }
}

TEST(IowaSurfaces, TruncatedRealFileIsRefusedAtEveryCut) {
    SKIP_UNLESS_SHARED("realdata/T566581_Surfaces_Iowa.xml");
    // The real document cut at 64 places: a parse error (corrupt, with an offset), never a read.
    TempDir dir;
    const std::string doc = slurp(realdata(kReal));
    for (int i = 1; i <= 64; ++i) {
        const std::size_t cut = doc.size() * static_cast<std::size_t>(i) / 65;
        try {
            (void)io::parse_iowa_surfaces(std::string_view(doc).substr(0, cut), "cut.xml");
            ADD_FAILURE() << "cut at " << cut << " read";
        } catch (const InputError& e) {
            EXPECT_NE(std::string(e.what()).find("cut.xml"), std::string::npos);
        }
    }
}

TEST(IowaSurfaces, SegmentationOverAnExportMustDescribeIt) {
    TempDir dir;
    IowaDoc d;
    const io::Scan seg = io::read_scan(write_doc(dir, d, "seg.xml"));
    // An "export": the same geometry with its own lines and pixels.
    io::Scan exp = seg;
    exp.source_path = "export.vol";
    exp.meta.format = io::SourceFormat::kVol;
    exp.line_names.clear();
    for (auto& b : exp.bscans) {
        b.seg.assign(2, std::vector<float>(6, 1.0F));
        b.pixels.assign(6 * 40, 0.5F);
    }
    exp.pixels_loaded = true;
    io::Scan over = exp;
    io::apply_segmentation(over, seg);
    EXPECT_EQ(over.num_lines(), 3);
    EXPECT_EQ(over.depth_px(1, 0, 0), 34.0F);
    EXPECT_EQ(over.bscans[0].pixels, exp.bscans[0].pixels);
    EXPECT_EQ(over.line_name(2), "S140");
    auto refused = [&](auto change, const std::string& phrase) {
        io::Scan e = exp;
        change(e);
        try {
            io::apply_segmentation(e, seg);
            ADD_FAILURE() << phrase;
        } catch (const UsageError& err) {
            const std::string m = err.what();
            EXPECT_NE(m.find(phrase), std::string::npos) << m;
            EXPECT_NE(m.find("seg.xml"), std::string::npos) << m;
            EXPECT_NE(m.find("export.vol"), std::string::npos) << m;
        }
    };
    refused([](io::Scan& e) { e.meta.size_z = 496; }, "pixels per A-scan");
    refused([](io::Scan& e) { e.bscans.pop_back(); }, "B-scans");
    refused([](io::Scan& e) { e.meta.laterality = io::Laterality::kOS; }, "eye");
    refused([](io::Scan& e) { e.meta.scale_x_mm = 0.0117 * 1.5; }, "A-scan spacing");
    refused([](io::Scan& e) { e.meta.distance_mm = 0.125; }, "B-scan spacing");
}

}  // namespace
}  // namespace octshape::test
