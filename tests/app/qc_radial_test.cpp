// The QC pictures of radial scans (octshape/qc/onh_radial.h, octshape/qc/macula.h): drawn in
// memory from a real analysis and checked at the pixels their layouts give for the analysis's
// data, and `octshape onh --qc` / `octshape macula --qc` end to end on radial phantoms.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <numbers>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "octshape/qc/macula.h"
#include "octshape/qc/onh_radial.h"
#include "octshape/io/scan_reader.h"
#include "octshape/retina/cube.h"
#include "octshape/retina/onh.h"
#include "octshape/retina/radial_geometry.h"
#include "test_paths.h"

namespace octshape {
namespace {

namespace fs = std::filesystem;

fs::path radial_onh_sample() {
    return test::source_dir() / "sample_scans" / "onh_radial_cupped_os.vol";
}

struct RadialOnh {
    io::Scan scan;
    retina::OnhResult r;
    retina::RadialGeometry geo;
};

// The sample (12 lines x 128 A-scans, OS, crossing 50 um off the disc) analysed with the device
// ILM, as `octshape onh --ilm device --qc` does.
const RadialOnh& analysed_sample() {
    static const RadialOnh s = [] {
        RadialOnh o;
        io::ReadOptions read;
        read.pixels = true;
        o.scan = io::read_scan(radial_onh_sample().string(), read);
        const retina::IlmSurface ilm =
            retina::build_ilm_surface(o.scan, retina::IlmSource::kDevice);
        o.r = retina::analyse_onh(o.scan, ilm);
        o.geo = retina::radial_geometry(o.scan);
        return o;
    }();
    return s;
}

cv::Vec3b at(const cv::Mat& img, cv::Point p) {
    if (p.x < 0 || p.y < 0 || p.x >= img.cols || p.y >= img.rows) return {0, 0, 0};
    return img.at<cv::Vec3b>(p);
}

// Any pixel within `radius` (square window) of p for which `is` holds.
template <class Pred>
bool any_near(const cv::Mat& img, cv::Point p, int radius, Pred is) {
    for (int dy = -radius; dy <= radius; ++dy) {
        for (int dx = -radius; dx <= radius; ++dx) {
            if (is(at(img, p + cv::Point(dx, dy)))) return true;
        }
    }
    return false;
}

// Colour classes of the palette (BGR), loose enough for antialiased edges.
bool reddish(const cv::Vec3b& c) { return c[2] > 150 && c[2] > c[1] + 60 && c[2] > c[0] + 60; }
bool pinkish(const cv::Vec3b& c) { return c[0] > 150 && c[2] > 150 && c[1] + 60 < c[0]; }
bool yellowish(const cv::Vec3b& c) { return c[2] > 150 && c[1] > 120 && c[0] + 80 < c[1]; }
bool blueish(const cv::Vec3b& c) { return c[0] > 150 && c[0] > c[2] + 80 && c[1] + 20 < c[0]; }

// The B-scan titles say what the registrations did (docs/algorithms/onh.md): the axial shift
// (+ = the B-scan lay deeper, moved up), the lateral one (+ = it lay towards higher A-scans,
// moved left), joined; nothing below 0.5 um or when a registration was not applied.
TEST(OnhQc, RegistrationTitleSaysBothShifts) {
    retina::OnhResult r;
    r.axial_registration.applied = true;
    r.axial_registration.shift_um = {12.3, 0.2, -7.0, 0.0};
    r.lateral_registration.applied = true;
    r.lateral_registration.shift_um = {9.0, -15.6, 0.4, 0.0};
    EXPECT_EQ(qc::registration_title(r, 0), ", moved 12 um up, 9 um left");
    EXPECT_EQ(qc::registration_title(r, 1), ", moved 16 um right");
    EXPECT_EQ(qc::registration_title(r, 2), ", moved 7 um down");
    EXPECT_EQ(qc::registration_title(r, 3), "");
    EXPECT_EQ(qc::registration_title(r, 4), "");  // beyond the shifts
    r.lateral_registration.applied = false;  // estimated, not removed: not said
    EXPECT_EQ(qc::registration_title(r, 0), ", moved 12 um up");    // The macula's B-scan picture says its lateral shift the same way (one function, draw.h).
    EXPECT_EQ(qc::registration_title(0.0, 9.0), ", moved 9 um left");
    EXPECT_EQ(qc::registration_title(0.0, -0.4), "");
}

TEST(OnhRadialQc, EnfaceDrawsEachBmoPointOnItsLine) {
    const RadialOnh& s = analysed_sample();
    ASSERT_TRUE(s.r.radial);
    qc::RadialEnfaceLayout L;
    const cv::Mat img = qc::radial_enface_picture(s.scan, s.r, {}, "t", &L);
    const cv::Vec3b white(255, 255, 255);
    const cv::Vec3b line(200, 200, 200);
    ASSERT_EQ(s.r.bmo_measured.size(), 24U);  // two per line
    for (const auto& m : s.r.bmo_measured) {
        // The dots are drawn last, filled, without smoothing: white at their pixel exactly.
        const cv::Point p = L.px(m.mm.x(), m.mm.y());
        EXPECT_EQ(at(img, p), white) << "B-scan " << m.bscan;
        // And they lie on their line as drawn from the scan's Start/End positions: the line's
        // grey 7-10 px either side of the dot along the line (beyond the dot's 3 px radius and
        // the ellipse's 2 px stroke), within 1 px across it (Bresenham rounding).
        const Eigen::Vector2d u = s.geo.direction(m.bscan);
        for (const double sign : {-1.0, 1.0}) {
            bool found = false;
            for (int d = 7; d <= 10 && !found; ++d) {
                const cv::Point q = p + cv::Point(static_cast<int>(std::lround(sign * d * u.x())),
                                                  static_cast<int>(std::lround(-sign * d * u.y())));
                found = any_near(img, q, 1, [&](const cv::Vec3b& c) { return c == line; });
            }
            EXPECT_TRUE(found) << "B-scan " << m.bscan << " side " << sign;
        }
    }
    // Between two lines, at the same distance from the crossing, no line is drawn: at 0.85 of
    // the scanned radius (1.85 mm, 0.3 mm outside the disc circle), half a step (7.5 deg) off a
    // line is 0.24 mm = 30 px away from it.
    const double rr = 0.85 * s.r.radial_scanned_radius_mm;
    for (int k = 0; k < 12; ++k) {
        const Eigen::Vector2d u = s.geo.direction(k);
        const double a = std::atan2(u.y(), u.x()) + 7.5 * std::numbers::pi / 180.0;
        const Eigen::Vector2d q =
            s.r.radial_crossing_mm + rr * Eigen::Vector2d(std::cos(a), std::sin(a));
        EXPECT_FALSE(any_near(img, L.px(q.x(), q.y()), 2, [&](const cv::Vec3b& c) {
            return c == line;
        })) << k;
        const Eigen::Vector2d on = s.r.radial_crossing_mm + rr * u;
        EXPECT_TRUE(any_near(img, L.px(on.x(), on.y()), 1, [&](const cv::Vec3b& c) {
            return c == line;
        })) << k;
    }
}

TEST(OnhRadialQc, BscanSheetDrawsTheUsedIlmWhereTheIlmIsAndTheInplaneMrw) {
    const RadialOnh& s = analysed_sample();
    qc::RadialSheetLayout L;
    const cv::Mat img = qc::radial_bscans_picture(s.scan, s.r, "t", &L);
    ASSERT_EQ(L.lines, 12);
    ASSERT_EQ(img.cols, L.cols * L.panel_w + (L.cols - 1) * L.gap);
    const int nx = s.scan.meta.size_x;
    const double dz = s.scan.meta.scale_z_mm;
    // The used ILM (the device mesh cut by each B-scan's plane) over the device ILM line, on
    // the retina outside the disc (1.5 mm to 0.98 of the scanned radius, 2.13 mm, from the
    // crossing; the BMO is 0.85 mm out).
    // Its vertices off the line carry values interpolated in angle at the same radius, which
    // differ from the line's by a fraction of a depth pixel there; drawing rounds by 0.5 px and
    // smooths by 1 px: within 2 px. Not red 12 px above it (the vitreous).
    int checked = 0;
    int missed = 0;
    for (int k = 0; k < L.lines; ++k) {
        const io::BScan& bs = s.scan.bscans[static_cast<std::size_t>(k)];
        const auto& ilm = bs.seg[static_cast<std::size_t>(io::Layer::kILM)];
        const double ds = s.geo.lines[static_cast<std::size_t>(k)].length_mm / (nx - 1);
        const double foot = s.geo.lines[static_cast<std::size_t>(k)].crossing_along_mm / ds;
        for (int a = 0; a < nx; ++a) {
            const double rr = std::fabs(a - foot) * ds;
            if (rr < 1.5 || rr > 0.98 * s.r.radial_scanned_radius_mm) continue;
            if (!io::is_valid(ilm[static_cast<std::size_t>(a)])) continue;
            const cv::Point p = L.px(k, a, ilm[static_cast<std::size_t>(a)]);
            ++checked;
            if (!any_near(img, p, 2, reddish)) ++missed;
            EXPECT_FALSE(reddish(at(img, p - cv::Point(0, 12)))) << k << " " << a;
        }
    }
    EXPECT_GT(checked, 12 * 2 * 15);  // 0.6 mm each side of each line: ~17 A-scans
    EXPECT_EQ(missed, 0) << "of " << checked;
    // Every in-plane MRW segment from its BMO point (ringed) to its ILM point, and the BMO
    // point at the end of the BM line (half an A-scan beyond its last value: 1.6 px here).
    ASSERT_EQ(s.r.mrw_inplane.size(), 24U);
    for (const auto& m : s.r.mrw_inplane) {
        const Eigen::Vector2d o = s.r.radial_crossing_mm + s.geo.ascan_mm(m.bscan, 0.0, nx);
        const Eigen::Vector2d u = s.geo.direction(m.bscan);
        const double ds = s.geo.lines[static_cast<std::size_t>(m.bscan)].length_mm / (nx - 1);
        const double a0 = (m.bmo_mm.head<2>() - o).dot(u) / ds;
        const double a1 = (m.ilm_mm.head<2>() - o).dot(u) / ds;
        const cv::Point p0 = L.px(m.bscan, a0, -m.bmo_mm.z() / dz);
        const cv::Point p1 = L.px(m.bscan, a1, -m.ilm_mm.z() / dz);
        ASSERT_GT(cv::norm(p1 - p0), 12.0);  // long enough to tell its ends from the ring
        EXPECT_TRUE(any_near(img, p1, 1, pinkish)) << m.bscan;
        EXPECT_TRUE(any_near(img, (p0 + p1) / 2, 1, pinkish)) << m.bscan;
        int ring = 0;
        for (int dy = -7; dy <= 7; ++dy) {
            for (int dx = -7; dx <= 7; ++dx) {
                const double d = std::hypot(dx, dy);
                if (d >= 4.0 && d <= 6.0 && yellowish(at(img, p0 + cv::Point(dx, dy)))) ++ring;
            }
        }
        EXPECT_GE(ring, 12) << m.bscan;  // a 5 px ring has ~30 pixels; the segment hides few
        EXPECT_FALSE(yellowish(at(img, p0))) << m.bscan;  // a ring, not a dot
        EXPECT_TRUE(any_near(img, p0, 4, blueish)) << m.bscan;
    }
}

TEST(OnhRadialQc, CliWritesTheThreePicturesWholeUnderTheStem) {
    const test::TempDir dir;
    const auto r =
        test::run_octshape("onh " + radial_onh_sample().string() + " --ilm device -o " +
                           (dir / "left.json").string() + " --qc " + (dir / "qc").string());
    ASSERT_EQ(r.exit_code, 0) << r.err;
    // Exactly the volume's three names (the gallery and the cohort's resume know them), no
    // temporary left beside them (each is written atomically).
    std::set<std::string> names;
    for (const auto& e : fs::directory_iterator(dir / "qc")) names.insert(e.path().filename());
    EXPECT_EQ(names, (std::set<std::string>{"left_enface.png", "left_bscans.png", "left_mrw.png"}));
    const cv::Mat enface = cv::imread((dir / "qc" / "left_enface.png").string());
    const cv::Mat sheet = cv::imread((dir / "qc" / "left_bscans.png").string());
    const cv::Mat mrw = cv::imread((dir / "qc" / "left_mrw.png").string());
    ASSERT_FALSE(enface.empty());
    ASSERT_FALSE(sheet.empty());
    ASSERT_FALSE(mrw.empty());
    // The en-face: 760 px of grid, 40 px margins, the colour bar: 980 px wide.
    EXPECT_EQ(enface.cols, 980);
    // 12 B-scans in 4 columns of 400 px (6 px apart) and 3 rows of 240 px.
    EXPECT_EQ(sheet.cols, 4 * 400 + 3 * 6);
    EXPECT_EQ(sheet.rows, 34 + 3 * 240 + 2 * 6 + 84);
    EXPECT_EQ(mrw.cols, 930);
    const nlohmann::json j = nlohmann::json::parse(test::slurp(dir / "left.json"));
    EXPECT_EQ(j["radial"]["lines"], 12);
}

// The cohort writes them where it writes a volume's (qc/<eye key>_KIND.png) and its gallery
// lists them. (`--type onh`: the automatic scan type refuses radial patterns, docs/cohort.md.)
TEST(OnhRadialQc, CohortWritesThemAndTheGalleryListsThem) {
    const test::TempDir dir;
    fs::create_directories(dir / "in");
    fs::copy_file(radial_onh_sample(), dir / "in" / "scan.vol");
    const auto r = test::run_octshape("cohort " + (dir / "in").string() + " -o " +
                                      (dir / "out").string() +
                                      " --type onh --ilm device --qc -q --jobs 1");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    std::vector<std::string> pngs;
    for (const auto& e : fs::directory_iterator(dir / "out" / "qc")) {
        if (e.path().extension() == ".png") pngs.push_back(e.path().filename());
    }
    std::sort(pngs.begin(), pngs.end());
    ASSERT_EQ(pngs.size(), 3U);
    const std::string page = test::slurp(dir / "out" / "qc" / "index.html");
    for (const char* kind : {"_bscans.png", "_enface.png", "_mrw.png"}) {
        const auto it = std::find_if(pngs.begin(), pngs.end(),
                                     [&](const std::string& n) { return n.ends_with(kind); });
        ASSERT_NE(it, pngs.end()) << kind;
        EXPECT_NE(page.find("src=\"" + *it + "\""), std::string::npos) << *it;
        EXPECT_FALSE(cv::imread((dir / "out" / "qc" / *it).string()).empty()) << *it;
    }
    EXPECT_EQ(page.find("scan.vol"), std::string::npos);  // no file name on the shared page
}

// A folder of radial scans with the cohort's defaults (the classifier, the level-set ILM): the
// radial ONH scan is an ONH eye, the radial macula scan a macula eye, each one row of its table
// with the scan pattern it has.
TEST(RadialCohort, DefaultsClassifyAndAnalyseRadialOnhAndMaculaScans) {
    const test::TempDir dir;
    fs::create_directories(dir / "in");
    fs::copy_file(radial_onh_sample(), dir / "in" / "disc.vol");
    const auto made = test::run_octshape("phantom macula --pattern radial --lines 12 -o " +
                                         (dir / "in" / "fovea.vol").string());
    ASSERT_EQ(made.exit_code, 0) << made.err;
    fs::remove(dir / "in" / "fovea.truth.json");  // only the scans in the folder
    const auto r = test::run_octshape("cohort " + (dir / "in").string() + " -o " +
                                      (dir / "out").string() + " -q --jobs 1");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const auto rows = [&](const char* table) {
        std::vector<std::string> lines;
        std::istringstream in(test::slurp(dir / "out" / table));
        for (std::string line; std::getline(in, line);) lines.push_back(line);
        return lines;
    };
    const auto macula = rows("eyes.csv");
    const auto onh = rows("eyes_onh.csv");
    ASSERT_EQ(macula.size(), 2U);  // header + the radial macula eye
    ASSERT_EQ(onh.size(), 2U);     // header + the radial ONH eye
    EXPECT_NE(macula[1].find(",macula,"), std::string::npos) << macula[1];
    EXPECT_NE(onh[1].find(",onh,"), std::string::npos) << onh[1];
    EXPECT_NE(onh[1].find(",levelset,"), std::string::npos) << onh[1];
    // The in-plane MRW exists for radial scans only (NA for volumes): the row is a radial eye's.
    const auto split = [](const std::string& line) {
        std::vector<std::string> cells;
        std::istringstream in(line);
        for (std::string c; std::getline(in, c, ',');) cells.push_back(c);
        return cells;
    };
    const auto header = split(onh[0]);
    const auto values = split(onh[1]);
    const auto col = std::find(header.begin(), header.end(), "mrw_inplane_mean_mm");
    ASSERT_NE(col, header.end()) << onh[0];
    const auto at = static_cast<std::size_t>(col - header.begin());
    ASSERT_LT(at, values.size());
    EXPECT_GT(std::stod(values[at]), 0.1) << values[at];  // mm; a normal rim is ~0.3 mm
    EXPECT_FALSE(fs::exists(dir / "out" / "failures.csv") &&
                 rows("failures.csv").size() > 1);
}

// ---- Radial macula -----------------------------------------------------------------------

TEST(MaculaRadialQc, ThicknessIsDrawnAlongEachLineAndNowhereElse) {
    const test::TempDir dir;
    const auto vol = dir / "m.vol";
    const auto made =
        test::run_octshape("phantom macula --pattern radial --lines 12 -o " + vol.string());
    ASSERT_EQ(made.exit_code, 0) << made.err;
    io::ReadOptions read;
    read.pixels = true;
    const io::Scan scan = io::read_scan(vol.string(), read);
    retina::CubeParams params;
    params.num_half_lines = 24;  // twice the lines (cube.h)
    const retina::CubeResult r = retina::analyse_macula(scan, params);
    ASSERT_TRUE(r.radial_scan);
    const retina::RadialGeometry geo = retina::radial_geometry(scan);
    qc::RadialThicknessLayout L;
    const cv::Mat img = qc::macula_radial_thickness_picture(r, scan, "t", &L);
    const auto [lo, hi] = qc::macula_thickness_range(r);
    cv::Mat ramp(1, 256, CV_8UC1);
    for (int i = 0; i < 256; ++i) ramp.at<uchar>(0, i) = static_cast<uchar>(i);
    cv::Mat lut;
    cv::applyColorMap(ramp, lut, cv::COLORMAP_VIRIDIS);
    auto colour = [&](double v) {
        const int i =
            static_cast<int>(std::lround(255 * std::clamp((v - lo) / (hi - lo), 0.0, 1.0)));
        return lut.at<cv::Vec3b>(0, i);
    };
    const int nx = scan.meta.size_x;
    int checked = 0;
    for (int k = 0; k < static_cast<int>(geo.lines.size()); ++k) {
        for (int a = 0; a < nx; a += 7) {
            const Eigen::Vector2d p = geo.ascan_mm(k, a, nx);
            // Beyond the rim (about 1.2 mm) and before the lines' numbers.
            if (p.norm() < 2.0 || p.norm() > 2.8) continue;
            // The line is 7 px wide and A-scans ~1 px apart: the pixel of A-scan a is painted
            // by a neighbour up to 4 A-scans on; its colour is one of theirs.
            const cv::Vec3b got = at(img, L.px(p.x(), p.y()));
            bool match = false;
            for (int n = std::max(0, a - 6); n <= std::min(nx - 1, a + 6); ++n) {
                match = match || got == colour(r.map.at(k, n));
            }
            EXPECT_TRUE(match) << "line " << k << " A-scan " << a << ": " << got;
            ++checked;
        }
    }
    EXPECT_GT(checked, 12 * 2 * 10);
    // Half-way between two lines 2.5 mm out (0.33 mm = 44 px from either): the background,
    // where an interpolated map would have a thickness colour.
    const cv::Vec3b panel(30, 30, 30);
    for (int k = 0; k < static_cast<int>(geo.lines.size()); ++k) {
        const Eigen::Vector2d u = geo.direction(k);
        const double a = std::atan2(u.y(), u.x()) + 7.5 * std::numbers::pi / 180.0;
        for (const double sign : {-1.0, 1.0}) {
            const cv::Point q = L.px(sign * 2.5 * std::cos(a), sign * 2.5 * std::sin(a));
            EXPECT_EQ(at(img, q), panel) << k;
        }
    }
    // The B-scan picture: the line nearest the horizontal, i.e. the phantom's first (0 deg).
    int b = -1;
    const cv::Mat bscan = qc::macula_bscan_picture(r, scan, "t", &b);
    ASSERT_FALSE(bscan.empty());
    ASSERT_EQ(b, 0);
    // Its fitted profile (BM raised by the fitted thickness: yellow) on the device ILM along
    // the line, 0.3-1.8 mm either side of the centre's foot (the phantom's fit RMSE is below
    // 0.1 um). The picture's layout (octshape/qc/macula.h): 900 px wide, depth rows stretched by half
    // the width's factor, at (70, 24) under the 34-px title; the 2-px stroke and rounding:
    // within 2 px.
    const double sx = 900.0 / nx;
    const int H = std::max(120, static_cast<int>(std::lround(scan.meta.size_z * sx * 0.5)));
    const double sz = static_cast<double>(H) / scan.meta.size_z;
    const auto& ilm = scan.bscans[0].seg[static_cast<std::size_t>(io::Layer::kILM)];
    const Eigen::Vector2d p0 = geo.ascan_mm(0, 0.0, nx);
    const double ds = geo.lines[0].length_mm / (nx - 1);
    const double foot = (r.centre_mm - p0).dot(geo.direction(0)) / ds;
    int on_ilm = 0;
    int tried = 0;
    for (int a = 0; a < nx; ++a) {
        const double rr = std::fabs(a - foot) * ds;
        if (rr < 0.3 || rr > 1.8 || !io::is_valid(ilm[static_cast<std::size_t>(a)])) continue;
        const cv::Point q(70 + static_cast<int>(std::lround((a + 0.5) * sx)),
                          34 + 24 + static_cast<int>(std::lround(
                                        (ilm[static_cast<std::size_t>(a)] + 0.5) * sz)));
        ++tried;
        if (any_near(bscan, q, 2, yellowish)) ++on_ilm;
    }
    EXPECT_GT(tried, 300);
    EXPECT_EQ(on_ilm, tried);
}

TEST(MaculaRadialQc, CliWritesItsThreePictures) {
    const test::TempDir dir;
    const auto vol = dir / "m.vol";
    ASSERT_EQ(test::run_octshape("phantom macula --pattern radial --lines 6 -o " + vol.string())
                  .exit_code,
              0);
    const auto r =
        test::run_octshape("macula " + vol.string() + " -o " + (dir / "right.json").string() +
                           " --qc " + (dir / "qc").string());
    ASSERT_EQ(r.exit_code, 0) << r.err;
    std::set<std::string> names;
    for (const auto& e : fs::directory_iterator(dir / "qc")) names.insert(e.path().filename());
    EXPECT_EQ(names, (std::set<std::string>{"right_thickness.png", "right_profiles.png",
                                            "right_bscan.png"}));
    const cv::Mat t = cv::imread((dir / "qc" / "right_thickness.png").string());
    ASSERT_FALSE(t.empty());
    // The radial picture (800 px square and its colour bar), not a map of 6 rows.
    EXPECT_EQ(t.cols, 930);
    EXPECT_GT(t.rows, 800);
}

}  // namespace
}  // namespace octshape
