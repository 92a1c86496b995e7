#include "octshape/mesh/envt.h"

#include "octshape/error.h"
#include "octshape/mesh/simd_exp.h"
#include "octshape/mesh/folds.h"

#include <chrono>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>

#include <Eigen/Eigenvalues>

#include "parallel.h"
#include "denoise_setup.h"

namespace octshape::mesh {
namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t0) {
    return std::chrono::duration<double>(Clock::now() - t0).count();
}

void require(bool ok, const std::string& where, const std::string& rule, double value) {
    if (!ok) {
        throw UsageError(where + " must be " + rule + ", got " +
                                    std::to_string(value));
    }
}

// Eigenvalues in descending order and the matching eigenvectors (columns) of a symmetric 3×3.
struct Eigen3 {
    Eigen::Vector3d values;
    Eigen::Matrix3d vectors;
};

Eigen3 decompose(const Eigen::Matrix3d& c) {
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(c);
    Eigen3 out;
    // Eigen sorts ascending; flip to λ1 ≥ λ2 ≥ λ3.
    out.values = solver.eigenvalues().reverse();
    out.vectors = solver.eigenvectors().rowwise().reverse();
    return out;
}

}  // namespace

void EnvtParams::validate() const {
    require(std::isfinite(tau) && tau > 0.0 && tau <= 1.0, "EnvtParams.tau", "in (0, 1]", tau);
    if (radius) {
        require(std::isfinite(*radius) && *radius > 0.0, "EnvtParams.radius", "finite and > 0",
                *radius);
    }
    require(iterations >= 0, "EnvtParams.iterations", ">= 0", iterations);
    require(rho > 0.0 && rho <= std::numbers::pi, "EnvtParams.rho", "in (0, pi]", rho);
    require(std::isfinite(damping) && damping >= 0.0, "EnvtParams.damping", "finite and >= 0",
            damping);
    require(fold_repair_interval >= 0, "EnvtParams.fold_repair_interval", ">= 0",
            fold_repair_interval);
    require(threads >= 1, "EnvtParams.threads", ">= 1", threads);
}

void FeatureParams::validate() const {
    if (radius) {
        require(std::isfinite(*radius) && *radius > 0.0, "FeatureParams.radius",
                "finite and > 0", *radius);
    }
    require(threads >= 1, "FeatureParams.threads", ">= 1", threads);
}

namespace {

// envt_denoise on a valid mesh as it is numbered (the caller renumbers it: local_order).
DenoiseResult envt_denoise_numbered(const Vertices& V, const Faces& F,
                                    const EnvtParams& params) {
    DenoiseResult result;
    const detail::DenoiseSetup setup =
        detail::prepare_denoise(V, F, params.radius, 2.0, params.fix_boundary, params.iterations,
                                params.threads, result);
    if (!setup.run) return result;

    const auto t1 = Clock::now();
    const auto n = static_cast<int>(V.rows());
    const auto m = static_cast<int>(F.rows());
    const Csr& omega = setup.omega;
    const double cos_rho = std::cos(params.rho);
    std::vector<detail::FaceState> faces(static_cast<std::size_t>(m));
    Vertices normals(m, 3);  // current normals n_j (faces[].normal receives the filtered ones)
    Vertices next(n, 3);
    for (int it = 0; it < params.iterations; ++it) {
        detail::parallel_for(m, params.threads, [&](int begin, int end) {
            detail::update_faces(result.V, F, begin, end, faces.data(), simd_avx2_available());
            for (int f = begin; f < end; ++f) {
                const double* nf = faces[static_cast<std::size_t>(f)].normal;
                normals.row(f) << nf[0], nf[1], nf[2];
            }
        });
        detail::parallel_for(m, params.threads, [&](int begin, int end) {
            for (int i = begin; i < end; ++i) {
                const Eigen::Vector3d ni = normals.row(i);
                Eigen::Matrix3d c = Eigen::Matrix3d::Zero();
                double weight = 0.0;
                for (int p = omega.begin(i); p < omega.end(i); ++p) {
                    const int j = omega.item(p);
                    const Eigen::Vector3d nj = normals.row(j);
                    const double w = (ni.dot(nj) >= cos_rho ? 1.0 : 0.1) *
                                     faces[static_cast<std::size_t>(j)].area;
                    c.noalias() += w * nj * nj.transpose();  // Eq. 3.1, 3.2
                    weight += w;
                }
                double* filtered = faces[static_cast<std::size_t>(i)].normal;
                if (!(weight > 0.0)) continue;  // keep n_i
                const Eigen3 e = decompose(c / weight);
                // §3.1.3 binary optimisation, then Eq. 3.4–3.5.
                const int kept =
                    e.values(2) >= params.tau ? 3 : (e.values(1) >= params.tau ? 2 : 1);
                Eigen::Vector3d out = params.damping * ni;
                for (int k = 0; k < kept; ++k) {
                    out += e.vectors.col(k).dot(ni) * e.vectors.col(k);
                }
                const double len = out.norm();
                if (len > 0.0) {
                    for (int k = 0; k < 3; ++k) filtered[k] = out(k) / len;
                }
            }
        });
        detail::parallel_for(n, params.threads, [&](int begin, int end) {
            detail::vertex_step(result.V, faces.data(), setup.adjacency, setup.fixed, 0.0, begin,
                                end, next, simd_avx2_available());
        });
        result.V.swap(next);
        ++result.iterations;
        const int every = params.fold_repair_interval;
        if (every > 0 && (result.iterations % every == 0 || it + 1 == params.iterations)) {
            const auto t2 = Clock::now();
            const FoldRepairResult folds =
                repair_folds(result.V, F, setup.adjacency, setup.fixed);
            result.folds_repaired += folds.folds_found - folds.folds_left;
            result.folds_left = folds.folds_left;
            result.seconds_fold_repair += seconds_since(t2);
        }
    }
    result.seconds_iterations = seconds_since(t1);
    return result;
}

}  // namespace

