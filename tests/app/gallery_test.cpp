// The QC gallery (`octshape gallery OUTDIR`) loaded in headless Chromium (Debian `chromium`):
// no console messages, every eye and failure in the DOM, working picture links, sorting, and a
// screenshot. The page never logs, so any console line is a fault; a deliberately broken page
// proves the detection works.

#include <gtest/gtest.h>
#include <sys/wait.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "test_paths.h"
#include "slow_test.h"

namespace octshape::test {
namespace {

namespace fs = std::filesystem;

// Positions of every occurrence of `needle` in `text` (plain search: std::regex trips a GCC 12
// -Wmaybe-uninitialized false positive under the sanitizer build).
std::vector<std::size_t> occurrences(const std::string& text, const std::string& needle) {
    std::vector<std::size_t> at;
    for (std::size_t p = text.find(needle); p != std::string::npos;
         p = text.find(needle, p + needle.size())) {
        at.push_back(p);
    }
    return at;
}



struct Browser {
    int exit_code = -1;
    std::string dom;
    std::string log;
};

// Headless Chromium with a throw-away profile; --no-sandbox because CI runs as root.
Browser chromium(const fs::path& profile, const std::string& url, const std::string& extra) {
    const fs::path out = profile / "stdout.txt";
    const fs::path err = profile / "stderr.txt";
    const std::string cmd =
        "timeout 120 chromium --headless --no-sandbox --disable-gpu "
        "--no-first-run --user-data-dir='" +
        (profile / "ud").string() + "' --enable-logging=stderr --v=0 " + extra + " '" + url +
        "' > '" + out.string() + "' 2> '" + err.string() + "'";
    Browser b;
    const int rc = std::system(cmd.c_str());
    b.exit_code = WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
    b.dom = slurp(out);
    b.log = slurp(err);
    return b;
}

std::vector<std::string> console_lines(const std::string& log) {
    std::vector<std::string> lines;
    std::istringstream in(log);
    for (std::string l; std::getline(in, l);) {
        if (l.find(":CONSOLE") != std::string::npos) lines.push_back(l);
    }
    return lines;
}

// A cohort-like OUTDIR from real analyses of two phantoms (their QC pictures), a third eye
// without pictures, an eyes.csv that adds subject/visit/group, and two failures.
void make_outdir(const fs::path& d) {
    fs::create_directories(d / "eyes");
    fs::create_directories(d / "qc");
    fs::create_directories(d / "in");
    const std::string common =
        " --bscans 25 --ascans 128 --depth 160 --wall-radius-mm 0 "
        "--tilt-x 0 --tilt-y 0 --no-pixels";
    ASSERT_EQ(run_octshape("phantom macula -o " + (d / "in" / "a.vol").string() + common).exit_code,
              0);
    ASSERT_EQ(
        run_octshape("phantom macula --eye OS --flat -o " + (d / "in" / "b.vol").string() + common)
            .exit_code,
        0);
    for (const char* k : {"a", "b"}) {
        const RunResult r = run_octshape(
            "macula " + (d / "in" / (std::string(k) + ".vol")).string() + " -o " +
            (d / "eyes" / (std::string(k) + ".json")).string() + " --qc " + (d / "qc").string());
        ASSERT_EQ(r.exit_code, 0) << r.err;
    }
    spit(d / "eyes" / "c_line.json",
          R"({"command":"macula","input":{"sha256":"cc"},)"
          R"("cohort":{"subject_id":"S9","visit_date":"2024-01-09","group":"case"},)"
          R"("parameters":{"cft_mm":0.1,"rim_height_mm":null},"qc_flags":["fit RMSE high"]})");
    // eyes.csv rows are found by eye key (the JSON's file name stem: "a").
    spit(d / "eyes.csv",
          "subject_id,eye,visit_date,scan_type,eye_key,sha256,group,cft_mm\n"
          "S1,OD,2024-01-01,macula,a,zz,control,0.2\n");
    spit(d / "failures.csv",
          "eye_key,reason,exit_code\n"
          "0b0b0b0b0b0b0b0b,\"truncated at offset 2048, <script>alert(1)</script>\",65\n"
          "0d0d0d0d0d0d0d0d,no such file,66\n");
}

TEST(GalleryBrowser, DetectsConsoleErrorsOnABrokenPage) {
    TempDir dir;
    spit(dir / "bad.html",
          "<!DOCTYPE html><html><head><link rel=\"icon\" href=\"data:,\">"
          "</head><body><script>no_such_function();</script></body></html>");
    const Browser b = chromium(dir.path(), "file://" + (dir / "bad.html").string(), "--dump-dom");
    ASSERT_EQ(b.exit_code, 0) << b.log;
    EXPECT_FALSE(console_lines(b.log).empty()) << b.log;
}

// Slow: analyses two phantoms and starts headless Chromium twice (~7 s alone).
SLOW_TEST(Gallery, PageInHeadlessChromium) {
    TempDir dir;
    const fs::path out = dir / "out";
    ASSERT_NO_FATAL_FAILURE(make_outdir(out));
    const RunResult r = run_octshape("gallery " + out.string());
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const fs::path page = out / "qc" / "index.html";
    ASSERT_TRUE(fs::exists(page));
    const std::string html = slurp(page);
    // Static and self-contained: no external scripts, styles or fonts.
    EXPECT_EQ(html.find("http://"), std::string::npos);
    EXPECT_EQ(html.find("https://"), std::string::npos);
    EXPECT_EQ(html.find("<script src"), std::string::npos);
    EXPECT_EQ(html.find("<script>alert"), std::string::npos);  // the failure reason is escaped

    // Sorted by cft_mm on load (#sort=cft_mm): the ascending order of the three CFTs.
    const Browser b =
        chromium(dir.path(), "file://" + page.string() + "#sort=cft_mm", "--dump-dom");
    ASSERT_EQ(b.exit_code, 0) << b.log;
    EXPECT_TRUE(console_lines(b.log).empty()) << b.log;
    EXPECT_NE(b.dom.find("data-ready=\"1\""), std::string::npos) << "script did not finish";
    // Every eye, every failure.
    for (const char* key : {"a", "b", "c_line"}) {
        EXPECT_NE(b.dom.find(std::string("data-key=\"") + key + "\""), std::string::npos) << key;
    }
    EXPECT_NE(b.dom.find("0b0b0b0b0b0b0b0b"), std::string::npos);
    EXPECT_NE(b.dom.find("0d0d0d0d0d0d0d0d"), std::string::npos);
    // No path on the page (it is shared with the rest of OUTDIR: docs/cohort.md).
    EXPECT_EQ(html.find(out.string()), std::string::npos);
    EXPECT_EQ(html.find(".vol"), std::string::npos);
    EXPECT_EQ(occurrences(b.dom, "<tr class=\"failure\">").size(), 2U);
    // Failures come before the eye table.
    EXPECT_LT(b.dom.find("id=\"failures\""), b.dom.find("id=\"eyes\""));
    // eyes.csv adds the subject of eye "a"; the JSON's cohort object that of "c_line".
    EXPECT_NE(b.dom.find("<td>S1</td>"), std::string::npos);
    EXPECT_NE(b.dom.find("<td>S9</td>"), std::string::npos);
    // The flagged eye is marked, its flag shown.
    EXPECT_NE(b.dom.find("fit RMSE high"), std::string::npos);
    // Every picture link resolves to a file in qc/, and both analysed eyes have two.
    const std::string img = "<img src=\"";
    int imgs = 0;
    for (const std::size_t at : occurrences(b.dom, img)) {
        const std::size_t begin = at + img.size();
        const std::size_t end = b.dom.find('"', begin);
        ASSERT_NE(end, std::string::npos);
        const std::string src = b.dom.substr(begin, end - begin);
        EXPECT_TRUE(fs::exists(out / "qc" / src)) << src;
        ++imgs;
    }
    EXPECT_EQ(imgs, 4);
    // Row order after sorting by cft_mm follows the CFTs in the eyes' JSON (c_line: 0.1 mm).
    std::vector<std::pair<double, std::size_t>> order;
    for (const char* key : {"a", "b", "c_line"}) {
        const auto j = nlohmann::json::parse(slurp(out / "eyes" / (std::string(key) + ".json")));
        order.emplace_back(j["parameters"]["cft_mm"].get<double>(),
                           b.dom.find(std::string("data-key=\"") + key + "\""));
    }
    ASSERT_NE(order[0].first, order[1].first);
    std::sort(order.begin(), order.end());
    EXPECT_LT(order[0].second, order[1].second);
    EXPECT_LT(order[1].second, order[2].second);

    // A screenshot: a non-empty PNG.
    const fs::path shot = dir / "gallery.png";
    const Browser s = chromium(dir.path(), "file://" + page.string(),
                               "--screenshot='" + shot.string() + "' --window-size=1400,1000");
    ASSERT_EQ(s.exit_code, 0) << s.log;
    EXPECT_TRUE(console_lines(s.log).empty()) << s.log;
    ASSERT_TRUE(fs::exists(shot));
    const std::string png = slurp(shot);
    EXPECT_GT(png.size(), 10000U);  // a 1400 x 1000 page with pictures, far above an empty PNG
    EXPECT_EQ(png.substr(0, 8), std::string("\x89PNG\r\n\x1a\n", 8));
}

TEST(Gallery, MissingOutdirAndEmptyCohort) {
    TempDir dir;
    EXPECT_EQ(run_octshape("gallery " + (dir / "nope").string()).exit_code, 66);
    fs::create_directories(dir / "empty");
    ASSERT_EQ(run_octshape("gallery " + (dir / "empty").string()).exit_code, 0);
    const std::string html = slurp(dir / "empty" / "qc" / "index.html");
    EXPECT_NE(html.find("No failures."), std::string::npos);
    EXPECT_NE(html.find("Eyes (0)"), std::string::npos);
}

}  // namespace
}  // namespace octshape::test
