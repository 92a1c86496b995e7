// A campaign of hostile mesh files (OBJ, PLY, OFF, STL, VTP) run through `octshape denoise`,
// `metrics` and `features` with a time limit: no crash, no hang, no internal error, a typed
// error (exit code of the README table) naming the file — and the line for OBJ and OFF — or a
// success whose every written vertex and printed number is finite. Prints the campaign's table.

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <sys/wait.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <iomanip>
#include <iostream>
#include <map>
#include <sstream>
#include <set>
#include <string>
#include <vector>

#include "mesh/mesh_fixtures.h"
#include "octshape/error.h"
#include "octshape/io/mesh_io.h"
#include "test_paths.h"
#include "slow_test.h"

namespace octshape::test {
namespace {

// Every command here takes well under a second on these meshes of at most 320 faces; 60 s only
// tells a hang (the minutes-long all-faces neighbourhood of issue 19) from a slow CI machine.
constexpr int kTimeLimitSeconds = 60;

struct Case {
    std::string file;      // name in the temp dir (its extension picks the reader)
    std::string content;   // bytes
    int expected_exit;     // 0 = success expected, else the documented code
    bool line_in_message;  // the error names a line (OBJ, OFF)
};

std::string obj_of(const TestMesh& m, const std::string& face_suffix = "") {
    std::ostringstream s;
    s << std::setprecision(17);
    for (Eigen::Index i = 0; i < m.V.rows(); ++i) {
        s << "v " << m.V(i, 0) << ' ' << m.V(i, 1) << ' ' << m.V(i, 2) << '\n';
    }
    for (Eigen::Index f = 0; f < m.F.rows(); ++f) {
        s << "f";
        for (int k = 0; k < 3; ++k) s << ' ' << m.F(f, k) + 1 << face_suffix;
        s << '\n';
    }
    return s.str();
}

// The OBJ of `m` with the coordinate text of vertex 5's x replaced by `x`.
std::string obj_with_x(const TestMesh& m, const std::string& x) {
    std::string text = obj_of(m);
    std::size_t line = 0;
    for (int i = 0; i < 5; ++i) line = text.find('\n', line) + 1;
    const std::size_t end = text.find(' ', line + 2);
    return text.substr(0, line + 2) + x + text.substr(end);
}

std::string off_of(const TestMesh& m) {
    std::ostringstream s;
    io::write_off(s, m.V, m.F);
    return s.str();
}

std::vector<Case> hostile_cases(const TestMesh& m) {
    const std::string ascii_ply_head =
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
        "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n";
    TestMesh outlier = m;
    outlier.V(5, 0) = 1e6;  // finite and within ±1e50, but c_a grows ~1000-fold
    std::string binary_stl(80, ' ');
    binary_stl += std::string("\xff\xff\xff\x0f", 4);  // 268 million triangles announced
    binary_stl += std::string(50, '\0');
    return {
        {"texture_no_vt.obj", obj_of(m, "/1"), 0, false},  // VTK segfaulted here
        {"texture_normal.obj", obj_of(m, "//1"), 0, false},
        {"nan.obj", obj_with_x(m, "nan"), 65, true},
        {"inf.obj", obj_with_x(m, "-inf"), 65, true},
        {"e400.obj", obj_with_x(m, "1e400"), 65, true},
        {"e300.obj", obj_with_x(m, "1e300"), 65, true},
        {"outlier.obj", obj_of(outlier), 65, false},  // denoise/features: the neighbourhood bound
        {"empty.obj", "", 65, false},
        {"no_vertex.obj", "f 1 2 3\n", 65, true},
        {"two_coords.obj", "v 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", 65, true},
        {"repeat.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 1 2\n", 65, true},
        // Faces of no area only: no surface, no normals to filter or compare (refused since
        // the message test; a mesh with some faces of area keeps its degenerate ones).
        {"collinear.obj", "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n", 65, false},
        {"collapsed.obj", "v 0 0 0\nv 0 0 0\nv 0 0 0\nv 0 0 0\nf 1 2 3\nf 1 3 4\n", 65, false},
        {"out_of_range.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 99\n", 65, true},
        {"negative_out.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -4\n", 65, true},
        {"huge_index.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 99999999999999999999\n", 65, true},
        {"empty.off", "", 65, false},
        {"nan.off", "OFF\n3 1 0\n0 0 0\nnan 0 0\n0 1 0\n3 0 1 2\n", 65, true},
        {"e300.off", "OFF\n3 1 0\n0 0 0\n1e300 0 0\n0 1 0\n3 0 1 2\n", 65, true},
        {"huge_counts.off", "OFF\n999999999999 999999999999 0\n0 0 0\n", 65, true},
        {"out_of_range.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 9\n", 65, true},
        {"degenerate.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 0 1\n", 65, true},
        {"outlier.off", off_of(outlier), 65, false},
        {"empty.ply", "", 65, false},
        {"nan.ply", ascii_ply_head + "0 0 0\nnan 0 0\n0 1 0\n3 0 1 2\n", 65, false},
        {"out_of_range.ply", ascii_ply_head + "0 0 0\n1 0 0\n0 1 0\n3 0 1 9\n", 65, false},
        {"huge_counts.ply",
         "ply\nformat binary_little_endian 1.0\nelement vertex 4000000000\nproperty float x\n"
         "property float y\nproperty float z\nelement face 4000000000\n"
         "property list uchar int vertex_indices\nend_header\n" + std::string(64, '\0'),
         65, false},
        {"empty.stl", "", 65, false},
        {"huge_count.stl", binary_stl, 65, false},
        {"nan.stl",
         "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex nan 0 0\nvertex 0 1 0\n"
         "endloop\nendfacet\nendsolid x\n",
         65, false},
        {"empty.vtp", "", 65, false},
        {"huge_counts.vtp",
         "<?xml version=\"1.0\"?>\n<VTKFile type=\"PolyData\" version=\"0.1\">\n<PolyData>\n"
         "<Piece NumberOfPoints=\"4000000000\" NumberOfPolys=\"4000000000\">\n<Points>\n"
         "<DataArray type=\"Float32\" NumberOfComponents=\"3\" format=\"ascii\">0 0 0"
         "</DataArray>\n</Points>\n</Piece>\n</PolyData>\n</VTKFile>\n",
         65, false},
        {"nan.vtp",
         "<?xml version=\"1.0\"?>\n<VTKFile type=\"PolyData\" version=\"0.1\">\n<PolyData>\n"
         "<Piece NumberOfPoints=\"3\" NumberOfPolys=\"1\">\n<Points>\n"
         "<DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">"
         "0 0 0 nan 0 0 0 1 0</DataArray>\n</Points>\n<Polys>\n"
         "<DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">0 1 2</DataArray>\n"
         "<DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">3</DataArray>\n"
         "</Polys>\n</Piece>\n</PolyData>\n</VTKFile>\n",
         65, false},
    };
}


// Whether the JSON on stdout holds a non-finite number (nlohmann writes one as null) or does
// not parse. Empty stdout (denoise, features without --json) holds none.
bool has_non_finite_json(const std::string& s) {
    if (s.empty()) return false;
    const auto j = nlohmann::json::parse(s, nullptr, false);
    if (j.is_discarded()) return true;
    bool bad = false;
    // A NaN or inf number is written as null, so a null is non-finite, except where a path
    // field is null by design (the input paths, shown only with --record-paths).
    static const std::set<std::string> kPathFields{"mesh", "reference", "input", "output",
                                                   "path", "file"};
    const auto visit = [&bad](const auto& self, const nlohmann::json& v) -> void {
        if (v.is_null()) bad = true;
        if (v.is_number_float() && !std::isfinite(v.get<double>())) bad = true;
        if (v.is_object()) {
            for (const auto& [key, item] : v.items()) {
                if (item.is_null() && kPathFields.count(key) != 0) continue;
                self(self, item);
            }
        } else if (v.is_array()) {
            for (const auto& item : v) self(self, item);
        }
    };
    visit(visit, j);
    return bad;
}

// Slow: runs octshape 99 times (33 files x denoise, metrics, features): ~6 s alone.
SLOW_TEST(MeshCampaign, HostileFilesGiveTypedErrorsOrFiniteResults) {
    TempDir tmp;
    const TestMesh m = with_noise(icosphere(2), 0.01);  // 320 faces: bound 80 faces a disk
    io::write_mesh(tmp / "reference.off", m.V, m.F);
    const std::vector<Case> cases = hostile_cases(m);
    const std::vector<std::string> commands = {"denoise", "metrics", "features"};
    // Table: per command, how many runs fell in each class.
    std::map<std::string, std::map<std::string, int>> table;
    for (const Case& c : cases) {
        const auto path = tmp / c.file;
        spit(path, c.content);
        for (const std::string& command : commands) {
            const auto output = tmp / ("result_" + command + (command == "denoise" ? ".off"
                                                                                    : ".vtp"));
            std::filesystem::remove(output);
            std::string args = command + " '" + path.string() + "'";
            if (command == "metrics") {
                args += " --json --reference '" + (tmp / "reference.off").string() + "'";
            }
            if (command != "metrics") args += " -o '" + output.string() + "'";
            const RunResult o = run_octshape_limited(args, kTimeLimitSeconds);
            const std::string where = c.file + " / " + command + ": exit " +
                                      std::to_string(o.exit_code) + ", stderr: " + o.err;
            std::string kind = failure_kind(o.exit_code);
            if (!kind.empty()) {
                // never acceptable: counted and asserted below
            } else if (o.exit_code == 0) {
                bool finite = !has_non_finite_json(o.out);
                if (command != "metrics") {
                    // What was written must read back finite (the reader refuses NaN and inf:
                    // a refusal here is an impossible success too).
                    try {
                        finite = finite && io::read_mesh(output).V.allFinite();
                    } catch (const InputError&) {
                        finite = false;
                    }
                }
                kind = finite ? "success" : "impossible success";
            } else {
                kind = "clean error";
                EXPECT_FALSE(std::filesystem::exists(output)) << where;
                // One line, naming the file (and the line for OBJ syntax errors).
                EXPECT_EQ(std::count(o.err.begin(), o.err.end(), '\n'), 1) << where;
                EXPECT_NE(o.err.find(path.string()), std::string::npos) << where;
                if (c.line_in_message) {
                    EXPECT_NE(o.err.find(": line "), std::string::npos) << where;
                }
            }
            ++table[command][kind];
            EXPECT_NE(kind, "hang") << where;
            EXPECT_NE(kind, "crash") << where;
            EXPECT_NE(kind, "internal error") << where;
            EXPECT_NE(kind, "impossible success") << where;
            // The outlier reads (it is finite and in range) and metrics measures it; denoise and
            // features refuse its neighbourhoods.
            const int expected =
                (c.file.starts_with("outlier") && command == "metrics") ? 0 : c.expected_exit;
            EXPECT_EQ(o.exit_code, expected) << where;
        }
    }
    std::cout << "mesh campaign (" << cases.size() << " inputs):\n";
    std::cout << std::left << std::setw(10) << "command";
    const std::vector<std::string> kinds = {"crash", "hang", "internal error",
                                            "impossible success", "clean error", "success"};
    for (const auto& k : kinds) std::cout << std::setw(20) << k;
    std::cout << '\n';
    for (const auto& command : commands) {
        std::cout << std::setw(10) << command;
        for (const auto& k : kinds) std::cout << std::setw(20) << table[command][k];
        std::cout << '\n';
    }
}

}  // namespace
}  // namespace octshape::test
