#include "octshape/mesh/rofi.h"

#include "octshape/mesh/simd_exp.h"
#include "octshape/mesh/folds.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <string>

#include "denoise_setup.h"
#include "parallel.h"
#include "simd.h"

namespace octshape::mesh {
namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t0) {
    return std::chrono::duration<double>(Clock::now() - t0).count();
}

// For each slot p of Ω (row i, item j): the slot of i in row j if j < i and i ∈ Ω_j (this row
// computes the pair and also writes there), −2 if j > i and j's row will write slot p, −1
// otherwise (this row computes the pair for itself alone; also the centre face j = i).
// Rows list f_i first and then ascending indices (mesh.h), so row j is searched by bisection.
std::vector<int> mirror_slots(const Csr& omega) {
    std::vector<int> out(omega.items.size(), -1);
    const auto find = [&](int row, int item) {
        const auto first = omega.items.begin() + omega.begin(row) + 1;
        const auto last = omega.items.begin() + omega.end(row);
        const auto it = std::lower_bound(first, last, item);
        return it != last && *it == item ? static_cast<int>(it - omega.items.begin()) : -1;
    };
    for (int i = 0; i < omega.rows(); ++i) {
        for (int p = omega.begin(i) + 1; p < omega.end(i); ++p) {
            const int j = omega.item(p);
            if (j < i) {
                const int q = find(j, i);
                if (q >= 0) {
                    out[static_cast<std::size_t>(p)] = q;
                    out[static_cast<std::size_t>(q)] = -2;
                }
            }
        }
    }
    return out;
}

// The per-row work of Eq. 5.1 on flat arrays (Ω in CSR, the slot weights, the face records).
// The pair weights are computed four pairs at a time (detail::V4d lanes, simd.h); each lane
// does the same operations whatever lanes it shares a vector with, so a weight has the same
// bits in either pass, in either PairWeights mode and on either instruction set.
struct PairKernel {
    const int* off;                   // Ω offsets
    const int* items;                 // Ω items: f_i, then ascending indices
    const int* mir;                   // mirror_slots(Ω)
    double* weight;                   // f g per slot (the centre slot unused: its weight is 1)
    const detail::FaceState* rec;     // current normal, area, centroid
    detail::FaceState* out;           // filtered normal ñ_i, area, centroid
    double inv_s2;                    // 1 / σ_s²
    double inv_two_sc2;               // 1 / (2 σ_c²)
    double inv_two_s2;                // 1 / (2 σ_s²)

    // f(|c_i − c_j|; σ_c) g(|n_i − n_j|; σ_s) of the pairs (i, j[l]), lane l.
    template <bool kTukey>
    [[gnu::always_inline]] void weights4(const detail::FaceState& fi, const int* j,
                                         detail::V4d& w) const {
        using detail::splat;
        using detail::V4d;
        const detail::FaceState& a = rec[j[0]];
        const detail::FaceState& b = rec[j[1]];
        const detail::FaceState& c = rec[j[2]];
        const detail::FaceState& d = rec[j[3]];
        const V4d dx = splat(fi.normal[0]) - V4d{a.normal[0], b.normal[0], c.normal[0], d.normal[0]};
        const V4d dy = splat(fi.normal[1]) - V4d{a.normal[1], b.normal[1], c.normal[1], d.normal[1]};
        const V4d dz = splat(fi.normal[2]) - V4d{a.normal[2], b.normal[2], c.normal[2], d.normal[2]};
        const V4d x2 = dx * dx + dy * dy + dz * dz;  // |n_i − n_j|²
        const V4d cx =
            splat(fi.centroid[0]) - V4d{a.centroid[0], b.centroid[0], c.centroid[0], d.centroid[0]};
        const V4d cy =
            splat(fi.centroid[1]) - V4d{a.centroid[1], b.centroid[1], c.centroid[1], d.centroid[1]};
        const V4d cz =
            splat(fi.centroid[2]) - V4d{a.centroid[2], b.centroid[2], c.centroid[2], d.centroid[2]};
        const V4d d2 = cx * cx + cy * cy + cz * cz;  // |c_i − c_j|²
        if constexpr (kTukey) {
            // Eq. 5.3 without its constant ½ (it cancels in K_i): (1 − x²/σ_s²)² for x ≤ σ_s,
            // else 0 — no diffusion across the cut-off. Eq. 5.2's Gaussian closeness.
            const V4d t = splat(1.0) - x2 * splat(inv_s2);
            V4d e{};
            detail::exp_lanes(-d2 * splat(inv_two_sc2), e);
            w = t > splat(0.0) ? t * t * e : splat(0.0);
        } else {
            detail::exp_lanes(-d2 * splat(inv_two_sc2) - x2 * splat(inv_two_s2), w);
        }
    }

