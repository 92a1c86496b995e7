// Point-set files (io/pointset_io.h) and `octshape denoise --method pointset`.

#include "octshape/io/pointset_io.h"
#include "octshape/io/sha256.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <fstream>
#include <random>
#include <sstream>

#include "octshape/error.h"
#include "test_paths.h"

namespace octshape::test {
namespace {

mesh::Vertices some_points() {
    mesh::Vertices P(5, 3);
    P << 0.0, 0.0, 0.0, 1.5, -2.0, 0.25, 1e-7, 3.0, -4.0, 0.1, 0.2, 0.3, -1.0, 2.0, 1.0 / 3.0;
    return P;
}

TEST(PointSetIo, XyzRoundTripIsExactAndIgnoresExtraColumns) {
    const mesh::Vertices P = some_points();
    std::stringstream ss;
    mesh::Vertices N = P;
    N.setConstant(0.5);
    io::write_xyz(ss, P, &N);  // x y z nx ny nz: the normals are extra columns
    EXPECT_EQ(io::read_xyz(ss, "mem"), P);
    std::istringstream with_comments("# header\n\n1 2 3\r\n  +4 5e-1 -6 # tail\n");
    const mesh::Vertices Q = io::read_xyz(with_comments, "mem");
    ASSERT_EQ(Q.rows(), 2);
    EXPECT_EQ(Q(1, 0), 4.0);
    EXPECT_EQ(Q(1, 1), 0.5);
}

TEST(PointSetIo, BadXyzGivesTypedErrorsWithOffsets) {
    std::istringstream two("1 2 3\n4 5\n");
    try {
        (void)io::read_xyz(two, "two.xyz");
        FAIL() << "a line with two numbers was accepted";
    } catch (const InputError& e) {
        EXPECT_EQ(e.kind(), InputError::Kind::kCorrupt);
        EXPECT_EQ(e.offset(), 6u);  // the start of the second line
    }
    std::istringstream word("1 2 x\n");
    EXPECT_THROW((void)io::read_xyz(word, "w.xyz"), InputError);
    std::istringstream nan("1 2 nan\n");
    EXPECT_THROW((void)io::read_xyz(nan, "n.xyz"), InputError);
    std::istringstream empty("# nothing\n");
    EXPECT_THROW((void)io::read_xyz(empty, "e.xyz"), InputError);
}

TEST(PointSetIo, FilesRoundTripThroughEveryFormat) {
    const TempDir dir;
    const mesh::Vertices P = some_points();
    for (const char* name : {"p.xyz", "p.txt", "p.ply", "p.obj"}) {
        io::write_point_set(dir / name, P, &P);
        const mesh::Vertices Q = io::read_point_set(dir / name);
        ASSERT_EQ(Q.rows(), P.rows()) << name;
        // PLY goes through VTK's reader, which stores single precision.
        EXPECT_LT((Q - P).cwiseAbs().maxCoeff(), 1e-6) << name;
    }
    EXPECT_THROW(io::write_point_set(dir / "p.stl", P), UsageError);
    EXPECT_THROW((void)io::read_point_set(dir / "missing.xyz"), InputError);
}

TEST(PointSetIo, VerticesOnlyAsciiPlyIsRead) {
    const TempDir dir;
    std::ofstream(dir / "v.ply") << "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n"
                                    "property float y\nproperty float z\nend_header\n"
                                    "0 0 0\n1 0 0\n0 1 2.5\n";
    const mesh::Vertices Q = io::read_point_set(dir / "v.ply");
    ASSERT_EQ(Q.rows(), 3);
    EXPECT_EQ(Q(2, 2), 2.5);
}

TEST(PointSetIo, DenoiseCommandRunsThePointSetMethod) {
    const TempDir dir;
    // A noisy sample of the plane z = 0.
    std::mt19937 rng(3);
    std::normal_distribution<double> gauss(0.0, 0.005);
    mesh::Vertices P(900, 3);
    for (int i = 0; i < 900; ++i) P.row(i) << (i % 30) * 0.03, (i / 30) * 0.03, gauss(rng);
    io::write_point_set(dir / "in.xyz", P);
    const RunResult r = run_octshape("denoise " + (dir / "in.xyz").string() + " -o " +
                                     (dir / "out.ply").string() +
                                     " --method pointset --json -p 10");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const auto j = nlohmann::json::parse(r.out);
    EXPECT_EQ(j.at("points"), 900);
    EXPECT_EQ(j.at("parameters").at("iterations"), 10);
    const mesh::Vertices Q = io::read_point_set(dir / "out.ply");
    ASSERT_EQ(Q.rows(), 900);
    EXPECT_LT(Q.col(2).cwiseAbs().mean(), P.col(2).cwiseAbs().mean());
    EXPECT_EQ(j.at("parameters").at("normals"), "pca");
    // The shifted normals are chosen by --normals and reported; as denoisers they must also
    // bring the points closer to the plane.
    const RunResult shifted = run_octshape("denoise " + (dir / "in.xyz").string() + " -o " +
                                           (dir / "shifted.xyz").string() +
                                           " --method pointset --normals shifted --json -p 10");
    ASSERT_EQ(shifted.exit_code, 0) << shifted.err;
    EXPECT_EQ(nlohmann::json::parse(shifted.out).at("parameters").at("normals"), "shifted");
    const mesh::Vertices S = io::read_point_set(dir / "shifted.xyz");
    ASSERT_EQ(S.rows(), 900);
    // Both outputs carry their provenance (a PLY header comment, an XYZ comment line that the
    // reader skips): the command, the input's SHA-256, the options.
    for (const char* out : {"out.ply", "shifted.xyz"}) {
        const std::string text = slurp(dir / out);
        const std::string key = "octshape_provenance ";
        const auto at = text.find(key);
        ASSERT_NE(at, std::string::npos) << out;
        const auto line = text.substr(at + key.size(), text.find('\n', at) - at - key.size());
        const auto prov = nlohmann::json::parse(line);
        EXPECT_EQ(prov.at("command"), "denoise") << out;
        EXPECT_EQ(prov.at("inputs")[0].at("sha256").get<std::string>(),
                  io::sha256_file((dir / "in.xyz").string()));
        EXPECT_EQ(prov.at("options").at("parameters").at("iterations"), 10);
    }
    EXPECT_LT(S.col(2).cwiseAbs().mean(), P.col(2).cwiseAbs().mean());
    // The edge snapping is on by default and reported; a plane has one face, so it moves no
    // point and --no-edge-snap gives the same output.
    EXPECT_EQ(j.at("parameters").at("snap_edges"), true);
    EXPECT_EQ(j.at("snapped_points"), 0);
    const RunResult unsnapped = run_octshape("denoise " + (dir / "in.xyz").string() + " -o " +
                                             (dir / "unsnapped.ply").string() +
                                             " --method pointset --no-edge-snap --json -p 10");
    ASSERT_EQ(unsnapped.exit_code, 0) << unsnapped.err;
    EXPECT_EQ(nlohmann::json::parse(unsnapped.out).at("parameters").at("snap_edges"), false);
    EXPECT_EQ(io::read_point_set(dir / "unsnapped.ply"), Q);
    EXPECT_EQ(run_octshape("denoise " + (dir / "in.xyz").string() + " -o " +
                           (dir / "o.ply").string() + " --method envt --no-edge-snap")
                  .exit_code,
              64);
    // --normals belongs to the point-set method.
    EXPECT_EQ(run_octshape("denoise " + (dir / "in.xyz").string() + " -o " +
                           (dir / "o.ply").string() + " --method envt --normals shifted")
                  .exit_code,
              64);
    // Mesh-only options are usage errors with the point-set method.
    EXPECT_EQ(run_octshape("denoise " + (dir / "in.xyz").string() + " -o " +
                           (dir / "o.xyz").string() + " --method pointset --sigma-s 0.3")
                  .exit_code,
              64);
}

}  // namespace
}  // namespace octshape::test
