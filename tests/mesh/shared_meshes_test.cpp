// RoFi, ENVT and bilateral filtering on the noisy / ground-truth pairs of ../shared/meshes
// against the targets of issue 4 (peer values in ../shared/meshes/README.md). Labelled "slow".

#include <gtest/gtest.h>

#include <string>

#include "octshape/io/mesh_io.h"
#include "octshape/mesh/envt.h"
#include "octshape/mesh/metrics.h"
#include "octshape/mesh/rofi.h"
#include "test_paths.h"
#include "slow_test.h"

namespace octshape::test {
namespace {

struct Pair {
    io::MeshData noisy;
    io::MeshData truth;
    mesh::MeshComparison input;
};

Pair load(const std::string& name) {
    const auto dir = shared_dir() / "meshes" / name;
    Pair p{io::read_mesh(dir / "Noisy.obj"), io::read_mesh(dir / "Original.obj"), {}};
    p.input = mesh::compare_meshes(p.noisy.V, p.noisy.F, p.truth.V, p.truth.F);
    return p;
}

mesh::MeshComparison compare(const Pair& p, const mesh::DenoiseResult& r) {
    const auto c = mesh::compare_meshes(r.V, p.noisy.F, p.truth.V, p.truth.F);
    std::printf("  MSAE %.3f deg  E_v %.5f  Q %.3f (truth %.3f)  flips %d (input %d)\n",
                c.msae_deg, c.vertex_error, c.quality, c.reference_quality, c.flipped_faces,
                p.input.flipped_faces);
    return c;
}

// RoFi with auto_rofi_params; also checks that it beats paper_disk_rofi_params (the rule before
// session 8) on this pair: a lower MSAE and no more flips created (flip_transitions against the
// noisy input); and that it is no worse than fixed_p_rofi_params (session 8) on either count.
mesh::MeshComparison rofi_auto(const Pair& p) {
    const auto noise = mesh::estimate_noise(p.noisy.V, p.noisy.F);
    const auto r = mesh::rofi_denoise(p.noisy.V, p.noisy.F, mesh::auto_rofi_params(noise));
    const auto before =
        mesh::rofi_denoise(p.noisy.V, p.noisy.F, mesh::paper_disk_rofi_params(noise));
    const auto c = compare(p, r);
    const auto t = mesh::flip_transitions(r.V, p.noisy.V, p.truth.V, p.noisy.F);
    const auto t0 = mesh::flip_transitions(before.V, p.noisy.V, p.truth.V, p.noisy.F);
    EXPECT_LT(c.msae_deg, mesh::mean_angle_error_deg(before.V, p.noisy.F, p.truth.V, p.truth.F));
    EXPECT_LE(t.created, t0.created);
    // And the session-8 rule (fixed p = 30, no stop): the stop of session 9 must not be worse
    // on any shared pair (issue 23).
    const auto today =
        mesh::rofi_denoise(p.noisy.V, p.noisy.F, mesh::fixed_p_rofi_params(noise));
    EXPECT_LE(c.msae_deg, mesh::mean_angle_error_deg(today.V, p.noisy.F, p.truth.V, p.truth.F));
    EXPECT_LE(t.created, mesh::flip_transitions(today.V, p.noisy.V, p.truth.V, p.noisy.F).created);
    return c;
}

// Targets: the guided filter's MSAE (README), Q no worse than the truth's + 0.05, and no
// flipped face beyond those the noisy input already has.
// Slow: denoises a mesh of ../shared/meshes (seconds).
SLOW_TEST(SharedMeshes, RofiAutoFandisk) {
    SKIP_UNLESS_SHARED("meshes/Fandisk0.3/Noisy.obj", "meshes/Fandisk0.3/Original.obj");
    const Pair p = load("Fandisk0.3");
    const auto c = rofi_auto(p);
    EXPECT_LE(c.msae_deg, 2.93);
    EXPECT_LE(c.quality, c.reference_quality + 0.05);
    EXPECT_EQ(c.flipped_faces, 0);
}

// Slow: denoises a mesh of ../shared/meshes (seconds).
SLOW_TEST(SharedMeshes, RofiAutoBlock) {
    SKIP_UNLESS_SHARED("meshes/Block0.4/Noisy.obj", "meshes/Block0.4/Original.obj");
    const Pair p = load("Block0.4");
    const auto c = rofi_auto(p);
    EXPECT_LE(c.msae_deg, 4.09);
    EXPECT_LE(c.quality, c.reference_quality + 0.05);
    EXPECT_EQ(c.flipped_faces, 0);
}

// Slow: denoises a mesh of ../shared/meshes (seconds).
SLOW_TEST(SharedMeshes, RofiAutoTwelveImpulsive) {
    SKIP_UNLESS_SHARED("meshes/Twelve0.5Impulsive/Noisy.obj", "meshes/Twelve0.5Impulsive/Original.obj");
    const Pair p = load("Twelve0.5Impulsive");
    const auto c = rofi_auto(p);
    EXPECT_LE(c.msae_deg, 3.84);
    EXPECT_LE(c.quality, c.reference_quality + 0.05);
    EXPECT_EQ(c.flipped_faces, 0);  // the input's 7 all fixed, none created
}

// Slow: denoises a mesh of ../shared/meshes (seconds).
SLOW_TEST(SharedMeshes, RofiAutoSharpSphere) {
    SKIP_UNLESS_SHARED("meshes/SharpSphere0.3/Noisy.obj", "meshes/SharpSphere0.3/Original.obj");
    // The creases are the hard case: the input has 201 flipped faces there. The MSAE target
    // holds; the flip count stays below the input's (README: a faithful RoFi keeps ~160–200;
    // the flips it creates are faces thinner than its vertex error, rofi.md).
    const Pair p = load("SharpSphere0.3");
    const auto c = rofi_auto(p);
    EXPECT_LE(c.msae_deg, 8.17);
    EXPECT_LE(c.quality, c.reference_quality + 0.05);
    EXPECT_LE(c.flipped_faces, p.input.flipped_faces);
}

// Slow: denoises a mesh of ../shared/meshes (seconds).
SLOW_TEST(SharedMeshes, RofiTunedFandisk) {
    SKIP_UNLESS_SHARED("meshes/Fandisk0.3/Noisy.obj", "meshes/Fandisk0.3/Original.obj");
    // Issue target ≤ 2.2° (thesis Table 5.1, tuned parameters). Tuned over the thesis's own
    // (σ_s, λ_I, p), with σ_c = c_a and r = 2 c_a fixed as in §5.2, the best found is ≈ 2.37°:
    // asserted better than the faithful RoFi at the paper's parameters on this mesh (README:
    // ≈ 2.65°). Tuned over σ_c and r too (grid in rofi.md), a wider, flatter disk reaches
    // 2.13°, and ~2.12–2.15° on the plateau around it (not a single lucky point); on ten fresh
    // draws of this pair's noise it gives 2.25–2.45° against 2.48–2.81° for the three-parameter
    // setting (bench/mesh_realisations), so the gain is the method's, not the draw's.
    const Pair p = load("Fandisk0.3");
    struct Case {
        double sigma_s, lambda_i;
        int iterations;
        double sigma_c_factor, radius_factor, bound_deg;
    };
    for (const Case& k : {Case{1.1, 0.05, 100, 1.0, 2.0, 2.65}, Case{1.2, 0.01, 50, 3.0, 4.0, 2.2}}) {
        mesh::RofiParams params;
        params.sigma_s = k.sigma_s;
        params.lambda_i = k.lambda_i;
        params.iterations = k.iterations;
        params.sigma_c_factor = k.sigma_c_factor;
        params.radius_factor = k.radius_factor;
        const auto c = compare(p, mesh::rofi_denoise(p.noisy.V, p.noisy.F, params));
        EXPECT_LE(c.msae_deg, k.bound_deg) << "r = " << k.radius_factor << " c_a";
        EXPECT_LE(c.quality, c.reference_quality + 0.05);
        EXPECT_EQ(c.flipped_faces, 0);
    }
}

// Slow: denoises a mesh of ../shared/meshes (seconds).
SLOW_TEST(SharedMeshes, RofiTunedSharpSphere) {
    SKIP_UNLESS_SHARED("meshes/SharpSphere0.3/Noisy.obj", "meshes/SharpSphere0.3/Original.obj");
    const Pair p = load("SharpSphere0.3");
    mesh::RofiParams params;
    params.sigma_s = 0.75;
    params.lambda_i = 0.1;
    params.iterations = 40;
    const auto c = compare(p, mesh::rofi_denoise(p.noisy.V, p.noisy.F, params));
    EXPECT_LE(c.msae_deg, 8.17);
    EXPECT_LE(c.flipped_faces, p.input.flipped_faces);
}

TEST(SharedMeshes, FoldRepairRemovesTheFlipsRofiCreatesOnTwelveAndBlock) {
    SKIP_UNLESS_SHARED("meshes/Twelve0.5Impulsive/Noisy.obj", "meshes/Twelve0.5Impulsive/Original.obj",
                       "meshes/Block0.4/Noisy.obj", "meshes/Block0.4/Original.obj");
    // Eq. 5.1–5.9 alone (repair_folds = false) turn over faces that the input had right: on
    // Twelve at the paper-disk auto parameters (before session 8; the wider-disk auto creates
    // none there) and on Block at (0.6, 0.2, 100). Each is a fold (a face lying back on its
    // edge-neighbour); with the repair RoFi creates none, and the MSAE targets hold.
    struct Case {
        const char* name;
        bool automatic;
        double target_deg;
    };
    for (const Case& k : {Case{"Twelve0.5Impulsive", true, 3.84}, Case{"Block0.4", false, 4.09}}) {
        const Pair p = load(k.name);
        mesh::RofiParams params;
        if (k.automatic) {
            params = mesh::paper_disk_rofi_params(mesh::estimate_noise(p.noisy.V, p.noisy.F));
        } else {
            params.sigma_s = 0.6;
            params.lambda_i = 0.2;
            params.iterations = 100;
        }
        params.repair_folds = false;
        const auto plain = mesh::rofi_denoise(p.noisy.V, p.noisy.F, params);
        params.repair_folds = true;
        const auto repaired = mesh::rofi_denoise(p.noisy.V, p.noisy.F, params);
        const auto t0 = mesh::flip_transitions(plain.V, p.noisy.V, p.truth.V, p.noisy.F);
        const auto t1 = mesh::flip_transitions(repaired.V, p.noisy.V, p.truth.V, p.noisy.F);
        std::printf("  %s: created %d -> %d, folds repaired %d\n", k.name, t0.created,
                    t1.created, repaired.folds_repaired);
        EXPECT_GT(t0.created, 0) << k.name;
        EXPECT_EQ(t1.created, 0) << k.name;
        EXPECT_GT(repaired.folds_repaired, 0) << k.name;
        EXPECT_EQ(repaired.folds_left, 0) << k.name;
        EXPECT_LE(mesh::mean_angle_error_deg(repaired.V, p.noisy.F, p.truth.V, p.truth.F),
                  k.target_deg)
            << k.name;
    }
}

// Slow: denoises a mesh of ../shared/meshes (seconds).
SLOW_TEST(SharedMeshes, EnvtAutoFandisk) {
    SKIP_UNLESS_SHARED("meshes/Fandisk0.3/Noisy.obj", "meshes/Fandisk0.3/Original.obj");
    // Thesis Table 3.1: ENVT 2.692° on Fandisk.
    const Pair p = load("Fandisk0.3");
    const auto params = mesh::auto_envt_params(mesh::estimate_noise(p.noisy.V, p.noisy.F));
    const auto c = compare(p, mesh::envt_denoise(p.noisy.V, p.noisy.F, params));
    EXPECT_LE(c.msae_deg, 2.7);
    EXPECT_LE(c.quality, c.reference_quality + 0.05);
    EXPECT_EQ(c.flipped_faces, 0);
}

// Slow: denoises a mesh of ../shared/meshes (seconds).
SLOW_TEST(SharedMeshes, BilateralFandisk) {
    SKIP_UNLESS_SHARED("meshes/Fandisk0.3/Noisy.obj", "meshes/Fandisk0.3/Original.obj");
    // Classic bilateral normal filtering (Gaussian similarity, λ_I = 0): at least as good as
    // the published bilateral implementation's 3.49° (README).
    const Pair p = load("Fandisk0.3");
    mesh::RofiParams params;
    params.similarity = mesh::Similarity::kGaussian;
    params.sigma_s = 0.35;
    params.lambda_i = 0.0;
    params.iterations = 80;
    const auto c = compare(p, mesh::rofi_denoise(p.noisy.V, p.noisy.F, params));
    EXPECT_LE(c.msae_deg, 3.49);
}

}  // namespace
}  // namespace octshape::test