    // The weights of row i's slots [p0, p1) into w[0 .. p1 − p0).
    template <bool kTukey>
    [[gnu::always_inline]] void row_weights(int i, int p0, int p1, double* w) const {
        const detail::FaceState& fi = rec[i];
        int p = p0;
        detail::V4d v{};
        for (; p + 4 <= p1; p += 4) {
            weights4<kTukey>(fi, items + p, v);
            for (int l = 0; l < 4; ++l) w[p - p0 + l] = v[l];
        }
        if (p < p1) {  // the last 1–3 slots; the other lanes pair f_i with itself, unused
            int j[4] = {i, i, i, i};
            for (int l = 0; p + l < p1; ++l) j[l] = items[p + l];
            weights4<kTukey>(fi, j, v);
            for (int l = 0; p + l < p1; ++l) w[p - p0 + l] = v[l];
        }
    }

    // The pairs row i computes: the neighbours j < i (a row lists ascending indices after
    // f_i), written to their slots and mirror slots, then the rare j > i with i ∉ Ω_j.
    template <bool kTukey>
    [[gnu::always_inline]] void row_pairs(int i) const {
        const int b = off[i] + 1;
        const int e = off[i + 1];
        int lo = b;
        while (lo < e && items[lo] < i) ++lo;
        row_weights<kTukey>(i, b, lo, weight + b);
        for (int p = b; p < lo; ++p) {
            const int q = mir[p];
            if (q >= 0) weight[q] = weight[p];
        }
        for (int p = lo; p < e; ++p) {
            if (mir[p] == -1) row_weights<kTukey>(i, p, p + 1, weight + p);
        }
    }

    // Eq. 5.1: ñ_i = normalise(Σ_j a_j w_ij n_j) over Ω_i in row order (K_i cancels in the
    // normalisation); the centre face has w = 1. Writes out[i]. kStored: the weights from
    // `weight` (row_pairs); otherwise computed here in blocks (PairWeights::kPerRow), the same
    // bits.
    template <bool kStored, bool kTukey>
    [[gnu::always_inline]] void row_sum(int i) const {
        const detail::FaceState& fi = rec[i];
        // 0.0 + keeps the bits of a sum that starts from zero (−0 becomes +0).
        double sx = 0.0 + fi.area * fi.normal[0];
        double sy = 0.0 + fi.area * fi.normal[1];
        double sz = 0.0 + fi.area * fi.normal[2];
        const int e = off[i + 1];
        constexpr int kBlock = 64;
        double block[kBlock];
        for (int p0 = off[i] + 1; p0 < e; p0 += kBlock) {
            const int p1 = std::min(e, p0 + kBlock);
            const double* wp = weight + p0;
            if constexpr (!kStored) {
                row_weights<kTukey>(i, p0, p1, block);
                wp = block;
            }
            for (int p = p0; p < p1; ++p) {
                const detail::FaceState& fj = rec[items[p]];
                const double w = fj.area * wp[p - p0];
                sx += w * fj.normal[0];
                sy += w * fj.normal[1];
                sz += w * fj.normal[2];
            }
        }
        const double len = std::sqrt(sx * sx + sy * sy + sz * sz);
        detail::FaceState& o = out[i];
        o = fi;
        if (len > 0.0) {  // else keep n_i
            o.normal[0] = sx / len;
            o.normal[1] = sy / len;
            o.normal[2] = sz / len;
        }
    }
};

