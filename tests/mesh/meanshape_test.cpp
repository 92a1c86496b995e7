// Statistical shape analysis (§8.2): ICP (io/registration.h), mean shape and per-vertex SD
// (mesh/meanshape.h), and `octshape meanshape`.

#include "octshape/mesh/meanshape.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include "octshape/io/mesh_io.h"
#include "octshape/io/registration.h"
#include "octshape/io/sha256.h"
#include "fixtures/ilm_patch.h"
#include "test_paths.h"
#include "slow_test.h"

namespace octshape::test {
namespace {

// Area-weighted unit vertex normals.
mesh::Vertices vertex_normals(const mesh::Surface& s) {
    mesh::Vertices N = mesh::Vertices::Zero(s.V.rows(), 3);
    for (Eigen::Index f = 0; f < s.F.rows(); ++f) {
        const Eigen::Vector3d a = s.V.row(s.F(f, 0)).transpose();
        const Eigen::Vector3d b = s.V.row(s.F(f, 1)).transpose();
        const Eigen::Vector3d c = s.V.row(s.F(f, 2)).transpose();
        const Eigen::RowVector3d w = (b - a).cross(c - a).transpose();  // 2 × area × normal
        for (int k = 0; k < 3; ++k) N.row(s.F(f, k)) += w;
    }
    N.rowwise().normalize();
    return N;
}

Eigen::Isometry3d rigid(double angle_deg, const Eigen::Vector3d& axis, const Eigen::Vector3d& t) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = Eigen::AngleAxisd(angle_deg * M_PI / 180.0, axis.normalized()).toRotationMatrix();
    T.translation() = t;
    return T;
}

double rotation_error_deg(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
    return Eigen::AngleAxisd(a.linear() * b.linear().transpose()).angle() * 180.0 / M_PI;
}

// Slow: VTK's ICP runs hundreds of iterations per registration.
SLOW_TEST(Icp, RecoversKnownRotations) {
    const mesh::Surface ref = ilm_patch(30);
    const std::vector<Eigen::Isometry3d> moves{
        rigid(2.0, {0, 0, 1}, {0.05, -0.02, 0.01}), rigid(5.0, {1, 0.3, 0}, {-0.1, 0.0, 0.05}),
        rigid(10.0, {0.2, -1, 0.5}, {0.2, 0.1, -0.1}), rigid(15.0, {0, 0.4, 1}, {0, 0.3, 0})};
    for (const auto& T : moves) {
        const mesh::Vertices moved = io::transformed(ref.V, T);
        const io::IcpResult r = io::icp_rigid(moved, ref.V, ref.F);
        // ICP maps the moved copy back: r.transform ≈ T⁻¹.
        const Eigen::Isometry3d back = T.inverse();
        const double angle_err = rotation_error_deg(r.transform, back);
        const double aligned_err =
            (io::transformed(moved, r.transform) - ref.V).rowwise().norm().maxCoeff();
        std::printf("[ icp      ] rotation %.1f deg: error %.2e deg, max vertex error %.2e mm, "
                    "rms residual %.2e mm, %d iterations\n",
                    Eigen::AngleAxisd(T.linear()).angle() * 180.0 / M_PI, angle_err, aligned_err,
                    r.rms_distance, r.iterations);
        // Exact copies: the true alignment has zero residual; the point-to-plane steps
        // (Gauss-Newton on a zero-residual problem) converge quadratically to it, so the answer
        // is exact to rounding: 1e-9 mm is 1e-8 of the 100 µm grid step, 1e-7° moves a point
        // 2 mm from the centre by 3.5e-9 mm.
        EXPECT_LT(angle_err, 1e-7);
        EXPECT_LT(aligned_err, 1e-9);
        EXPECT_LT(r.rms_distance, 1e-9);
    }
}

// A surface large enough that VTK's point-to-point ICP alone does not converge in a short
// iteration budget: the point-to-plane refinement must take it to the exact alignment.
TEST(Icp, PointToPlaneRefinementConvergesWherePointToPointStalls) {
    const mesh::Surface ref = ilm_patch(100);  // 10 201 vertices, 30 µm grid
    const Eigen::Isometry3d T = rigid(5.0, {1, 0.3, 0}, {-0.1, 0.0, 0.05});
    const mesh::Vertices moved = io::transformed(ref.V, T);
    // 30 VTK iterations (a quarter of the default budget keeps the test short) with and
    // without the refinement.
    io::IcpParams vtk_only;
    vtk_only.max_iterations = 30;
    vtk_only.refine_iterations = 0;
    io::IcpParams refined = vtk_only;
    refined.refine_iterations = io::IcpParams{}.refine_iterations;
    const io::IcpResult a = io::icp_rigid(moved, ref.V, ref.F, vtk_only);
    const io::IcpResult b = io::icp_rigid(moved, ref.V, ref.F, refined);
    const double err_a = rotation_error_deg(a.transform, T.inverse());
    const double err_b = rotation_error_deg(b.transform, T.inverse());
    const double vert_b = (io::transformed(moved, b.transform) - ref.V).rowwise().norm().maxCoeff();
    std::printf("[ icp      ] 10k vertices, 5 deg: VTK only %.2e deg (%d it), refined %.2e deg "
                "(+%d steps), max vertex error %.2e mm\n",
                err_a, a.iterations, err_b, b.refine_iterations, vert_b);
    // Exact copies: zero residual at the true alignment, and Gauss-Newton on a zero-residual
    // problem converges quadratically, so the refined answer is exact to rounding (a 1e-9 mm
    // vertex error is 1e-7 of the grid step; the rotation bound is that over the 2 mm arm).
    EXPECT_LT(vert_b, 1e-9);
    EXPECT_LT(err_b, 1e-7);
    EXPECT_LT(b.rms_distance, 1e-9);
    EXPECT_LT(err_b, err_a);
    EXPECT_GT(b.refine_iterations, 0);
}

// Slow: VTK's ICP runs hundreds of iterations per registration.
SLOW_TEST(MeanShape, RigidCopiesGiveTheOriginalWithZeroSd) {
    const mesh::Surface ref = ilm_patch(30);
    std::vector<mesh::Surface> others;
    for (const auto& T : {rigid(4.0, {0, 0, 1}, {0.1, 0, 0}), rigid(7.0, {1, 1, 0}, {0, 0.1, 0}),
                          rigid(3.0, {0, 1, 1}, {0, 0, 0.2})}) {
        mesh::Surface copy{io::transformed(ref.V, T), ref.F};
        const io::IcpResult r = io::icp_rigid(copy.V, ref.V, ref.F);
        copy.V = io::transformed(copy.V, r.transform);
        others.push_back(copy);
    }
    const mesh::MeanShapeResult m = mesh::mean_shape(ref, others);
    EXPECT_EQ(m.surfaces, 4);
    const double max_mean_err = (m.mean - ref.V).rowwise().norm().maxCoeff();
    std::printf("[ meanshape] rigid copies: max |mean - original| %.2e mm, max SD %.2e mm\n",
                max_mean_err, m.sd.maxCoeff());
    // Same bound as the ICP test: the copies are aligned exactly to rounding.
    EXPECT_LT(max_mean_err, 1e-9);
    EXPECT_LT(m.sd.maxCoeff(), 1e-9);
}

TEST(MeanShape, NoisyCopiesGiveTheExpectedSd) {
    // n_s surfaces, each the ILM with independent Gaussian noise of SD σ along the vertex
    // normals (already aligned: this tests Eq. 8.25 and the SD, not ICP). σ = 0.5 µm is 1/150
    // of the grid step, so the noisy triangles tilt by < 1 % and the closest point of a
    // reference vertex on copy i is that copy's vertex to a relative error ~1e-4.
    const int n_s = 8;
    const double sigma = 5e-4;
    const mesh::Surface clean = ilm_patch(40);
    const mesh::Vertices N = vertex_normals(clean);
    std::mt19937 rng(2024);
    std::normal_distribution<double> gauss(0.0, sigma);
    const auto noisy = [&] {
        mesh::Surface s = clean;
        for (Eigen::Index i = 0; i < s.V.rows(); ++i) s.V.row(i) += gauss(rng) * N.row(i);
        return s;
    };
    const mesh::Surface ref = noisy();
    std::vector<mesh::Surface> others;
    for (int i = 1; i < n_s; ++i) others.push_back(noisy());
    mesh::MeanShapeParams p;
    p.threads = 2;
    const mesh::MeanShapeResult m = mesh::mean_shape(ref, others, p);

    const auto V = static_cast<double>(clean.V.rows());
    const double mean_sd2 = m.sd.squaredNorm() / V;
    const double expected_sd2 = sigma * sigma * (n_s - 1) / n_s;
    const double mean_err2 = (m.mean - clean.V).rowwise().squaredNorm().sum() / V;
    std::printf("[ meanshape] noisy copies: RMS SD %.4e mm, expected sigma*sqrt((n-1)/n) "
                "%.4e mm (ratio %.4f); RMS |mean - clean| %.4e, expected sigma/sqrt(n) %.4e\n",
                std::sqrt(mean_sd2), std::sqrt(expected_sd2), std::sqrt(mean_sd2 / expected_sd2),
                std::sqrt(mean_err2), sigma / std::sqrt(n_s));
    // n_s sd_j²/σ² ~ χ²(n_s − 1) independently per vertex: the mean over #V = 1681 vertices
    // has relative SD sqrt(2/(n_s − 1) / #V) = 1.3 %; 4 SD = 5.2 %.
    EXPECT_NEAR(mean_sd2 / expected_sd2, 1.0, 4.0 * std::sqrt(2.0 / (n_s - 1) / V));
    // mean − clean ~ N(0, σ²/n_s) along the normal: n_s |·|²/σ² ~ χ²(1), relative SD of the
    // average sqrt(2/#V) = 3.4 %; 4 SD = 14 %.
    EXPECT_NEAR(mean_err2 / (sigma * sigma / n_s), 1.0, 4.0 * std::sqrt(2.0 / V));
    // Per-vertex SD varies as the χ distribution says, but never beyond the noise extremes.
    EXPECT_LT(m.sd.maxCoeff(), 5.0 * sigma);
    ASSERT_EQ(m.mean_distance.size(), static_cast<std::size_t>(n_s));
    EXPECT_EQ(m.mean_distance[0], 0.0);
    // |c_i − v_j| is the difference of two N(0, σ²) offsets: RMS σ√2.
    for (int i = 1; i < n_s; ++i) {
        EXPECT_NEAR(m.rms_distance[static_cast<std::size_t>(i)] / (sigma * std::sqrt(2.0)), 1.0,
                    4.0 * std::sqrt(1.0 / (2.0 * V)));  // RMS: half the relative SD of χ²(1)/#V
    }
}

// Slow: VTK's ICP runs hundreds of iterations per registration.
SLOW_TEST(MeanShape, CommandWritesMeanWithSdAndReportsIcpResiduals) {
    const TempDir dir;
    const mesh::Surface ref = ilm_patch(24);
    io::write_mesh(dir / "a.ply", ref.V, ref.F);
    io::write_mesh(dir / "b.ply", io::transformed(ref.V, rigid(6.0, {0, 1, 1}, {0.1, 0, 0})),
                   ref.F);
    io::write_mesh(dir / "c.vtp", io::transformed(ref.V, rigid(3.0, {1, 0, 0}, {0, 0, 0.1})),
                   ref.F);
    const auto out = dir / "mean.vtp";
    const RunResult r = run_octshape("meanshape " + (dir / "a.ply").string() + " " +
                                     (dir / "b.ply").string() + " " + (dir / "c.vtp").string() +
                                     " -o " + out.string());
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const auto j = nlohmann::json::parse(r.out);
    ASSERT_EQ(j.at("surfaces").size(), 3u);
    EXPECT_EQ(j.at("surfaces")[0].at("icp_iterations"), 0);
    EXPECT_LT(j.at("surfaces")[1].at("icp_rms_distance_mm").get<double>(), 1e-4);
    EXPECT_NEAR(j.at("surfaces")[1].at("icp_rotation_deg").get<double>(), 6.0, 0.01);
    EXPECT_NEAR(j.at("surfaces")[2].at("icp_rotation_deg").get<double>(), 3.0, 0.01);
    EXPECT_LT(j.at("max_sd_mm").get<double>(), 1e-3);
    const io::MeshData mean = io::read_mesh(out);
    EXPECT_EQ(mean.V.rows(), ref.V.rows());
    const auto provenance = nlohmann::json::parse(mean.provenance);
    EXPECT_EQ(provenance.at("command"), "meanshape");
    ASSERT_EQ(provenance.at("inputs").size(), 3u);
    EXPECT_EQ(provenance.at("inputs")[1].at("sha256").get<std::string>(),
              io::sha256_file((dir / "b.ply").string()));
    EXPECT_LT((mean.V - ref.V).cwiseAbs().maxCoeff(), 1e-3);

    // Fewer than two surfaces is a usage error (exit 64); a missing file exits 66.
    EXPECT_EQ(run_octshape("meanshape " + (dir / "a.ply").string() + " -o " + out.string())
                  .exit_code,
              64);
    EXPECT_EQ(run_octshape("meanshape " + (dir / "a.ply").string() + " " +
                           (dir / "nope.ply").string() + " -o " + out.string())
                  .exit_code,
              66);
}

}  // namespace
}  // namespace octshape::test
