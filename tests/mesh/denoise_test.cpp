// The noise estimate behind --auto (denoise.h) and the parameters chosen from it.

#include "octshape/mesh/denoise.h"

#include <gtest/gtest.h>

#include "mesh/mesh_fixtures.h"
#include "octshape/mesh/envt.h"
#include "octshape/mesh/rofi.h"

namespace octshape::test {
namespace {

// A plane grid with Gaussian heights of σ = level · h at the interior vertices.
TestMesh noisy_plane(double level, std::uint32_t seed) {
    const int n = 60;
    auto m = plane_grid(n);
    Gaussian g(seed);
    const auto adj = mesh::build_adjacency(m.F, static_cast<int>(m.V.rows()));
    for (Eigen::Index i = 0; i < m.V.rows(); ++i) {
        if (adj.boundary_vertex[static_cast<std::size_t>(i)] == 0) m.V(i, 2) = level * g() / n;
    }
    return m;
}

TEST(NoiseEstimate, CleanMeshesHaveNoNoise) {
    EXPECT_EQ(mesh::estimate_noise(plane_grid(10).V, plane_grid(10).F).noise_sigma, 0.0);
    const auto s = icosphere(4);
    // The sphere's own bending reads as noise: a vertex sits l_e²/(2R) above its 1-ring
    // centroid, i.e. l_e/(2R) = 0.033 edge lengths at l_e = 0.066 R, divided by the Gaussian
    // median factor 0.6745: 0.049. Anything above 0.06 would be an error of the estimator.
    EXPECT_LT(mesh::estimate_noise(s.V, s.F).noise_sigma, 0.06);
}

TEST(NoiseEstimate, TracksTheNoiseLevelOfANoisyPlane) {
    // The grid's mean edge is 1.14 h (sides h, diagonals √2 h), so σ = level·h reads as
    // level/1.14 edge lengths. The median of ~3500 offsets has a relative standard error of
    // ~2.5 %; the vertex-normal estimate from noisy faces biases it by up to ~15 %.
    for (const double level : {0.1, 0.3, 0.5}) {
        const auto m = noisy_plane(level, 17);
        const auto e = mesh::estimate_noise(m.V, m.F);
        EXPECT_NEAR(e.noise_sigma, level / 1.14, 0.2 * level / 1.14) << level;
    }
}

TEST(AutoParams, MoreNoiseGivesWiderSimilarityAndMoreFidelity) {
    const auto low = mesh::estimate_noise(noisy_plane(0.1, 3).V, noisy_plane(0.1, 3).F);
    const auto high = mesh::estimate_noise(noisy_plane(0.6, 3).V, noisy_plane(0.6, 3).F);
    const auto rl = mesh::auto_rofi_params(low);
    const auto rh = mesh::auto_rofi_params(high);
    EXPECT_LT(rl.sigma_s, rh.sigma_s);
    EXPECT_LT(rl.lambda_i, rh.lambda_i);
    EXPECT_NO_THROW(rl.validate());
    EXPECT_NO_THROW(rh.validate());
    const auto el = mesh::auto_envt_params(low);
    const auto eh = mesh::auto_envt_params(high);
    EXPECT_LT(el.tau, eh.tau);
    EXPECT_NO_THROW(el.validate());
}

TEST(AutoParams, DoNotDependOnTheMeshScale) {
    // θ is an angle, σ̂_n is in edge lengths and the disk (r, σ_c) in units of c_a, so a mesh
    // scaled by 1000 gets the same RoFi parameters (and its disk in mm scales with it). A rule
    // written in absolute lengths would fail this.
    const auto m = noisy_plane(0.3, 5);
    const auto a = mesh::auto_rofi_params(mesh::estimate_noise(m.V, m.F));
    const mesh::Vertices big = 1000.0 * m.V;
    const auto b = mesh::auto_rofi_params(mesh::estimate_noise(big, m.F));
    EXPECT_NEAR(a.sigma_s, b.sigma_s, 1e-9);
    EXPECT_NEAR(a.lambda_i, b.lambda_i, 1e-9);
    EXPECT_EQ(a.iterations, b.iterations);
    EXPECT_EQ(a.stop, mesh::RofiStop::kWhiteResidual);
    EXPECT_EQ(a.radius_factor, b.radius_factor);
    EXPECT_EQ(a.sigma_c_factor, b.sigma_c_factor);
    // The automatic disk is wider and flatter than §5.2's (rofi.md, "Automatic parameters"),
    // with the paper's ratio r = 2 σ_c.
    EXPECT_GT(a.radius_factor, mesh::RofiParams{}.radius_factor);
    EXPECT_GT(a.sigma_c_factor, mesh::RofiParams{}.sigma_c_factor);
    EXPECT_EQ(a.radius_factor, 2.0 * a.sigma_c_factor);
}

}  // namespace
}  // namespace octshape::test
