// Mesh files (io/mesh_io.h): round trips in every format, face scalars, bad files.

#include "octshape/io/mesh_io.h"
#include "octshape/io/sha256.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <fstream>
#include <sstream>

#include "mesh/mesh_fixtures.h"
#include "octshape/error.h"
#include "octshape/mesh/metrics.h"
#include "test_paths.h"

namespace octshape::test {
namespace {

std::string slurp(const std::filesystem::path& p) {
    std::ifstream in(p, std::ios::binary);
    std::ostringstream ss;
    ss << in.rdbuf();
    return ss.str();
}

void write_text(const std::filesystem::path& p, const std::string& text) {
    std::ofstream(p, std::ios::binary) << text;
}

TEST(MeshIo, RoundTripInEveryFormatKeepsVerticesAndFaces) {
    TempDir tmp;
    const auto m = with_noise(icosphere(2), 0.01);
    for (const std::string ext : {".off", ".ply", ".vtp", ".obj", ".stl"}) {
        const auto path = tmp / ("m" + ext);
        io::write_mesh(path, m.V, m.F);
        const io::MeshData back = io::read_mesh(path);
        ASSERT_EQ(back.F.rows(), m.F.rows()) << ext;
        ASSERT_EQ(back.V.rows(), m.V.rows()) << ext;
        // OFF and VTP keep doubles; PLY is read through VTK in single precision, OBJ and STL
        // are written by VTK in single precision (relative 6e-8 of coordinates ≤ 1.1).
        const double tol = (ext == ".off" || ext == ".vtp") ? 0.0 : 2e-7;
        if (ext == ".stl") {
            // STL has no shared vertices: the reader merges equal points, in its own order.
            for (Eigen::Index f = 0; f < m.F.rows(); ++f) {
                for (int k = 0; k < 3; ++k) {
                    EXPECT_LE((back.V.row(back.F(f, k)) - m.V.row(m.F(f, k))).cwiseAbs().maxCoeff(),
                              tol);
                }
            }
        } else {
            EXPECT_EQ(back.F, m.F) << ext;
            EXPECT_LE((back.V - m.V).cwiseAbs().maxCoeff(), tol) << ext;
        }
        // Written under a temporary name and renamed: no temporary file is left behind.
        for (const auto& entry : std::filesystem::directory_iterator(path.parent_path())) {
            EXPECT_EQ(entry.path().filename().string().find(".tmp-"), std::string::npos)
                << entry.path();
        }
    }
}

TEST(MeshIo, ProvenanceIsWrittenAndReadBack) {
    // PLY, OFF, OBJ (a comment line) and VTP carry the line and read_mesh returns it (with a
    // JSON-like text: quotes, braces, spaces); binary STL has no room for it. The geometry reads back as without it.
    TempDir tmp;
    const auto m = with_noise(icosphere(1), 0.01);
    const std::string line = R"({"version": "test", "command": "denoise", "inputs": [{"sha256": "ab"}]})";
    for (const std::string ext : {".ply", ".off", ".vtp", ".obj", ".stl"}) {
        const auto path = tmp / ("p" + ext);
        io::write_mesh(path, m.V, m.F, {}, line);
        const io::MeshData back = io::read_mesh(path);
        EXPECT_EQ(back.F.rows(), m.F.rows()) << ext;
        const bool carried = ext != ".stl";
        EXPECT_EQ(back.provenance, carried ? line : std::string()) << ext;
        if (ext == ".obj") {
            EXPECT_NE(slurp(path).find("\n# octshape_provenance " + line + "\n"),
                      std::string::npos);
        }
    }
    // Without one, nothing is read back; a line break is refused before anything is written.
    io::write_mesh(tmp / "none.ply", m.V, m.F);
    EXPECT_EQ(io::read_mesh(tmp / "none.ply").provenance, "");
    EXPECT_THROW(io::write_mesh(tmp / "two.ply", m.V, m.F, {}, "a\nb"), UsageError);
    EXPECT_FALSE(std::filesystem::exists(tmp / "two.ply"));
    // Per-vertex scalars take it too.
    io::write_mesh_vertex_scalars(tmp / "v.vtp", m.V, m.F,
                                  {{"sd_mm", Eigen::VectorXd::Zero(m.V.rows())}}, line);
    EXPECT_EQ(io::read_mesh(tmp / "v.vtp").provenance, line);
}

TEST(MeshIo, FaceScalarsAreWrittenToVtpAndPly) {
    TempDir tmp;
    const auto m = cube(2);
    Eigen::VectorXd s(m.F.rows());
    for (Eigen::Index f = 0; f < s.size(); ++f) s(f) = 0.25 * static_cast<double>(f);
    io::write_mesh(tmp / "s.ply", m.V, m.F, {{"feature_strength", s}});
    const std::string header = slurp(tmp / "s.ply");
    EXPECT_NE(header.find("element face 48\nproperty list uchar int vertex_indices\n"
                          "property double feature_strength\n"),
              std::string::npos);
    io::write_mesh(tmp / "s.vtp", m.V, m.F, {{"feature_strength", s}});
    const std::string xml = slurp(tmp / "s.vtp");
    EXPECT_NE(xml.find("<CellData"), std::string::npos);
    EXPECT_NE(xml.find("Name=\"feature_strength\""), std::string::npos);
    EXPECT_THROW(io::write_mesh(tmp / "bad.vtp", m.V, m.F, {{"x", Eigen::VectorXd(3)}}),
                 UsageError);
}

TEST(MeshIo, OffPolygonsAreFanTriangulatedAndCommentsSkipped) {
    std::istringstream in("OFF\n# a square\n4 1 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3 255 0 0\n");
    const io::MeshData m = io::read_off(in, "square.off");
    ASSERT_EQ(m.F.rows(), 2);
    EXPECT_EQ(m.F.row(0), Eigen::RowVector3i(0, 1, 2));
    EXPECT_EQ(m.F.row(1), Eigen::RowVector3i(0, 2, 3));
}

TEST(MeshIo, EveryTruncationOfAnOffFileIsATypedError) {
    std::ostringstream out;
    const auto m = plane_grid(2);
    io::write_off(out, m.V, m.F);
    const std::string good = out.str();
    // Cutting inside the last number still parses (a shorter number); cut before the last
    // face's last index instead, and at every earlier byte.
    const std::size_t last = good.find_last_of(' ');
    for (std::size_t n = 0; n <= last; ++n) {
        std::istringstream in(good.substr(0, n));
        EXPECT_THROW((void)io::read_off(in, "cut.off"), InputError) << n;
    }
}

TEST(MeshIo, HostileOffCountsAreRejectedBeforeAllocating) {
    std::istringstream in("OFF\n2000000000 2000000000 0\n0 0 0\n");
    try {
        (void)io::read_off(in, "huge.off");
        FAIL();
    } catch (const InputError& e) {
        EXPECT_EQ(e.kind(), InputError::Kind::kCorrupt);
        EXPECT_EQ(e.path(), "huge.off");
        EXPECT_TRUE(e.offset().has_value());
    }
    std::istringstream bad_index("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n");
    EXPECT_THROW((void)io::read_off(bad_index, "index.off"), InputError);
}

TEST(MeshIo, ObjCornersWithTextureAndNormalIndicesAndNegativeIndicesShareVertices) {
    // A quad as v/vt/vn, a triangle as v//vn with relative indices, texture indices that name
    // no vt line (VTK's reader crashed on them): the vertex indices alone give the faces.
    std::istringstream in(
        "# a comment\nmtllib x.mtl\no quad\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
        "vn 0 0 1\nusemtl m\ns off\nf 1/7/1 2/7/1 3/7/1 4/7/1\n"
        "v 0.5 0.5 1.25e-3\nf -5//1 -4//1 -1//1  # trailing comment\r\nl 1 2\n");
    const io::MeshData m = io::read_obj(in, "q.obj");
    ASSERT_EQ(m.V.rows(), 5);
    ASSERT_EQ(m.F.rows(), 3);
    mesh::Faces expected(3, 3);
    expected << 0, 1, 2, 0, 2, 3, 0, 1, 4;  // the quad as a fan from its first corner
    EXPECT_EQ(m.F, expected);
    EXPECT_EQ(m.V(4, 2), 1.25e-3);  // parsed as a double: the same bits as the literal
    // Doubles are kept (VTK stored float32, which rounds 0.1 to 0.100000001490116).
    std::istringstream tenth("v 0.1 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    EXPECT_EQ(io::read_obj(tenth, "t.obj").V(0, 0), 0.1);
}

TEST(MeshIo, ObjErrorsNameTheLine) {
    const auto expect_line = [](const std::string& text, const std::string& line) {
        std::istringstream in(text);
        try {
            (void)io::read_obj(in, "bad.obj");
            FAIL() << text;
        } catch (const InputError& e) {
            EXPECT_EQ(e.kind(), InputError::Kind::kCorrupt) << e.what();
            EXPECT_EQ(e.path(), "bad.obj");
            EXPECT_NE(std::string(e.what()).find("bad.obj: corrupt: line " + line + ": "),
                      std::string::npos)
                << e.what();
        }
    };
    const std::string tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
    for (const std::string x : {"nan", "inf", "-inf", "1e400", "1e300", "-2e50", "0x1", "1.5.2"}) {
        expect_line("v 0 0 0\nv " + x + " 0 0\nv 0 1 0\nf 1 2 3\n", "2");
    }
    expect_line(tri + "v 1 2\nf 1 2 3\n", "4");
    expect_line(tri + "f 1 2\n", "4");
    expect_line(tri + "f 1 2 4\n", "4");          // checked once every vertex is read
    expect_line(tri + "f 1 2 0\n", "4");          // OBJ counts from 1
    expect_line(tri + "f -1 -2 -4\n", "4");       // before the first vertex
    expect_line(tri + "f 1 2 2\n", "4");          // repeats a vertex
    expect_line(tri + "f 1/x 2 3\n", "4");
    expect_line(tri + "f 1/1/1/1 2 3\n", "4");
    expect_line(tri + "f 1 2 99999999999999999999\n", "4");
    // A face may name a vertex defined after it.
    std::istringstream later("f 1 2 3\n" + tri);
    EXPECT_EQ(io::read_obj(later, "l.obj").F.rows(), 1);
    // Coordinates up to ±1e50 are accepted.
    std::istringstream big("v 0 0 0\nv 1e50 0 0\nv 0 -1e50 0\nf 1 2 3\n");
    EXPECT_EQ(io::read_obj(big, "b.obj").V(2, 1), -1e50);
}

TEST(MeshIo, EveryFormatRefusesCoordinatesBeyondTheBound) {
    TempDir tmp;
    mesh::Vertices V(3, 3);
    V << 0, 0, 0, 1, 0, 0, 0, 2e50, 0;
    mesh::Faces F(1, 3);
    F << 0, 1, 2;
    for (const std::string ext : {".off", ".ply", ".vtp", ".obj"}) {
        const auto path = tmp / ("big" + ext);
        io::write_mesh(path, V, F);
        try {
            (void)io::read_mesh(path);
            FAIL() << ext;
        } catch (const InputError& e) {
            // VTK reads PLY as float32, where 2e50 is already +inf.
            const std::string want = ext == ".ply" ? "not finite" : "1e50";
            EXPECT_NE(std::string(e.what()).find(want), std::string::npos) << e.what();
            EXPECT_EQ(e.path(), path.string());
        }
    }
}

TEST(MeshIo, BadFilesGiveInputErrorsNamingThePath) {
    TempDir tmp;
    const auto expect_kind = [](const std::filesystem::path& p, InputError::Kind kind) {
        try {
            (void)io::read_mesh(p);
            FAIL() << p;
        } catch (const InputError& e) {
            EXPECT_EQ(e.kind(), kind) << p << ": " << e.what();
            EXPECT_EQ(e.path(), p.string());
        }
    };
    expect_kind(tmp / "missing.ply", InputError::Kind::kMissing);
    expect_kind(tmp.path(), InputError::Kind::kNotRegular);
    write_text(tmp / "empty.obj", "");
    expect_kind(tmp / "empty.obj", InputError::Kind::kCorrupt);
    write_text(tmp / "text.obj", "hello world\n");
    expect_kind(tmp / "text.obj", InputError::Kind::kCorrupt);
    write_text(tmp / "noface.obj", "v 0 0 0\nv 1 0 0\n");
    expect_kind(tmp / "noface.obj", InputError::Kind::kCorrupt);
    write_text(tmp / "junk.ply", "ply\nformat nonsense\n");
    expect_kind(tmp / "junk.ply", InputError::Kind::kCorrupt);
    write_text(tmp / "junk.vtp", "<?xml version=\"1.0\"?>\n<VTKFile type=\"PolyData\">\n");
    expect_kind(tmp / "junk.vtp", InputError::Kind::kCorrupt);
    write_text(tmp / "junk.xyz", "1 2 3\n");
    expect_kind(tmp / "junk.xyz", InputError::Kind::kUnsupported);
}

TEST(MeshIo, UnknownOutputExtensionIsAUsageError) {
    TempDir tmp;
    const auto m = plane_grid(1);
    EXPECT_THROW(io::write_mesh(tmp / "m.xyz", m.V, m.F), UsageError);
    EXPECT_THROW(io::write_mesh(tmp / "no" / "dir" / "m.off", m.V, m.F), OutputError);
}

TEST(MeshCommands, DenoiseThenMetricsAndFeatures) {
    TempDir tmp;
    const auto clean = cube(6);
    const auto noisy = with_noise(clean, 0.03);
    io::write_mesh(tmp / "noisy.off", noisy.V, noisy.F);
    io::write_mesh(tmp / "clean.off", clean.V, clean.F);
    const auto in = (tmp / "noisy.off").string();
    const auto out = (tmp / "out.vtp").string();
    auto r = run_octshape("denoise '" + in + "' -o '" + out + "' --threads 2 --json");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_NE(r.out.find("\"auto\": true"), std::string::npos) << r.out;
    r = run_octshape("metrics '" + out + "' --reference '" + (tmp / "clean.off").string() +
                     "' --json");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_NE(r.out.find("\"msae_deg\""), std::string::npos);
    EXPECT_NE(r.out.find("\"flipped_faces\": 0"), std::string::npos) << r.out;
    // The flips against the denoiser's input: none created here, and the input's own count.
    const int input_flips = mesh::flipped_faces(noisy.V, noisy.F, clean.V, clean.F);
    r = run_octshape("metrics '" + out + "' --reference '" + (tmp / "clean.off").string() +
                     "' --input '" + in + "' --json");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_NE(r.out.find("\"flipped_faces_created\": 0"), std::string::npos) << r.out;
    {
        const auto j = nlohmann::json::parse(r.out);
        EXPECT_EQ(j.at("mesh_sha256").get<std::string>(), io::sha256_file(out));
        EXPECT_EQ(j.at("reference_sha256").get<std::string>(),
                  io::sha256_file((tmp / "clean.off").string()));
        EXPECT_EQ(j.at("input_sha256").get<std::string>(), io::sha256_file(in));
        EXPECT_NE(j.at("mesh_sha256"), j.at("input_sha256"));
    }
    EXPECT_NE(r.out.find("\"input_flipped_faces\": " + std::to_string(input_flips)),
              std::string::npos)
        << r.out;
    // An input of another triangulation is a usage error.
    const auto other = plane_grid(2);
    io::write_mesh(tmp / "other.off", other.V, other.F);
    EXPECT_EQ(run_octshape("metrics '" + out + "' --reference '" + (tmp / "clean.off").string() +
                           "' --input '" + (tmp / "other.off").string() + "'")
                  .exit_code,
              64);
    r = run_octshape("features '" + out + "' -o '" + (tmp / "f.vtp").string() + "'");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    {
        // The output meshes name their command, inputs with SHA-256 and options.
        const auto d = nlohmann::json::parse(io::read_mesh(out).provenance);
        EXPECT_EQ(d.at("command"), "denoise");
        EXPECT_EQ(d.at("inputs")[0].at("sha256").get<std::string>(), io::sha256_file(in));
        EXPECT_EQ(d.at("options").at("method"), "rofi");
        EXPECT_TRUE(d.at("options").at("parameters").contains("sigma_s"));
        const auto f = nlohmann::json::parse(io::read_mesh(tmp / "f.vtp").provenance);
        EXPECT_EQ(f.at("command"), "features");
        EXPECT_EQ(f.at("inputs")[0].at("sha256").get<std::string>(), io::sha256_file(out));
        EXPECT_GT(f.at("options").at("radius_mm").get<double>(), 0.0);
    }
    // Errors map to the documented exit codes.
    EXPECT_EQ(run_octshape("denoise '" + (tmp / "none.off").string() + "' -o x.off").exit_code,
              66);
    EXPECT_EQ(run_octshape("denoise '" + in + "' -o x.off --sigma-s -1").exit_code, 64);
    EXPECT_EQ(run_octshape("features '" + in + "' -o x.obj").exit_code, 64);
    EXPECT_EQ(run_octshape("denoise '" + in + "' -o x.off --method pointset --no-fold-repair")
                  .exit_code,
              64);
    EXPECT_FALSE(std::filesystem::exists("x.off"));
    // RoFi's disk radius and closeness width in units of c_a: used and recorded (r and σ_c
    // in mesh units are the factors times the input's c_a), and refused for the other methods
    // or out of range.
    r = run_octshape("denoise '" + in + "' -o '" + out +
                     "' -p 3 --radius-factor 3 --sigma-c-factor 1.5 --json");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    {
        const auto j = nlohmann::json::parse(r.out);
        const auto& p = j.at("parameters");
        const double ca = j.at("noise").at("mean_centroid_distance_mm").get<double>();
        EXPECT_FALSE(j.at("auto").get<bool>());
        EXPECT_EQ(p.at("radius_factor").get<double>(), 3.0);
        EXPECT_EQ(p.at("sigma_c_factor").get<double>(), 1.5);
        // RoFi computes c_a on its renumbered mesh (rofi.md, "Issue 35 (session 21)"): the
        // same ≈ 650 edge distances of this cube (same bits each), summed in another order,
        // so it differs from the noise estimate's c_a by at most N u ≈ 7e−14 relative (N
        // positive terms, u = 2^−53); 1e−12 relative allows that and nothing larger.
        EXPECT_NEAR(p.at("radius_mm").get<double>(), 3.0 * ca, 1e-12 * ca);
        EXPECT_NEAR(p.at("sigma_c_mm").get<double>(), 1.5 * ca, 1e-12 * ca);
        EXPECT_EQ(j.at("input_sha256").get<std::string>(), io::sha256_file(in));
        // A wider disk holds more faces than the default one.
        const auto d = nlohmann::json::parse(
            run_octshape("denoise '" + in + "' -o '" + out + "' -p 3 --json").out);
        EXPECT_GT(j.at("mean_neighbourhood_faces").get<double>(),
                  d.at("mean_neighbourhood_faces").get<double>());
    }
    // The automatic rule ends RoFi when its residual is no longer white (rofi.md,
    // "Stopping"): the stop and the iterations run are recorded; an explicit --iterations
    // runs exactly that many.
    r = run_octshape("denoise '" + in + "' -o '" + out + "' --json");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    {
        const auto j = nlohmann::json::parse(r.out);
        const auto& p = j.at("parameters");
        EXPECT_TRUE(j.at("auto").get<bool>());
        EXPECT_EQ(p.at("stop").get<std::string>(), "white_residual");
        const int run = j.at("iterations_run").get<int>();
        EXPECT_GE(run, 1);
        EXPECT_LE(run, p.at("iterations").get<int>());
        EXPECT_GT(j.at("residual_rms_mm").get<double>(), 0.0);
        if (run < p.at("iterations").get<int>()) {
            EXPECT_LE(j.at("residual_whiteness").get<double>(), 1.0);
        }
        const auto d = nlohmann::json::parse(
            run_octshape("denoise '" + in + "' -o '" + out + "' --auto -p 3 --json").out);
        EXPECT_EQ(d.at("parameters").at("stop").get<std::string>(), "none");
        EXPECT_EQ(d.at("iterations_run").get<int>(), 3);
    }
    EXPECT_EQ(run_octshape("denoise '" + in + "' -o x.off --method envt --radius-factor 3")
                  .exit_code,
              64);
    EXPECT_EQ(run_octshape("denoise '" + in + "' -o x.off --sigma-c-factor 0").exit_code, 64);
    EXPECT_FALSE(std::filesystem::exists("x.off"));
    // ENVT records its fold-repair interval; --no-fold-repair turns the repair off.
    r = run_octshape("denoise '" + in + "' -o '" + out + "' --method envt -p 5 --json");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_NE(r.out.find("\"fold_repair_interval\": 10"), std::string::npos) << r.out;
    r = run_octshape("denoise '" + in + "' -o '" + out +
                     "' --method envt -p 5 --no-fold-repair --json");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_NE(r.out.find("\"fold_repair_interval\": 0"), std::string::npos) << r.out;
}

}  // namespace
}  // namespace octshape::test
