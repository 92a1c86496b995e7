// The mesh commands' provenance (docs/outputs.md, "Provenance"): `denoise --json`, `metrics
// --json`, `meanshape` and the meshes written by `denoise`, `features` and `meanshape` carry the
// one provenance block: version, source revision, every input by its SHA-256 (computed here by
// coreutils' sha256sum, independently of octshape's own hashing) and every effective option,
// the code defaults included (compared with the library's own default values).

#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>

#include "mesh/mesh_fixtures.h"
#include "octshape/io/mesh_io.h"
#include "octshape/io/registration.h"
#include "octshape/mesh/rofi.h"
#include "octshape/version.h"
#include "test_paths.h"

namespace octshape {
namespace {

using nlohmann::json;
namespace fs = std::filesystem;

// Appended piece by piece: GCC 12 warns (-Wrestrict, a false positive) on "'" + string.
std::string q(const fs::path& p) {
    std::string out = "'";
    out += p.string();
    out += '\'';
    return out;
}

// SHA-256 of a file by coreutils (not by the code under test).
std::string sha256sum(const fs::path& p) {
    const std::string cmd = "sha256sum " + q(p);
    FILE* f = ::popen(cmd.c_str(), "r");
    if (f == nullptr) return "popen failed";
    char buf[256] = {};
    const std::size_t n = std::fread(buf, 1, sizeof buf - 1, f);
    ::pclose(f);
    const std::string out(buf, n);
    return out.substr(0, out.find(' '));
}

// The revision `octshape --version` prints: "octshape V (revision R[, ...]; ...)".
std::string version_revision() {
    const auto v = test::run_octshape("--version");
    const std::size_t at = v.out.find(" (revision ");
    if (at == std::string::npos) return "no revision in --version";
    const std::size_t from = at + 11;
    return v.out.substr(from, v.out.find_first_of(",;", from) - from);
}

// The software identity, the command and the inputs (by SHA-256 and role, no path) of a block.
void expect_identity(const json& p, const std::string& command,
                     const std::vector<fs::path>& inputs, const std::string& revision) {
    ASSERT_TRUE(p.is_object()) << p.dump();
    EXPECT_EQ(p["version"], kVersion);
    EXPECT_EQ(p["revision"], revision);
    const bool hex12 = revision.size() == 12 &&
                       revision.find_first_not_of("0123456789abcdef") == std::string::npos;
    EXPECT_TRUE(hex12 || revision == "unknown") << revision;
    for (const char* k : {"modified", "build_type"}) EXPECT_TRUE(p[k].is_string()) << k;
    EXPECT_EQ(p["command"], command);
    ASSERT_EQ(p["inputs"].size(), inputs.size()) << p.dump();
    for (std::size_t i = 0; i < inputs.size(); ++i) {
        EXPECT_EQ(p["inputs"][i]["sha256"], sha256sum(inputs[i])) << i;
        EXPECT_FALSE(p["inputs"][i].contains("path")) << "a path without --record-paths";
    }
}

// The provenance line of a written mesh is the JSON's block without the run's time.
void expect_mesh_line_is_block(const fs::path& mesh_file, json block) {
    const io::MeshData m = io::read_mesh(mesh_file);
    ASSERT_FALSE(m.provenance.empty()) << mesh_file;
    block.erase("utc");
    block.erase("seconds");
    EXPECT_EQ(json::parse(m.provenance), block) << mesh_file;
}

TEST(Provenance, MeshCommandsCarryVersionRevisionInputHashesAndEveryEffectiveOption) {
    const test::TempDir dir;
    const fs::path noisy = dir / "noisy.ply";
    const fs::path clean = dir / "clean.ply";
    const auto sphere = test::icosphere(2);
    io::write_mesh(clean, sphere.V, sphere.F);
    const auto n = test::with_noise(sphere, 0.01);
    io::write_mesh(noisy, n.V, n.F);
    const std::string revision = version_revision();

    // denoise with one explicit parameter: the others are the library's defaults.
    const fs::path out = dir / "out.ply";
    const auto d = test::run_octshape("-q denoise " + q(noisy) + " -o " + q(out) +
                                      " --method rofi --sigma-s 0.4 -p 3 --json");
    ASSERT_EQ(d.exit_code, 0) << d.err;
    const json dj = json::parse(d.out);
    EXPECT_FALSE(dj.contains("software"));
    const json& dp = dj["provenance"];
    expect_identity(dp, "denoise", {noisy}, revision);
    EXPECT_TRUE(dp["utc"].is_string());
    const mesh::RofiParams def;
    const json& o = dp["options"];
    EXPECT_EQ(o["method"], "rofi");
    EXPECT_EQ(o["auto"], false);
    EXPECT_EQ(o["threads"], 1);
    const json& pr = o["parameters"];
    EXPECT_EQ(pr["sigma_s"], 0.4);
    EXPECT_EQ(pr["iterations"], 3);
    EXPECT_EQ(pr["lambda_i"], def.lambda_i);
    EXPECT_EQ(pr["lambda_decay"], def.lambda_decay);
    EXPECT_EQ(pr["radius_factor"], def.radius_factor);
    EXPECT_EQ(pr["sigma_c_factor"], def.sigma_c_factor);
    EXPECT_EQ(pr["similarity"], "tukey");
    EXPECT_EQ(pr["repair_folds"], def.repair_folds);
    EXPECT_EQ(pr["fix_boundary"], def.fix_boundary);
    EXPECT_EQ(pr["stop"], "none");  // an explicit -p runs exactly that many
    // The radius and closeness width in mesh units, which the factors gave on this mesh.
    EXPECT_GT(pr["radius_mm"].get<double>(), 0.0);
    EXPECT_GT(pr["sigma_c_mm"].get<double>(), 0.0);
    expect_mesh_line_is_block(out, dp);

    // metrics: three inputs, each by its role.
    const auto m = test::run_octshape("-q metrics " + q(out) + " --reference " + q(clean) +
                                      " --input " + q(noisy) + " --json");
    ASSERT_EQ(m.exit_code, 0) << m.err;
    const json mj = json::parse(m.out);
    EXPECT_FALSE(mj.contains("software"));
    expect_identity(mj["provenance"], "metrics", {out, clean, noisy}, revision);
    EXPECT_EQ(mj["provenance"]["inputs"][0]["role"], "mesh");
    EXPECT_EQ(mj["provenance"]["inputs"][1]["role"], "reference");
    EXPECT_EQ(mj["provenance"]["inputs"][2]["role"], "input");
    EXPECT_EQ(mj["provenance"]["options"]["input"], true);

    // features: no JSON on stdout; the block is in the mesh, with the radius it used.
    const fs::path feat = dir / "features.vtp";
    const auto f = test::run_octshape("-q features " + q(noisy) + " -o " + q(feat));
    ASSERT_EQ(f.exit_code, 0) << f.err;
    const json fp = json::parse(io::read_mesh(feat).provenance);
    expect_identity(fp, "features", {noisy}, revision);
    EXPECT_GT(fp["options"]["radius_mm"].get<double>(), 0.0);  // default 2 c_a, resolved
    EXPECT_EQ(fp["options"]["threads"], 1);
    EXPECT_FALSE(fp.contains("utc"));  // a re-run writes the same mesh byte for byte

    // meanshape: the ICP settings, the defaults the command line does not expose included.
    const fs::path mean = dir / "mean.vtp";
    const auto s = test::run_octshape("-q meanshape " + q(clean) + " " + q(noisy) + " -o " +
                                      q(mean));
    ASSERT_EQ(s.exit_code, 0) << s.err;
    const json sj = json::parse(s.out);
    EXPECT_FALSE(sj.contains("software"));
    const json& sp = sj["provenance"];
    expect_identity(sp, "meanshape", {clean, noisy}, revision);
    const io::IcpParams icp;
    EXPECT_EQ(sp["options"]["icp_max_iterations"], icp.max_iterations);
    EXPECT_EQ(sp["options"]["icp_refine_iterations"], icp.refine_iterations);
    EXPECT_EQ(sp["options"]["icp_tolerance"], icp.tolerance);
    EXPECT_EQ(sp["options"]["icp_max_landmarks"], icp.max_landmarks);
    EXPECT_EQ(sp["options"]["icp_match_centroids"], icp.match_centroids);
    expect_mesh_line_is_block(mean, sp);

    // --record-paths adds each input's path to its entry, and nothing else changes.
    const auto r = test::run_octshape("-q metrics " + q(out) + " --reference " + q(clean) +
                                      " --json --record-paths");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const json rp = json::parse(r.out)["provenance"];
    EXPECT_EQ(rp["inputs"][0]["path"], out.string());
    EXPECT_EQ(rp["inputs"][1]["path"], clean.string());
}

}  // namespace
}  // namespace octshape
