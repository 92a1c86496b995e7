#pragma once
// Private to libmesh: what RoFi (rofi.cpp) and ENVT (envt.cpp) share — the set-up before the
// first iteration, the packed per-face state of an iteration and the vertex step (Eq. 5.9 /
// Eq. 3.7).

#include <chrono>
#include <cstdint>
#include <optional>
#include <utility>
#include <vector>

#include "octshape/mesh/denoise.h"
#include "octshape/mesh/mesh.h"

namespace octshape::mesh::detail {

// The mesh a denoiser iterates on, renumbered for locality (docs/algorithms/rofi.md,
// "Issue 35 (session 21)"): faces sorted along a Morton (Z-order) curve of their centroids
// (10 bits per axis over the centroids' bounding cube; ties keep the input's order), each
// face's corners in the input's order; vertices numbered in order of first appearance in the
// new face list, corner by corner; a vertex no face uses is left out. So the faces of a disk
// Ω_i and the stars of neighbouring vertices lie close together in memory whatever the
// input's order: the caller's numbering only decides the order of equal keys.
struct LocalOrder {
    Vertices V;               // the used vertices, renumbered
    Faces F;                  // the faces, reordered and renamed
    std::vector<int> vertex;  // vertex[k] = the caller's index of vertex k of V
};

[[nodiscard]] LocalOrder local_order(const Vertices& V, const Faces& F);

// out.row(order.vertex[k]) = X.row(k) for every k: X (in the local numbering) back into the
// caller's; the rows of `out` no face uses are left as they are.
void to_caller_order(const Vertices& X, const LocalOrder& order, Vertices& out);

// A denoiser on the renumbered mesh: `denoise(local)` runs it on local.V and local.F; its
// result comes back with V in the caller's numbering (rows no face uses: as in V) and the
// renumbering's time added to seconds_setup. RoFi and ENVT both call it.
template <class Denoise>
[[nodiscard]] DenoiseResult denoise_in_local_order(const Vertices& V, const Faces& F,
                                                   Denoise&& denoise) {
    using Clock = std::chrono::steady_clock;
    const auto t0 = Clock::now();
    const LocalOrder local = local_order(V, F);
    const auto t1 = Clock::now();
    DenoiseResult result = denoise(local);
    const auto t2 = Clock::now();
    Vertices out = V;
    to_caller_order(result.V, local, out);
    result.V = std::move(out);
    result.seconds_setup += std::chrono::duration<double>(t1 - t0).count() +
                            std::chrono::duration<double>(Clock::now() - t2).count();
    return result;
}

// Everything a denoiser needs before its first iteration.
struct DenoiseSetup {
    Adjacency adjacency;               // of F
    FaceGeometry geometry;             // of the input V
    std::vector<std::uint8_t> fixed;   // #V, 1 = kept in place (boundary / non-manifold)
    Csr omega;                         // disk neighbourhoods Ω_i (f_i first); empty if !run
    bool run = false;                  // false: nothing to iterate (return result.V = V)
};

// Builds adjacency, geometry, c_a, the fixed vertices and (when there is something to
// iterate) Ω_i of radius `radius` if given, else radius_factor · c_a. Fills result.V = V and
// the set-up fields of `result` (c_a, radius, |Ω_i|, fixed count, warnings, seconds_setup).
[[nodiscard]] DenoiseSetup prepare_denoise(const Vertices& V,
                                           const Faces& F,
                                           std::optional<double> radius,
                                           double radius_factor,
                                           bool fix_boundary,
                                           int iterations,
                                           int threads,
                                           DenoiseResult& result);

// Per-face state of one iteration read by the vertex step: the filtered unit normal ñ_k, the
// current area a_k and centroid c_k, packed in one cache line.
struct alignas(64) FaceState {
    double normal[3];
    double area;
    double centroid[3];
    double unused;
};

// Recomputes normal (into `normal`), area and centroid of faces [begin, end) from V. avx2:
// run the AVX2 copy (the CPU must have AVX2; the same bits as the baseline copy).
void update_faces(const Vertices& V, const Faces& F, int begin, int end, FaceState* faces,
                  bool avx2);

// One Jacobi step for vertices [begin, end): out.row(i) from V, the per-face state (normal =
// the FILTERED normal ñ_k) and λ_I (0 = ENVT / plain orthogonality step):
//   v_i + 1/|F_v(i)| Σ_k (ñ_k·(c_k − v_i)) ñ_k + λ_I R_i
// which equals 1/(3|F_v(i)|) Σ_k Σ_{j∈f_k, j≠i} (ñ_k·(v_j − v_i)) ñ_k (Eq. 5.9, 3.7) because
// Σ_{j∈f_k, j≠i} (v_j − v_i) = 3 (c_k − v_i). R_i = D_i + D_t,i (Eq. 5.5–5.8). Fixed vertices
// and vertices without faces are copied. avx2: run the AVX2 copy (the CPU must have AVX2;
// the same bits as the baseline copy).
void vertex_step(const Vertices& V,
                 const FaceState* faces,
                 const Adjacency& adjacency,
                 const std::vector<std::uint8_t>& fixed,
                 double lambda_i,
                 int begin,
                 int end,
                 Vertices& out,
                 bool avx2);

}  // namespace octshape::mesh::detail