// The passes over rows [begin, end), one copy per instruction set (simd.h): kind 0 = the
// shared pair weights, 1 = the sums from them, 2 = the sums with the weights computed per row.
template <bool kTukey>
[[gnu::always_inline]] inline void rows_impl(const PairKernel& k, int kind, int begin,
                                             int end) {
    if (kind == 0) {
        for (int i = begin; i < end; ++i) k.row_pairs<kTukey>(i);
    } else if (kind == 1) {
        for (int i = begin; i < end; ++i) k.row_sum<true, kTukey>(i);
    } else {
        for (int i = begin; i < end; ++i) k.row_sum<false, kTukey>(i);
    }
}

void rows_baseline(const PairKernel& k, bool tukey, int kind, int begin, int end) {
    if (tukey) {
        rows_impl<true>(k, kind, begin, end);
    } else {
        rows_impl<false>(k, kind, begin, end);
    }
}

__attribute__((target("avx2"))) void rows_avx2(const PairKernel& k, bool tukey, int kind,
                                               int begin, int end) {
    if (tukey) {
        rows_impl<true>(k, kind, begin, end);
    } else {
        rows_impl<false>(k, kind, begin, end);
    }
}

// One body for both paths (inlined into each, compiled for its instruction set).
[[gnu::always_inline]] inline void exp_impl(const double* x, double* out, std::size_t n) {
    detail::V4d e{};
    for (std::size_t i = 0; i < n; i += 4) {
        const auto at = [&](std::size_t l) { return i + l < n ? x[i + l] : 0.0; };
        const detail::V4d v{at(0), at(1), at(2), at(3)};
        detail::exp_lanes(v, e);
        for (std::size_t l = 0; l < 4 && i + l < n; ++l) out[i + l] = e[l];
    }
}

__attribute__((target("avx2"))) void exp_avx2(const double* x, double* out, std::size_t n) {
    exp_impl(x, out, n);
}

void exp_baseline(const double* x, double* out, std::size_t n) { exp_impl(x, out, n); }

void require(bool ok, const std::string& field, const std::string& rule, double value) {
    if (!ok) {
        throw std::invalid_argument("RofiParams." + field + " must be " + rule + ", got " +
                                    std::to_string(value));
    }
}

}  // namespace

void RofiParams::validate() const {
    require(std::isfinite(sigma_s) && sigma_s > 0.0, "sigma_s", "finite and > 0", sigma_s);
    require(std::isfinite(lambda_i) && lambda_i >= 0.0, "lambda_i", "finite and >= 0", lambda_i);
    require(iterations >= 0, "iterations", ">= 0", iterations);
    require(lambda_decay >= 0.0 && lambda_decay <= 1.0, "lambda_decay", "in [0, 1]",
            lambda_decay);
    require(std::isfinite(radius_factor) && radius_factor > 0.0, "radius_factor",
            "finite and > 0", radius_factor);
    require(std::isfinite(sigma_c_factor) && sigma_c_factor > 0.0, "sigma_c_factor",
            "finite and > 0", sigma_c_factor);
    require(threads >= 1, "threads", ">= 1", threads);
    if (simd == SimdPath::kAvx2 && !simd_avx2_available()) {
        throw std::invalid_argument("RofiParams.simd is kAvx2 but this CPU has no AVX2");
    }
}

bool simd_avx2_available() {
    static const bool available = __builtin_cpu_supports("avx2") != 0;
    return available;
}

void simd_exp_nonpositive(const double* x, double* out, std::size_t n, SimdPath path) {
    if (path == SimdPath::kAvx2 && !simd_avx2_available()) {
        throw std::invalid_argument("simd_exp_nonpositive: SimdPath::kAvx2 on a CPU without AVX2");
    }
    const bool avx2 = path == SimdPath::kAvx2 || (path == SimdPath::kBest && simd_avx2_available());
    if (avx2) {
        exp_avx2(x, out, n);
    } else {
        exp_baseline(x, out, n);
    }
}

