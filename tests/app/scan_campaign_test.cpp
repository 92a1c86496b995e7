// A campaign of semantically hostile exports: files that parse but describe impossible eyes or
// broken acquisitions, made from a small macula and a small ONH phantom by one change each, run
// through `info`, `macula`, `onh --ilm device` and `onh` (level set) with a time limit. Each run
// must end in a success whose CSV holds only finite numbers (or NA), or a clean error: exit
// 65/69, one line on stderr naming the file, no output. Never a crash, a hang or an internal
// error. Prints the table (inputs x commands). The long form (scripts/campaign.sh) adds every
// pair of mutations, left-eye/swollen/overhanging bases and the macula base written as a Topcon
// .fda. The long form with the mesh campaign's inputs is
// tests/mesh/mesh_campaign_test.cpp; the readers' own damage is tests/io.

#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cmath>
#include <cstdlib>
#include <functional>
#include <iomanip>
#include <iostream>
#include <limits>
#include <map>
#include <sstream>

#include "octshape/error.h"
#include "octshape/io/csv.h"
#include "octshape/io/scan_reader.h"
#include "octshape/io/topcon.h"
#include "octshape/io/vol.h"
#include "slow_test.h"
#include "test_paths.h"

namespace octshape::test {
namespace {

constexpr int kTimeLimitSeconds = 120;
constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();


void each_value(io::Scan& s, int line, const std::function<void(float&, int, int)>& f) {
    for (int b = 0; b < s.num_bscans(); ++b) {
        auto& seg = s.bscans[static_cast<std::size_t>(b)].seg;
        if (line >= static_cast<int>(seg.size())) continue;
        auto& v = seg[static_cast<std::size_t>(line)];
        for (int a = 0; a < static_cast<int>(v.size()); ++a) f(v[static_cast<std::size_t>(a)], b, a);
    }
}

struct Mutation {
    std::string name;
    std::function<void(io::Scan&)> apply;
};

std::vector<Mutation> mutations() {
    return {
        {"bm_at_1e6_px", [](io::Scan& s) { each_value(s, 1, [](float& v, int, int) { v = 1e6F; }); }},
        {"ilm_at_9e29_px", [](io::Scan& s) { each_value(s, 0, [](float& v, int, int) { v = 9e29F; }); }},
        {"ilm_below_bm",
         [](io::Scan& s) {
             for (auto& b : s.bscans) std::swap(b.seg[0], b.seg[1]);
         }},
        {"ilm_spikes",
         [](io::Scan& s) {
             each_value(s, 0, [](float& v, int, int a) {
                 if (a % 7 == 0) v -= 400.0F;
             });
         }},
        {"one_valid_ascan",
         [](io::Scan& s) {
             for (int k : {0, 1}) {
                 each_value(s, k, [](float& v, int b, int a) {
                     if (b != 3 || a != 10) v = kNaN;
                 });
             }
         }},
        {"ilm_all_missing", [](io::Scan& s) { each_value(s, 0, [](float& v, int, int) { v = kNaN; }); }},
        {"missing_centre",
         [](io::Scan& s) {
             const int nb = s.num_bscans();
             const int na = s.meta.size_x;
             for (int k : {0, 1}) {
                 each_value(s, k, [&](float& v, int b, int a) {
                     if (std::abs(b - nb / 2) <= nb / 5 && std::abs(a - na / 2) <= na / 5) v = kNaN;
                 });
             }
         }},
        {"unknown_pattern",
         [](io::Scan& s) {
             s.meta.pattern = io::ScanPattern::kUnknown;
             s.meta.scan_pattern_code = 17;
         }},
        {"identical_positions",
         [](io::Scan& s) {
             for (auto& b : s.bscans) {
                 b.start_x_mm = s.bscans[0].start_x_mm;
                 b.start_y_mm = s.bscans[0].start_y_mm;
                 b.end_x_mm = s.bscans[0].end_x_mm;
                 b.end_y_mm = s.bscans[0].end_y_mm;
             }
         }},
        {"shuffled_positions",
         [](io::Scan& s) {
             for (std::size_t b = 0; b + 1 < s.bscans.size(); b += 2) {
                 std::swap(s.bscans[b].start_y_mm, s.bscans[b + 1].start_y_mm);
                 std::swap(s.bscans[b].end_y_mm, s.bscans[b + 1].end_y_mm);
             }
         }},
        {"distance_zero", [](io::Scan& s) { s.meta.distance_mm = 0.0; }},
        {"scale_x_1e-6", [](io::Scan& s) { s.meta.scale_x_mm = 1e-6; }},
        {"scale_z_0.9", [](io::Scan& s) { s.meta.scale_z_mm = 0.9; }},  // a 446 mm deep image
        {"pixels_zero",
         [](io::Scan& s) {
             for (auto& b : s.bscans) std::fill(b.pixels.begin(), b.pixels.end(), 0.0F);
         }},
        {"pixels_nan",
         [](io::Scan& s) {
             for (auto& b : s.bscans) std::fill(b.pixels.begin(), b.pixels.end(), kNaN);
         }},
        {"pixels_1e30",
         [](io::Scan& s) {
             for (auto& b : s.bscans) std::fill(b.pixels.begin(), b.pixels.end(), 1e30F);
         }},
        {"laterality_unknown", [](io::Scan& s) { s.meta.laterality = io::Laterality::kUnknown; }},
    };
}

// A CSV row of a success: every field a finite number, NA, or text that is not a number.
bool csv_is_finite(const std::filesystem::path& csv) {
    if (!std::filesystem::exists(csv)) return false;
    for (const auto& row : io::read_csv_file(csv.string()).rows) {
        for (const std::string& f : row) {
            std::istringstream in(f);
            double v = 0.0;
            if ((in >> v) && in.eof() && !std::isfinite(v)) return false;
            if (f == "nan" || f == "inf" || f == "-inf" || f == "-nan") return false;
        }
    }
    return true;
}

SLOW_TEST(ScanCampaign, HostileExportsGiveCleanErrorsOrFiniteResults) {
    TempDir tmp;
    // The two bases: a small macula volume and a small ONH volume, with pixels.
    const auto macula_vol = tmp / "macula_base.vol";
    const auto onh_vol = tmp / "onh_base.vol";
    ASSERT_EQ(run_octshape("phantom macula --bscans 25 --ascans 128 -o '" + macula_vol.string() +
                           "'").exit_code, 0);
    ASSERT_EQ(run_octshape("phantom onh --bscans 25 --ascans 96 -o '" + onh_vol.string() + "'")
                  .exit_code,
              0);
    struct Base {
        std::string name;
        io::Scan scan;
        std::vector<std::string> commands;
        bool fda = false;  // written as a Topcon .fda (contours only) instead of a .vol
    };
    std::vector<Base> bases = {
        {"macula", io::read_scan(macula_vol.string(), {.pixels = true}),
         {"info", "macula", "onh --ilm device"}},
        {"onh", io::read_scan(onh_vol.string(), {.pixels = true}),
         {"info", "macula --no-type-check", "onh --ilm device", "onh"}},
    };
    // The long form (scripts/campaign.sh, OCTSHAPE_CAMPAIGN_LONG=1): every pair of mutations
    // too, on the two bases and on left-eye, swollen and overhanging variants.
    const bool long_form = std::getenv("OCTSHAPE_CAMPAIGN_LONG") != nullptr;
    std::vector<Mutation> cases = mutations();
    if (long_form) {
        const auto single = mutations();
        for (std::size_t i = 0; i < single.size(); ++i) {
            for (std::size_t j = i + 1; j < single.size(); ++j) {
                cases.push_back({single[i].name + "+" + single[j].name,
                                 [a = single[i].apply, b = single[j].apply](io::Scan& s) {
                                     a(s);
                                     b(s);
                                 }});
            }
        }
        for (const char* variant : {"macula --eye OS", "onh --shape swollen --eye OS",
                                    "onh --shape overhang"}) {
            const std::string kind = std::string(variant).substr(0, std::string(variant).find(' '));
            const auto vol = tmp / ("base_" + std::to_string(bases.size()) + ".vol");
            const std::string sizes = kind == "macula" ? " --bscans 25 --ascans 128"
                                                       : " --bscans 25 --ascans 96";
            ASSERT_EQ(run_octshape("phantom " + std::string(variant) + sizes + " -o '" +
                                   vol.string() + "'")
                          .exit_code,
                      0)
                << variant;
            bases.push_back({kind + std::to_string(bases.size()),
                             io::read_scan(vol.string(), {.pixels = true}),
                             bases[kind == "macula" ? 0 : 1].commands});
        }
        // The macula base through the Topcon reader: the same mutations written as .fda.
        bases.push_back({"macula_fda", bases[0].scan, {"info", "macula"}, true});
    }
    // OCTSHAPE_CAMPAIGN_BASES=name,name: only these bases (e.g. macula_fda), to rerun a part.
    if (const char* only = std::getenv("OCTSHAPE_CAMPAIGN_BASES")) {
        const std::string list = "," + std::string(only) + ",";
        std::erase_if(bases, [&](const Base& b) {
            return list.find("," + b.name + ",") == std::string::npos;
        });
    }
    std::map<std::string, std::map<std::string, int>> table;
    int runs = 0;
    for (const Base& base : bases) {
        for (const Mutation& m : cases) {
            io::Scan s = base.scan;
            m.apply(s);
            const auto path = tmp / (base.name + "_" + m.name + (base.fda ? ".fda" : ".vol"));
            try {
                if (base.fda) {
                    io::write_topcon_file(s, path.string());
                } else {
                    io::write_vol_file(s, path.string());
                }
            } catch (const UsageError& e) {
                // The writers refuse what no .vol (.fda) can hold; the readers' tests cover such
                // files.
                std::cout << path.filename().string() << ": not writable (" << e.what() << ")\n";
                continue;
            }
            for (const std::string& command : base.commands) {
                const auto json = tmp / "out.json";
                const auto csv = tmp / "out.csv";
                std::filesystem::remove(json);
                std::filesystem::remove(csv);
                const bool info = command == "info";
                const std::string args = command + " '" + path.string() + "'" +
                                         (info ? std::string(" --json")
                                               : " -o '" + json.string() + "' --csv '" +
                                                     csv.string() + "'");
                const RunResult o = run_octshape_limited(args, kTimeLimitSeconds);
                ++runs;
                const std::string where = path.filename().string() + " / " + command + ": exit " +
                                          std::to_string(o.exit_code) + ", stderr: " + o.err;
                std::string kind = failure_kind(o.exit_code);
                if (!kind.empty()) {
                    // never acceptable: counted and asserted below
                } else if (o.exit_code == 0) {
                    kind = info || (std::filesystem::exists(json) && csv_is_finite(csv))
                               ? "success"
                               : "impossible success";
                } else {
                    kind = "clean error";
                    EXPECT_TRUE(o.exit_code == 65 || o.exit_code == 69) << where;
                    EXPECT_FALSE(std::filesystem::exists(json)) << where;
                    EXPECT_FALSE(std::filesystem::exists(csv)) << where;
                    // One line naming the file (warnings before it are other lines: count the
                    // error lines).
                    const auto at = o.err.find("octshape: error: ");
                    ASSERT_NE(at, std::string::npos) << where;
                    const std::string line = o.err.substr(at, o.err.find('\n', at) - at);
                    EXPECT_NE(line.find(path.string()), std::string::npos) << where;
                    EXPECT_EQ(o.err.find('\n', at) + 1, o.err.size()) << where;
                }
                ++table[command + (base.fda ? " [.fda]" : "")][kind];
                EXPECT_NE(kind, "hang") << where;
                EXPECT_NE(kind, "crash") << where;
                EXPECT_NE(kind, "internal error") << where;
                EXPECT_NE(kind, "impossible success") << where;
            }
        }
    }
    const std::vector<std::string> kinds = {"crash", "hang", "internal error",
                                            "impossible success", "clean error", "success"};
    std::cout << "scan campaign (" << runs << " runs):\n" << std::left << std::setw(24) << "command";
    for (const auto& k : kinds) std::cout << std::setw(20) << k;
    std::cout << '\n';
    for (const auto& [command, counts] : table) {
        std::cout << std::setw(24) << command;
        for (const auto& k : kinds) {
            const auto it = counts.find(k);
            std::cout << std::setw(20) << (it == counts.end() ? 0 : it->second);
        }
        std::cout << '\n';
    }
}

}  // namespace
}  // namespace octshape::test
