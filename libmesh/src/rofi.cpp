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

// Current normal, area and centroid of a face, packed in one cache line: the filter reads them
// for ~10–20 neighbours per face.
struct alignas(64) FaceRecord {
    double n[3];
    double area;
    double c[3];
    double unused;
};

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
    const detail::DenoiseSetup setup =
        detail::prepare_denoise(V, F, std::nullopt, params.radius_factor, params.fix_boundary,
                                params.iterations, params.threads, result);
    if (!setup.run) return result;

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
    std::vector<detail::FaceState> faces(static_cast<std::size_t>(m));
    std::vector<FaceRecord> current(static_cast<std::size_t>(m));
    Vertices next(n, 3);
    // The weight f g of a pair (Eq. 5.1 without a_j) is symmetric in i and j, and bit for bit
    // so (|c_i − c_j|² and |n_i − n_j|² square the same differences up to sign). Where j ∈ Ω_i
    // and i ∈ Ω_j (nearly always), the row of the larger index computes it once and writes
    // both slots; `mirror[p]` is the slot of the pair in row j (−1 if i ∉ Ω_j, −2 if the other
    // row computes it). Each slot has one writer, so any thread count gives the same bits.
    const std::vector<int> mirror = mirror_slots(omega);
    std::vector<double> pair_weight(omega.items.size());
    double lambda = params.lambda_i;
    for (int it = 0; it < params.iterations; ++it) {
        detail::parallel_for(m, params.threads, [&](int begin, int end) {
            detail::update_faces(result.V, F, begin, end, faces.data());
            for (int f = begin; f < end; ++f) {
                const detail::FaceState& s = faces[static_cast<std::size_t>(f)];
                current[static_cast<std::size_t>(f)] = {
                    {s.normal[0], s.normal[1], s.normal[2]}, s.area,
                    {s.centroid[0], s.centroid[1], s.centroid[2]}, 0.0};
            }
        });
        // f(|c_i − c_j|; σ_c) g(|n_i − n_j|; σ_s) for every pair of Ω.
        detail::parallel_for(m, params.threads, [&](int begin, int end) {
            const int* off = omega.offsets.data();
            const int* items = omega.items.data();
            const int* mir = mirror.data();
            const FaceRecord* rec = current.data();
            double* weight = pair_weight.data();
            for (int i = begin; i < end; ++i) {
                const FaceRecord& fi = rec[i];
                for (int p = off[i]; p < off[i + 1]; ++p) {
                    const int q = mir[p];
                    if (q == -2) continue;  // written by row items[p]
                    const FaceRecord& fj = rec[items[p]];
                    const double dx = fi.n[0] - fj.n[0];
                    const double dy = fi.n[1] - fj.n[1];
                    const double dz = fi.n[2] - fj.n[2];
                    const double x2 = dx * dx + dy * dy + dz * dz;  // |n_i − n_j|²
                    const double cx = fi.c[0] - fj.c[0];
                    const double cy = fi.c[1] - fj.c[1];
                    const double cz = fi.c[2] - fj.c[2];
                    const double d2 = cx * cx + cy * cy + cz * cz;  // |c_i − c_j|²
                    double w = 0.0;
                    if (tukey) {
                        // Eq. 5.3 without its constant ½ (it cancels in K_i): (1 − x²/σ_s²)²
                        // for x ≤ σ_s, else 0 — no diffusion across the cut-off.
                        const double t = 1.0 - x2 * inv_s2;
                        if (t > 0.0) w = t * t * std::exp(-d2 * inv_two_sc2);
                    } else {
                        w = std::exp(-d2 * inv_two_sc2 - x2 * inv_two_s2);
                    }
                    weight[p] = w;
                    if (q >= 0) weight[q] = w;
                }
            }
        });
        // Eq. 5.1: bilateral average of the normals of Ω_i (K_i cancels in the normalisation).
        detail::parallel_for(m, params.threads, [&](int begin, int end) {
            const int* off = omega.offsets.data();
            const int* items = omega.items.data();
            const FaceRecord* rec = current.data();
            const double* weight = pair_weight.data();
            for (int i = begin; i < end; ++i) {
                double sx = 0.0;
                double sy = 0.0;
                double sz = 0.0;
                for (int p = off[i]; p < off[i + 1]; ++p) {
                    const FaceRecord& fj = rec[items[p]];
                    const double w = fj.area * weight[p];
                    sx += w * fj.n[0];
                    sy += w * fj.n[1];
                    sz += w * fj.n[2];
                }
                const double len = std::sqrt(sx * sx + sy * sy + sz * sz);
                double* out = faces[static_cast<std::size_t>(i)].normal;
                if (len > 0.0) {
                    out[0] = sx / len;
                    out[1] = sy / len;
                    out[2] = sz / len;
                }  // else: keep n_i (already in faces[i].normal)
            }
        });
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
