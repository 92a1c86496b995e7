#include "octshape/mesh/rofi.h"

#include <chrono>
#include <cmath>
#include <stdexcept>
#include <string>

#include "parallel.h"
#include "vertex_update.h"

namespace octshape::mesh {
namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t0) {
    return std::chrono::duration<double>(Clock::now() - t0).count();
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
    result.V = V;
    const auto t0 = Clock::now();
    const auto n = static_cast<int>(V.rows());
    const auto m = static_cast<int>(F.rows());
    const Adjacency adj = build_adjacency(F, n);
    if (adj.nonmanifold_edges > 0) {
        result.warnings.push_back(std::to_string(adj.nonmanifold_edges) +
                                  " non-manifold edges: their vertices are kept fixed");
    }
    FaceGeometry geometry = face_geometry(V, F);
    const double ca = mean_centroid_distance(geometry, adj);
    result.mean_centroid_distance = ca;
    result.radius = params.radius_factor * ca;
    std::vector<std::uint8_t> fixed(static_cast<std::size_t>(n), 0);
    if (params.fix_boundary) fixed = adj.boundary_vertex;
    for (const auto f : fixed) result.fixed_vertices += f;
    if (params.iterations == 0 || m == 0 || !(ca > 0.0)) {
        result.seconds_setup = seconds_since(t0);
        return result;
    }
    const Csr omega = disk_neighbourhoods(F, geometry, adj, result.radius, params.threads);
    result.mean_neighbourhood = static_cast<double>(omega.items.size()) / m;
    result.seconds_setup = seconds_since(t0);

    const auto t1 = Clock::now();
    const double sigma_c = params.sigma_c_factor * ca;
    const double inv_two_sc2 = 1.0 / (2.0 * sigma_c * sigma_c);
    const double s2 = params.sigma_s * params.sigma_s;
    const double inv_s2 = 1.0 / s2;
    const double inv_two_s2 = 1.0 / (2.0 * s2);
    const bool tukey = params.similarity == Similarity::kTukey;
    Vertices filtered(m, 3);
    Vertices next(n, 3);
    // Normal, centroid and area of each face packed in one cache line: the filter reads them
    // for ~10–20 neighbours per face.
    struct alignas(64) FaceRecord {
        double n[3];
        double c[3];
        double area;
    };
    std::vector<FaceRecord> faces(static_cast<std::size_t>(m));
    double lambda = params.lambda_i;
    for (int it = 0; it < params.iterations; ++it) {
        detail::parallel_for(m, params.threads, [&](int begin, int end) {
            for (int f = begin; f < end; ++f) {
                if (it > 0) {
                    const Eigen::Vector3d a = result.V.row(F(f, 0));
                    const Eigen::Vector3d b = result.V.row(F(f, 1));
                    const Eigen::Vector3d c = result.V.row(F(f, 2));
                    const Eigen::Vector3d cross = (b - a).cross(c - a);
                    const double norm = cross.norm();
                    geometry.areas(f) = 0.5 * norm;
                    geometry.normals.row(f) =
                        norm > 0.0 ? Eigen::Vector3d(cross / norm) : Eigen::Vector3d::Zero();
                    geometry.centroids.row(f) = (a + b + c) / 3.0;  // Eq. 2.31
                }
                FaceRecord& r = faces[static_cast<std::size_t>(f)];
                for (int k = 0; k < 3; ++k) {
                    r.n[k] = geometry.normals(f, k);
                    r.c[k] = geometry.centroids(f, k);
                }
                r.area = geometry.areas(f);
            }
        });
        // Eq. 5.1: bilateral average of the normals of Ω_i.
        detail::parallel_for(m, params.threads, [&](int begin, int end) {
            for (int i = begin; i < end; ++i) {
                const FaceRecord& fi = faces[static_cast<std::size_t>(i)];
                double sx = 0.0;
                double sy = 0.0;
                double sz = 0.0;
                for (int p = omega.begin(i); p < omega.end(i); ++p) {
                    const FaceRecord& fj = faces[static_cast<std::size_t>(omega.item(p))];
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
                        if (x2 > s2) continue;  // Eq. 5.3: no diffusion across the cut-off
                        const double t = 1.0 - x2 * inv_s2;
                        w = fj.area * 0.5 * t * t * std::exp(-d2 * inv_two_sc2);
                    } else {
                        w = fj.area * std::exp(-d2 * inv_two_sc2 - x2 * inv_two_s2);
                    }
                    sx += w * fj.n[0];
                    sy += w * fj.n[1];
                    sz += w * fj.n[2];
                }
                const double len = std::sqrt(sx * sx + sy * sy + sz * sz);
                if (len > 0.0) {
                    filtered.row(i) << sx / len, sy / len, sz / len;
                } else {
                    filtered.row(i) << fi.n[0], fi.n[1], fi.n[2];
                }
            }
        });
        // Eq. 5.9.
        detail::parallel_for(n, params.threads, [&](int begin, int end) {
            detail::vertex_step(result.V, filtered, geometry, adj, fixed, lambda, begin, end,
                                next);
        });
        result.V.swap(next);
        lambda *= params.lambda_decay;
        ++result.iterations;
    }
    result.seconds_iterations = seconds_since(t1);
    return result;
}

}  // namespace octshape::mesh
