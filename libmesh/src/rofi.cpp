#include "octshape/mesh/rofi.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <string>

#include "parallel.h"
#include "denoise_setup.h"

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

    // f(|c_i − c_j|; σ_c) g(|n_i − n_j|; σ_s) of the pair in slot p of row i, written to slot
    // p and to the mirror slot in row j.
    template <bool kTukey>
    [[nodiscard]] double pair_weight(const detail::FaceState& fi,
                                     const detail::FaceState& fj) const {
        const double dx = fi.normal[0] - fj.normal[0];
        const double dy = fi.normal[1] - fj.normal[1];
        const double dz = fi.normal[2] - fj.normal[2];
        const double x2 = dx * dx + dy * dy + dz * dz;  // |n_i − n_j|²
        const double cx = fi.centroid[0] - fj.centroid[0];
        const double cy = fi.centroid[1] - fj.centroid[1];
        const double cz = fi.centroid[2] - fj.centroid[2];
        const double d2 = cx * cx + cy * cy + cz * cz;  // |c_i − c_j|²
        double w = 0.0;
        if constexpr (kTukey) {
            // Eq. 5.3 without its constant ½ (it cancels in K_i): (1 − x²/σ_s²)² for x ≤ σ_s,
            // else 0 — no diffusion across the cut-off, and no exp() for such a pair.
            const double t = 1.0 - x2 * inv_s2;
            if (t > 0.0) w = t * t * std::exp(-d2 * inv_two_sc2);
        } else {
            w = std::exp(-d2 * inv_two_sc2 - x2 * inv_two_s2);
        }
        return w;
    }

    // f(|c_i − c_j|; σ_c) g(|n_i − n_j|; σ_s) of the pair in slot p of row i, written to slot
    // p and to the mirror slot in row j.
    template <bool kTukey>
    void pair(const detail::FaceState& fi, int p) const {
        const double w = pair_weight<kTukey>(fi, rec[items[p]]);
        weight[p] = w;
        const int q = mir[p];
        if (q >= 0) weight[q] = w;
    }

    // The pairs row i computes: the neighbours j < i (a row lists ascending indices after
    // f_i), then the rare j > i with i ∉ Ω_j.
    template <bool kTukey>
    void row_pairs(int i) const {
        const detail::FaceState& fi = rec[i];
        int p = off[i] + 1;
        const int e = off[i + 1];
        for (; p < e && items[p] < i; ++p) pair<kTukey>(fi, p);
        for (; p < e; ++p) {
            if (mir[p] == -1) pair<kTukey>(fi, p);
        }
    }

    // Eq. 5.1: ñ_i = normalise(Σ_j a_j w_ij n_j) over Ω_i in row order (K_i cancels in the
    // normalisation); the centre face has w = 1. Writes out[i]. kStored: the weights from
    // `weight` (row_pairs); otherwise computed here (PairWeights::kPerRow), the same bits.
    template <bool kStored, bool kTukey>
    void row_sum(int i) const {
        const detail::FaceState& fi = rec[i];
        // 0.0 + keeps the bits of a sum that starts from zero (−0 becomes +0).
        double sx = 0.0 + fi.area * fi.normal[0];
        double sy = 0.0 + fi.area * fi.normal[1];
        double sz = 0.0 + fi.area * fi.normal[2];
        const int e = off[i + 1];
        for (int p = off[i] + 1; p < e; ++p) {
            const detail::FaceState& fj = rec[items[p]];
            double wp = 0.0;
            if constexpr (kStored) {
                wp = weight[p];
            } else {
                wp = pair_weight<kTukey>(fi, fj);
            }
            const double w = fj.area * wp;
            sx += w * fj.normal[0];
            sy += w * fj.normal[1];
            sz += w * fj.normal[2];
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
    double lambda = params.lambda_i;
    for (int it = 0; it < params.iterations; ++it) {
        detail::parallel_for(m, params.threads, [&](int begin, int end) {
            detail::update_faces(result.V, F, begin, end, current.data());
        });
        if (shared) {
            // The pair weights (each row writes its own pairs and their mirror slots), then
            // the sums: two passes, so that every slot is written before any row reads it.
            detail::parallel_for(m, params.threads, [&](int begin, int end) {
                for (int i = begin; i < end; ++i) {
                    if (tukey) {
                        kernel.row_pairs<true>(i);
                    } else {
                        kernel.row_pairs<false>(i);
                    }
                }
            });
            detail::parallel_for(m, params.threads, [&](int begin, int end) {
                for (int i = begin; i < end; ++i) kernel.row_sum<true, true>(i);
            });
        } else {
            detail::parallel_for(m, params.threads, [&](int begin, int end) {
                for (int i = begin; i < end; ++i) {
                    if (tukey) {
                        kernel.row_sum<false, true>(i);
                    } else {
                        kernel.row_sum<false, false>(i);
                    }
                }
            });
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
    result.seconds_iterations = seconds_since(t1);
    return result;
}

}  // namespace octshape::mesh