DenoiseResult rofi_denoise(const Vertices& V, const Faces& F, const RofiParams& params) {
    params.validate();
    validate_mesh(V, F);
    DenoiseResult result;
    detail::DenoiseSetup setup =
        detail::prepare_denoise(V, F, std::nullopt, params.radius_factor, params.fix_boundary,
                                params.iterations, params.threads, result);
    if (!setup.run) return result;
    // Not read by the iterations: the input's face geometry (56 bytes a face) and the
    // face-face adjacency (~16 bytes a face) are released before the iteration arrays exist.
    setup.geometry = FaceGeometry{};
    setup.adjacency.face_faces = Csr{};

    const auto t1 = Clock::now();
    const auto n = static_cast<int>(V.rows());
    const auto m = static_cast<int>(F.rows());
    const Csr& omega = setup.omega;
    const double sigma_c = params.sigma_c_factor * result.mean_centroid_distance;
    const double inv_two_sc2 = 1.0 / (2.0 * sigma_c * sigma_c);
    const double s2 = params.sigma_s * params.sigma_s;
    const double inv_s2 = 1.0 / s2;
    const double inv_two_s2 = 1.0 / (2.0 * s2);
    const bool tukey = params.similarity == Similarity::kTukey;
    // current[f]: normal, area and centroid of the current mesh; faces[f]: the same with the
    // filtered normal ñ_f (what the vertex step reads).
    std::vector<detail::FaceState> current(static_cast<std::size_t>(m));
    std::vector<detail::FaceState> faces(static_cast<std::size_t>(m));
    Vertices next(n, 3);
    // The weight f g of a pair (Eq. 5.1 without a_j) is symmetric in i and j, and bit for bit
    // so (|c_i − c_j|² and |n_i − n_j|² square the same differences up to sign). Where j ∈ Ω_i
    // and i ∈ Ω_j (nearly always), the row of the larger index computes it once and writes
    // both slots; `mirror[p]` is the slot of the pair in row j (−1 if i ∉ Ω_j, −2 if the other
    // row computes it). Each slot has one writer, so any thread count gives the same bits.
    // The centre face's own weight is exactly 1 (x = 0, d = 0: (1 − 0)² exp(−0) = 1) and is not
    // stored: the slot holds the weight from the first neighbour on.
    const bool shared = params.pair_weights == PairWeights::kShared;
    const std::vector<int> mirror = shared ? mirror_slots(omega) : std::vector<int>();
    std::vector<double> pair_weight(shared ? omega.items.size() : 0);
    PairKernel kernel{omega.offsets.data(), omega.items.data(), mirror.data(),
                      pair_weight.data(), current.data(), faces.data(), inv_s2,
                      inv_two_sc2, inv_two_s2};
    // The same bits either way (simd.h).
    const bool avx2 = params.simd == SimdPath::kAvx2 ||
                      (params.simd == SimdPath::kBest && simd_avx2_available());
    double lambda = params.lambda_i;
    for (int it = 0; it < params.iterations; ++it) {
        detail::parallel_for(m, params.threads, [&](int begin, int end) {
            detail::update_faces(result.V, F, begin, end, current.data());
        });
        const auto rows = [&](int kind) {
            detail::parallel_for(m, params.threads, [&](int begin, int end) {
                if (avx2) {
                    rows_avx2(kernel, tukey, kind, begin, end);
                } else {
                    rows_baseline(kernel, tukey, kind, begin, end);
                }
            });
        };
        if (shared) {
            // The pair weights (each row writes its own pairs and their mirror slots), then
            // the sums: two passes, so that every slot is written before any row reads it.
            rows(0);
            rows(1);
        } else {
            rows(2);
        }
        // Eq. 5.9.
        detail::parallel_for(n, params.threads, [&](int begin, int end) {
            detail::vertex_step(result.V, faces.data(), setup.adjacency, setup.fixed, lambda,
                                begin, end, next);
        });
        result.V.swap(next);
        lambda *= params.lambda_decay;
        ++result.iterations;
    }
    if (params.repair_folds && result.iterations > 0) {
        const auto t2 = Clock::now();
        const FoldRepairResult folds = repair_folds(result.V, F, setup.adjacency, setup.fixed);
        result.folds_repaired = folds.folds_found - folds.folds_left;
        result.folds_left = folds.folds_left;
        result.seconds_fold_repair = seconds_since(t2);
    }
    result.seconds_iterations = seconds_since(t1);
    return result;
}

}  // namespace octshape::mesh