// The iterations run on the mesh renumbered for locality, as RoFi's (detail::local_order);
// the result is in the caller's numbering.
DenoiseResult envt_denoise(const Vertices& V, const Faces& F, const EnvtParams& params) {
    params.validate();
    validate_mesh(V, F);
    if (params.iterations == 0 || F.rows() == 0) return envt_denoise_numbered(V, F, params);
    return detail::denoise_in_local_order(V, F, [&](const detail::LocalOrder& local) {
        return envt_denoise_numbered(local.V, local.F, params);
    });
}

FaceFeatures face_features(const Vertices& V, const Faces& F, const FeatureParams& params) {
    params.validate();
    validate_mesh(V, F);
    const auto m = static_cast<int>(F.rows());
    const Adjacency adj = build_adjacency(F, static_cast<int>(V.rows()));
    const FaceGeometry g = face_geometry(V, F);
    FaceFeatures out;
    out.radius = params.radius.value_or(2.0 * mean_centroid_distance(g, adj));
    out.eigenvalues = Eigen::MatrixX3d::Zero(m, 3);
    out.strength = Eigen::VectorXd::Zero(m);
    out.mean_curvature = Eigen::VectorXd::Zero(m);
    if (m == 0 || !(out.radius > 0.0)) return out;
    const Csr omega = disk_neighbourhoods(F, g, adj, out.radius, params.threads);
    const double sigma = out.radius / 2.0;
    const double inv_two_s2 = 1.0 / (2.0 * sigma * sigma);
    detail::parallel_for(m, params.threads, [&](int begin, int end) {
        for (int i = begin; i < end; ++i) {
            const Eigen::Vector3d ni = g.normals.row(i);
            const Eigen::Vector3d ci = g.centroids.row(i);
            Eigen::Matrix3d c = Eigen::Matrix3d::Zero();
            double weight = 0.0;
            double curvature = 0.0;
            double curvature_weight = 0.0;
            for (int p = omega.begin(i); p < omega.end(i); ++p) {
                const int j = omega.item(p);
                const Eigen::Vector3d nj = g.normals.row(j);
                const Eigen::Vector3d d = g.centroids.row(j).transpose() - ci;
                const double d2 = d.squaredNorm();
                const double w = std::exp(-d2 * inv_two_s2) * g.areas(j);
                c.noalias() += w * nj * nj.transpose();  // Eq. 2.27
                weight += w;
                if (j != i && d2 > 0.0) {
                    curvature += g.areas(j) * 2.0 * ni.dot(d) / d2;  // Eq. 2.32
                    curvature_weight += g.areas(j);
                }
            }
            if (weight > 0.0) {
                const Eigen3 e = decompose(c / weight);
                out.eigenvalues.row(i) = e.values.cwiseMax(0.0).transpose();
                out.strength(i) = out.eigenvalues(i, 1) + out.eigenvalues(i, 2);  // Eq. 2.30
            }
            if (curvature_weight > 0.0) out.mean_curvature(i) = curvature / curvature_weight;
        }
    });
    return out;
}

}  // namespace octshape::mesh
