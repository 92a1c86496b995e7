// RoFi (thesis §5.1): properties over a family of meshes and known answers.

#include "octshape/mesh/rofi.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <stdexcept>
#include <vector>

#include "mesh/mesh_fixtures.h"
#include "octshape/mesh/metrics.h"

namespace octshape::test {
namespace {

mesh::RofiParams params(int iterations = 30) {
    mesh::RofiParams p;
    p.iterations = iterations;
    return p;
}

mesh::RofiParams auto_params(const TestMesh& m) {
    return mesh::auto_rofi_params(mesh::estimate_noise(m.V, m.F));
}

TEST(Rofi, ZeroIterationsIsTheIdentity) {
    for (const auto& m : noisy_family()) {
        const auto r = mesh::rofi_denoise(m.V, m.F, params(0));
        EXPECT_EQ(r.V, m.V) << m.name;
        EXPECT_EQ(r.iterations, 0);
    }
}

TEST(Rofi, DeterministicAndBitIdenticalForAnyThreadCount) {
    for (const auto& m : noisy_family()) {
        auto p = params();
        const auto one = mesh::rofi_denoise(m.V, m.F, p);
        const auto again = mesh::rofi_denoise(m.V, m.F, p);
        p.threads = 2;
        const auto two = mesh::rofi_denoise(m.V, m.F, p);
        p.threads = 5;
        const auto five = mesh::rofi_denoise(m.V, m.F, p);
        EXPECT_EQ(one.V, again.V) << m.name;
        EXPECT_EQ(one.V, two.V) << m.name;
        EXPECT_EQ(one.V, five.V) << m.name;
        EXPECT_EQ(one.V.rows(), m.V.rows());  // connectivity untouched: same vertex set
        EXPECT_NE(one.V, m.V) << m.name;      // and it did do something
    }
}

TEST(Rofi, RigidMotionOfTheInputMovesTheOutputTheSameWay) {
    const Eigen::Matrix3d R =
        Eigen::AngleAxisd(0.7, Eigen::Vector3d(0.3, -1.0, 0.5).normalized()).toRotationMatrix();
    const Eigen::RowVector3d t(3.0, -2.0, 0.5);
    for (const auto& m : noisy_family()) {
        const auto base = mesh::rofi_denoise(m.V, m.F, params());
        const mesh::Vertices moved = (m.V * R.transpose()).rowwise() + t;
        const auto out = mesh::rofi_denoise(moved, m.F, params());
        const mesh::Vertices expected = (base.V * R.transpose()).rowwise() + t;
        // Only rounding differs (≈1e-16 relative per operation over 30 iterations).
        EXPECT_LT((out.V - expected).cwiseAbs().maxCoeff(), 1e-9) << m.name;
    }
}

TEST(Rofi, BoundaryVerticesStayFixed) {
    const auto m = with_noise(plane_grid(16), 0.015);
    const auto r = mesh::rofi_denoise(m.V, m.F, params());
    const auto adj = mesh::build_adjacency(m.F, static_cast<int>(m.V.rows()));
    int fixed = 0;
    for (Eigen::Index i = 0; i < m.V.rows(); ++i) {
        if (adj.boundary_vertex[static_cast<std::size_t>(i)] != 0) {
            EXPECT_EQ(r.V.row(i), m.V.row(i));
            ++fixed;
        }
    }
    EXPECT_EQ(fixed, 4 * 16);
    EXPECT_EQ(r.fixed_vertices, fixed);
}

TEST(Rofi, NoisyPlaneBecomesAPlane) {
    // Noise only across the plane (σ = 0.25 h), boundary at z = 0 and fixed. A local filter
    // over a disk of radius ~2 h removes the short wavelengths; of white noise on the grid,
    // wavelengths longer than 4 h (|k| below half the Nyquist frequency in both axes) hold 1/4
    // of the height variance (RMS ½) and 1/16 of the slope variance (RMS ¼): bounds on what a
    // working filter leaves.
    auto m = plane_grid(24);
    Gaussian g(11);
    const double sigma = 0.25 / 24;
    const auto adj = mesh::build_adjacency(m.F, static_cast<int>(m.V.rows()));
    for (Eigen::Index i = 0; i < m.V.rows(); ++i) {
        if (adj.boundary_vertex[static_cast<std::size_t>(i)] == 0) m.V(i, 2) = sigma * g();
    }
    const double before = std::sqrt(m.V.col(2).squaredNorm() / m.V.rows());
    const auto r = mesh::rofi_denoise(m.V, m.F, auto_params(m));
    const double after = std::sqrt(r.V.col(2).squaredNorm() / r.V.rows());
    EXPECT_LT(after, 0.5 * before) << before << " -> " << after;
    const auto flat = plane_grid(24);
    EXPECT_LT(mesh::mean_angle_error_deg(r.V, m.F, flat.V, flat.F),
              0.25 * mesh::mean_angle_error_deg(m.V, m.F, flat.V, flat.F));
}

TEST(Rofi, NoisySphereBecomesASphereOfTheSameRadius) {
    // Icosphere (5120 faces, l_e ≈ 0.066) with σ = 0.13 l_e in each coordinate.
    const auto clean = icosphere(4);
    const auto m = with_noise(clean, 0.0085);
    const auto r = mesh::rofi_denoise(m.V, m.F, params(60));
    const auto radii = [](const mesh::Vertices& V) {
        std::vector<double> out;
        for (Eigen::Index i = 0; i < V.rows(); ++i) out.push_back(V.row(i).norm());
        return out;
    };
    const auto mean = [](const std::vector<double>& x) {
        double s = 0.0;
        for (const double v : x) s += v;
        return s / static_cast<double>(x.size());
    };
    const auto sd = [&](const std::vector<double>& x) {
        const double mu = mean(x);
        double s = 0.0;
        for (const double v : x) s += (v - mu) * (v - mu);
        return std::sqrt(s / static_cast<double>(x.size()));
    };
    const std::vector<double> before = radii(m.V);
    const std::vector<double> after = radii(r.V);
    // Radius: the input's mean radius is 1 + O(σ²) = 1.0001; a denoiser that shrank the sphere
    // like Laplacian smoothing would lose ~l_e²/2 per step. Allow 0.5 % (l_e / 13).
    EXPECT_NEAR(mean(after), 1.0, 5e-3);
    EXPECT_LT(sd(after), 0.3 * sd(before));
    EXPECT_LT(mesh::mean_angle_error_deg(r.V, m.F, clean.V, clean.F),
              0.3 * mesh::mean_angle_error_deg(m.V, m.F, clean.V, clean.F));
}

TEST(Rofi, CubeKeepsItsRightDihedralAngles) {
    const auto clean = cube(8);
    const auto m = with_noise(clean, 0.02);  // σ = 0.08 l_e
    const auto r = mesh::rofi_denoise(m.V, m.F, auto_params(m));
    const auto g = mesh::face_geometry(r.V, m.F);
    const auto g0 = mesh::face_geometry(clean.V, clean.F);
    const auto adj = mesh::build_adjacency(m.F, static_cast<int>(m.V.rows()));
    int sharp_pairs = 0;
    double worst = 0.0;
    double sum = 0.0;
    for (int f = 0; f < adj.face_faces.rows(); ++f) {
        for (int p = adj.face_faces.begin(f); p < adj.face_faces.end(f); ++p) {
            const int h = adj.face_faces.item(p);
            if (std::abs(g0.normals.row(f).dot(g0.normals.row(h))) > 0.5) continue;
            ++sharp_pairs;  // the two faces meet at a cube edge: 90° in the reference
            const double angle =
                std::acos(std::clamp(g.normals.row(f).dot(g.normals.row(h)), -1.0, 1.0));
            const double deviation = std::abs(angle * 180.0 / std::numbers::pi - 90.0);
            worst = std::max(worst, deviation);
            sum += deviation;
        }
    }
    EXPECT_EQ(sharp_pairs, 12 * 8 * 2);  // 12 edges × 8 faces per side × both directions
    // A smoothing filter rounds the edges into bevels: ~45° off at the edge. RoFi keeps them
    // square: within 3° on average, 10° at worst (input noise tilts faces by ~4° on average).
    EXPECT_LT(sum / sharp_pairs, 3.0);
    EXPECT_LT(worst, 10.0);
}

TEST(Rofi, GaussianSimilarityIsADifferentFilter) {
    const auto m = with_noise(cube(6), 0.03);
    auto p = params();
    const auto tukey = mesh::rofi_denoise(m.V, m.F, p);
    p.similarity = mesh::Similarity::kGaussian;
    const auto gaussian = mesh::rofi_denoise(m.V, m.F, p);
    EXPECT_GT((tukey.V - gaussian.V).cwiseAbs().maxCoeff(), 1e-6);
}

TEST(Rofi, ValidateNamesTheBadField) {
    const auto expect_field = [](mesh::RofiParams p, const std::string& field) {
        try {
            p.validate();
            FAIL() << field << " accepted";
        } catch (const std::invalid_argument& e) {
            EXPECT_NE(std::string(e.what()).find(field), std::string::npos) << e.what();
        }
    };
    mesh::RofiParams p;
    EXPECT_NO_THROW(p.validate());
    p.sigma_s = 0.0;
    expect_field(p, "sigma_s");
    p = {};
    p.lambda_i = -0.1;
    expect_field(p, "lambda_i");
    p = {};
    p.iterations = -1;
    expect_field(p, "iterations");
    p = {};
    p.lambda_decay = 1.5;
    expect_field(p, "lambda_decay");
    p = {};
    p.threads = 0;
    expect_field(p, "threads");
}

}  // namespace
}  // namespace octshape::test
