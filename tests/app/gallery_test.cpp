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
        "timeout 120 chromium --headless --no-sandbox --disable-gpu --disable-quic "
        "--no-first-run --disable-background-networking --disable-component-update "
        "--disable-sync --user-data-dir='" +
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

EXTERNAL_TEST(GalleryBrowser, DetectsConsoleErrorsOnABrokenPage) {
    TempDir dir;
    spit(dir / "bad.html",
          "<!DOCTYPE html><html><head><link rel=\"icon\" href=\"data:,\">"
          "</head><body><script>no_such_function();</script></body></html>");
    const Browser b = chromium(dir.path(), "file://" + (dir / "bad.html").string(), "--dump-dom");
    ASSERT_EQ(b.exit_code, 0) << b.log;
    EXPECT_FALSE(console_lines(b.log).empty()) << b.log;
}

// Slow: analyses two phantoms and starts headless Chromium twice (~7 s alone).
EXTERNAL_TEST(Gallery, PageInHeadlessChromium) {
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
    // Failures are shown by their eye key, reason and exit code, never by a file name; no
    // path of the output directory either (the page is shared: docs/cohort.md).
    EXPECT_NE(b.dom.find("0b0b0b0b0b0b0b0b"), std::string::npos);
    EXPECT_NE(b.dom.find("0d0d0d0d0d0d0d0d"), std::string::npos);
    EXPECT_EQ(b.dom.find(out.string()), std::string::npos);
    EXPECT_EQ(html.find(".vol"), std::string::npos);
    EXPECT_NE(b.dom.find("no such file (exit 66)"), std::string::npos);
    EXPECT_EQ(occurrences(b.dom, "<tr class=\"row failed failure\">").size(), 2U);
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
    EXPECT_EQ(imgs, 6);  // thickness, profiles and B-scan of each analysed eye
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

    // Sorted by QC severity by default: the failures, then the flagged eye, then the rest.
    const std::string page_html = slurp(page);
    const std::size_t first_failure = page_html.find("row failed failure");
    const std::size_t flagged = page_html.find("data-key=\"c_line\"");
    ASSERT_NE(first_failure, std::string::npos);
    ASSERT_NE(flagged, std::string::npos);
    EXPECT_LT(first_failure, flagged);
    EXPECT_LT(flagged, page_html.find("data-key=\"a\""));
    EXPECT_LT(flagged, page_html.find("data-key=\"b\""));

    // The first screen at 1400 x 900: a copy of the page with a probe script that writes the
    // positions of every eye's status, flag, eye, scan-type and parameter cells and of its
    // thumbnails into the DOM once the pictures have loaded.
    const std::string probe = R"(<pre id="probe"></pre><script>
window.addEventListener('load', function () {
  // The layout width is the window's; the first screen is its top 900 pixels (headless
  // Chromium's inner height is the window's less what it reserves, so it is not used).
  var bad = [], n = 0, thumbs = 0, vw = 1400, vh = 900;
  function inside(el, what, whole) {
    var r = el.getBoundingClientRect();
    n++;
    if (r.left < 0 || r.right > vw || r.top < 0 || (whole ? r.bottom : r.top) > vh) {
      bad.push(what + ' ' + JSON.stringify([r.left, r.top, r.right, r.bottom]));
    }
  }
  document.querySelectorAll('#eyes tbody tr.row[data-key]').forEach(function (tr) {
    var k = tr.getAttribute('data-key');
    for (var c = 0; c < 5; c++) inside(tr.cells[c], k + ' cell ' + c, true);
    tr.querySelectorAll('td.param').forEach(function (td) { inside(td, k + ' param', true); });
    tr.nextElementSibling.querySelectorAll('img').forEach(function (img) {
      thumbs++;
      inside(img, k + ' thumbnail', false);
      if (img.getBoundingClientRect().height < 200) bad.push(k + ' thumbnail below 200 px');
    });
  });
  document.getElementById('probe').textContent =
      'width ' + window.innerWidth + ' cells ' + n + ' thumbnails ' + thumbs +
      ' outside [' + bad.join('; ') + ']';
});
</script>
)";
    std::string probed = page_html;
    probed.insert(probed.rfind("</body>"), probe);
    spit(out / "qc" / "probe.html", probed);
    const Browser pb = chromium(dir.path(), "file://" + (out / "qc" / "probe.html").string(),
                                "--dump-dom --window-size=1400,900 --virtual-time-budget=5000");
    ASSERT_EQ(pb.exit_code, 0) << pb.log;
    const std::size_t at = pb.dom.find("<pre id=\"probe\">");
    ASSERT_NE(at, std::string::npos);
    const std::string result = pb.dom.substr(at, pb.dom.find("</pre>", at) - at);
    // Checked: 3 eyes x (5 cells + a cell per parameter column) and the 6 thumbnails; none
    // outside the first screen.
    // Parameter cells: one per parameter column in each of the 5 rows (2 failures, 3 eyes).
    const std::size_t columns = occurrences(page_html, "class=\"num param\"").size() / 5;
    EXPECT_GE(columns, 7U) << columns;  // the 7 macula key parameters at least
    EXPECT_NE(result.find("width 1400 cells " + std::to_string(3 * (5 + columns) + 6) + " "),
              std::string::npos)
        << result << " (" << columns << " parameter columns)";
    EXPECT_NE(result.find("thumbnails 6 "), std::string::npos) << result;
    EXPECT_NE(result.find("outside []"), std::string::npos) << result;

    // A screenshot of the first screen: a non-empty PNG.
    const fs::path shot = dir / "gallery.png";
    const Browser s = chromium(dir.path(), "file://" + page.string(),
                               "--screenshot='" + shot.string() + "' --window-size=1400,900");
    ASSERT_EQ(s.exit_code, 0) << s.log;
    EXPECT_TRUE(console_lines(s.log).empty()) << s.log;
    ASSERT_TRUE(fs::exists(shot));
    const std::string png = slurp(shot);
    EXPECT_GT(png.size(), 10000U);  // a 1400 x 900 page with pictures, far above an empty PNG
    EXPECT_EQ(png.substr(0, 8), std::string("\x89PNG\r\n\x1a\n", 8));
}

TEST(Gallery, MissingOutdirAndNothingToShow) {
    TempDir dir;
    EXPECT_EQ(run_octshape("gallery " + (dir / "nope").string()).exit_code, 66);
    // A folder without results: an error naming it (exit 66, README), and no page.
    fs::create_directories(dir / "empty");
    const RunResult r = run_octshape("gallery " + (dir / "empty").string());
    EXPECT_EQ(r.exit_code, 66);
    EXPECT_NE(r.err.find((dir / "empty").string() + ": nothing to show"), std::string::npos)
        << r.err;
    EXPECT_FALSE(fs::exists(dir / "empty" / "qc" / "index.html"));
}

}  // namespace
}  // namespace octshape::test
