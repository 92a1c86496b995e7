#pragma once
// RoFi: robust and high-fidelity mesh denoising (thesis §5.1; docs/algorithms/rofi.md).
//
// Each iteration: (1) every face normal is replaced by the bilateral average of the normals
// in its geometric disk Ω_i (Eq. 5.1): weight a_j f(|c_i − c_j|; σ_c) g(|n_i − n_j|; σ_s),
// f Gaussian, g Tukey's bi-weight (Eq. 5.3) or Gaussian; the centre face is included.
// (2) every interior vertex takes one gradient step (Eq. 5.9):
//   v_i ← v_i + 1/(3|F_v(i)|) Σ_{k∈F_v(i)} Σ_{j∈f_k, j≠i} (ñ_k·(v_j − v_i)) ñ_k + λ_I R_i,
// with the edge term written ñ_k·(v_j − v_i) (the printed v_i − v_j is a sign typo: this sign
// moves v_i onto the planes of its faces), R_i = D_i + D_t,i (Eq. 5.5–5.8) and
// w_ij = |v_i − v_j|². (3) λ_I ← decay · λ_I (decay 0.6, §5.1.2).
// Boundary vertices stay fixed. Every face and vertex is computed from the previous
// iteration's state only, so the result is bit-identical for any thread count.

#include <functional>

#include "octshape/mesh/denoise.h"
#include "octshape/mesh/mesh.h"
#include "octshape/mesh/simd_exp.h"

namespace octshape::mesh {

enum class Similarity {
    kTukey,     // Eq. 5.3: g = ½ (1 − (x/σ_s)²)² for x ≤ σ_s, else 0 (RoFi)
    kGaussian,  // g = exp(−x² / (2 σ_s²)) (classic bilateral normal filtering, Zheng et al.)
};

// How the pair weights f·g of Eq. 5.1 are computed; both give bit-identical results (the
// weight is symmetric in i and j bit for bit). docs/algorithms/rofi.md, "Memory".
enum class PairWeights {
    kShared,  // once per pair, read by both rows: ≈ 12 bytes per slot of Ω, fastest
    kPerRow,  // in each row, nothing stored: 4 bytes per slot, ~15–25 % more time per iteration
};

// The residual r_i = n̂_i · (v⁰_i − v_i) after an iteration: the input vertex v⁰_i against the
// current v_i along the current vertex normal n̂_i (area-weighted face normals); free vertices.
struct RofiProgress {
    double displacement = 0;  // δ = RMS of r_i (length unit)
    // W = Σ_i (r_i − mean_{j∈ring(i)} r_j)² / (1 + 1/k_i) / Σ_i r_i² over the free vertices
    // with k_i ≥ 3 ring neighbours not on a feature (two of their faces' current normals
    // further apart than σ_s, |n_a − n_b| > σ_s): 1 in expectation for white noise; > 1 while
    // the removed part is rougher than white noise; < 1 once it is smoother, i.e. holds the
    // surface's own relief.
    double whiteness = 0;
    int tested_vertices = 0;  // N, the vertices in W's sums
    // RofiStop::kWhiteResidual stops when W ≤ 1 − 1.5/√N: W below 1 by two of its standard
    // errors for white Gaussian residuals, ≈ 0.75/√N (rofi.md, "Stopping").
    double threshold = 0;
    // The same residual split by W's feature test: its RMS over the free vertices on a feature
    // (left out of W) and over W's vertices, and their count (rofi.md, "Stopping": the crease
    // term measured and not kept).
    int feature_vertices = 0;
    double feature_rms = 0;
    double flat_rms = 0;
};

enum class RofiStop {
    kNone,           // run all `iterations`
    kWhiteResidual,  // stop before the first iteration at whose start W ≤ its threshold
};

struct RofiParams {
    double sigma_s = 0.5;       // similarity width σ_s on x = |n_i − n_j| ∈ [0, 2], Eq. 5.3
    double lambda_i = 0.2;      // initial isotropic (fidelity) factor λ_I, Eq. 5.9; ≥ 0
    int iterations = 100;       // p (the maximum with a stop); 0 returns the input unchanged
    double lambda_decay = 0.6;  // λ_I^{p+1} = decay · λ_I^p (§5.1.2); in [0, 1]
    double radius_factor = 2.0;   // disk radius r = radius_factor · c_a (§5.2); > 0
    double sigma_c_factor = 1.0;  // closeness width σ_c = sigma_c_factor · c_a (§5.2); > 0
    Similarity similarity = Similarity::kTukey;
    PairWeights pair_weights = PairWeights::kShared;
    bool fix_boundary = true;   // keep boundary / non-manifold vertices in place
    // After the last iteration, repair fold-overs (folds.h: faces turned over against an
    // edge-neighbour, n_a · n_b < −0.9; their apex moves to its 1-ring centroid). Not in
    // Eq. 5.1–5.9 (docs/algorithms/rofi.md, "Fold-overs"); false = the equations alone.
    bool repair_folds = true;
    // When to stop (docs/algorithms/rofi.md, "Stopping"); kWhiteResidual makes `iterations`
    // the maximum.
    RofiStop stop = RofiStop::kNone;
    // Called after every iteration k = 1, 2, … with the vertices (before the fold repair) and
    // the residual's measures (RofiProgress); for measurements (bench/). Empty = none.
    std::function<void(int iteration, const Vertices& V, const RofiProgress& progress)> observer;
    // Called after every iteration k = 1, 2, … with k and `iterations` (the maximum), from
    // the calling thread; for progress reports (`octshape denoise` on large meshes). Unlike
    // `observer` it costs nothing measured. Empty = none.
    std::function<void(int iteration, int iterations)> progress;
    int threads = 1;            // std::threads; results do not depend on it; ≥ 1
    // Instruction set of the vector kernels; results do not depend on it (simd_exp.h).
    // kAvx2 / kAvx512 need a CPU with AVX2 / AVX-512.
    SimdPath simd = SimdPath::kBest;

    // Throws UsageError naming the first bad field.
    void validate() const;
};

// Denoises (V, F). Throws UsageError for bad parameters, DataError for an invalid mesh.
[[nodiscard]] DenoiseResult rofi_denoise(const Vertices& V,
                                         const Faces& F,
                                         const RofiParams& params);

// Parameters chosen from a noise estimate (docs/algorithms/rofi.md says how and shows the
// measurements behind it). `similarity` and `threads` are left at their defaults.
// Since session 9 it stops by RofiStop::kWhiteResidual, with `iterations` the maximum.
[[nodiscard]] RofiParams auto_rofi_params(const NoiseEstimate& noise);

// The automatic rule of session 8 (fixed p = 30, no stop): kept for comparison (tests,
// bench/rofi_autostop).
[[nodiscard]] RofiParams fixed_p_rofi_params(const NoiseEstimate& noise);

// The automatic rule with the paper's disk (r = 2 c_a, σ_c = c_a; σ_s = clamp(1.7 θ, 0.1, 1),
// p = 80, λ_I as auto_rofi_params): the automatic rule before session 8. `--method bilateral`
// takes its σ_s and p (the classic filter for comparison keeps its disk), and the tests check
// auto_rofi_params against it.
[[nodiscard]] RofiParams paper_disk_rofi_params(const NoiseEstimate& noise);

}  // namespace octshape::mesh
