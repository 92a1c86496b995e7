#pragma once
// The element-based normal voting tensor (ENVT, thesis §2.3–2.5) and the ENVT denoiser (§3.1).

#include <optional>

#include "octshape/mesh/denoise.h"
#include "octshape/mesh/mesh.h"

namespace octshape::mesh {

// ENVT denoising (§3.1). Each iteration, for every face f_i:
//  (1) local binary neighbours (Eq. 3.1): w_ij = 1 if ∠(n_i, n_j) ≤ ρ else 0.1, over the disk
//      Ω_i of radius r (f_i included);
//  (2) ENVT C_i = Σ w_ij A_j n_j n_jᵀ / Σ w_ij A_j (Eq. 3.2) and its eigen-decomposition
//      λ1 ≥ λ2 ≥ λ3 (Eq. 3.3);
//  (3) binary optimisation (§3.1.3): λ̃ = (1,1,1) if λ3 ≥ τ, (1,1,0) if λ2 ≥ τ > λ3, else
//      (1,0,0); C̃_i = Σ λ̃_k e_k e_kᵀ (Eq. 3.4);
//  (4) ñ_i = normalise(d n_i + C̃_i n_i) (Eq. 3.5, d = damping);
// then every interior vertex takes one step of Eq. 3.7 (with the edge term ñ_k·(v_j − v_i):
// the printed sign is a typo, as for RoFi's Eq. 5.9). Boundary vertices stay fixed.
struct EnvtParams {
    double tau = 0.3;               // eigenvalue threshold τ (dimensionless, ENVT trace = 1)
    std::optional<double> radius;   // disk radius r (length unit); unset: 2 c_a
    int iterations = 50;            // p; 0 returns the input unchanged
    double rho = 0.8;               // angle threshold ρ of Eq. 3.1, radians, in (0, π]
    double damping = 3.0;           // d of Eq. 3.5; ≥ 0
    bool fix_boundary = true;       // keep boundary / non-manifold vertices in place
    // Repair fold-overs (folds.h) after every this many iterations and after the last; 0 =
    // never (Eq. 3.1–3.7 alone). The tensor C̃ of Eq. 3.2–3.4 has no sign, so Eq. 3.5 keeps the
    // side of a face's own normal and the vertex step flattens a folded face onto the wrong
    // side: nothing in ENVT turns it back (docs/algorithms/envt.md, "Folds"). ≥ 0.
    int fold_repair_interval = 10;
    int threads = 1;                // std::threads; results do not depend on it; ≥ 1

    // Throws UsageError naming the first bad field.
    void validate() const;
};

[[nodiscard]] DenoiseResult envt_denoise(const Vertices& V,
                                         const Faces& F,
                                         const EnvtParams& params);

// Parameters chosen from a noise estimate (docs/algorithms/envt.md).
[[nodiscard]] EnvtParams auto_envt_params(const NoiseEstimate& noise);

// Feature analysis (§2.4–2.5) of a (smooth or denoised) mesh.
struct FeatureParams {
    std::optional<double> radius;  // disk radius r of Ω_i (length unit); unset: 2 c_a
    int threads = 1;               // ≥ 1

    // Throws UsageError naming the first bad field.
    void validate() const;
};

struct FaceFeatures {
    // #F×3 ENVT eigenvalues λ1 ≥ λ2 ≥ λ3 ≥ 0 per face (Eq. 2.27–2.28), with Gaussian weights
    // w_ij = exp(−|c_i − c_j|² / (2 (r/2)²)) and area weights; trace 1, so a plane gives
    // (1, 0, 0), a right-angled edge (½, ½, 0) and a cube corner (⅓, ⅓, ⅓).
    Eigen::MatrixX3d eigenvalues;
    Eigen::VectorXd strength;        // #F feature strength s_f = λ2 + λ3 (Eq. 2.30)
    // #F dual-mesh mean curvature (Eq. 2.32), 1/length unit:
    // H_i = Σ_{j∈Ω_i, j≠i} A_j κ_ij / Σ A_j with κ_ij = 2 ⟨n_i, c_j − c_i⟩ / |c_j − c_i|².
    // The thesis prints |c_j − c_i| in the denominator; the square is what makes κ_ij a
    // curvature (Eq. 2.10 from the Taylor expansion n·(q − p) = κ|q − p|²/2). Sign: negative
    // where the surface bends away from its normal (a sphere with outward normals: −1/R).
    Eigen::VectorXd mean_curvature;
    double radius = 0.0;             // radius used (length unit)
};

[[nodiscard]] FaceFeatures face_features(const Vertices& V,
                                         const Faces& F,
                                         const FeatureParams& params = {});

}  // namespace octshape::mesh
