#include "octshape/mesh/mesh.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>
#include <string>

#include "parallel.h"

namespace octshape::mesh {
namespace {

Csr csr_from_pairs(std::vector<std::pair<int, int>>& pairs, int rows) {
    std::sort(pairs.begin(), pairs.end());
    pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
    Csr out;
    out.offsets.assign(static_cast<std::size_t>(rows) + 1, 0);
    out.items.reserve(pairs.size());
    for (const auto& [row, item] : pairs) {
        ++out.offsets[static_cast<std::size_t>(row) + 1];
        out.items.push_back(item);
    }
    for (std::size_t i = 1; i < out.offsets.size(); ++i) out.offsets[i] += out.offsets[i - 1];
    return out;
}

}  // namespace

void validate_mesh(const Vertices& V, const Faces& F) {
    for (Eigen::Index i = 0; i < V.rows(); ++i) {
        if (!V.row(i).allFinite()) {
            throw std::invalid_argument("vertex " + std::to_string(i) + " is not finite");
        }
    }
    const auto n = static_cast<int>(V.rows());
    for (Eigen::Index f = 0; f < F.rows(); ++f) {
        for (int k = 0; k < 3; ++k) {
            const int v = F(f, k);
            if (v < 0 || v >= n) {
                throw std::invalid_argument("face " + std::to_string(f) + " refers to vertex " +
                                            std::to_string(v) + " of " + std::to_string(n));
            }
        }
        if (F(f, 0) == F(f, 1) || F(f, 1) == F(f, 2) || F(f, 2) == F(f, 0)) {
            throw std::invalid_argument("face " + std::to_string(f) + " repeats a vertex");
        }
    }
}

void compute_face_geometry(const Vertices& V, const Faces& F, FaceGeometry& out) {
    const Eigen::Index m = F.rows();
    out.normals.resize(m, 3);
    out.areas.resize(m);
    out.centroids.resize(m, 3);
    for (Eigen::Index f = 0; f < m; ++f) {
        const Eigen::Vector3d a = V.row(F(f, 0));
        const Eigen::Vector3d b = V.row(F(f, 1));
        const Eigen::Vector3d c = V.row(F(f, 2));
        const Eigen::Vector3d cross = (b - a).cross(c - a);
        const double norm = cross.norm();
        out.areas(f) = 0.5 * norm;
        out.normals.row(f) = norm > 0.0 ? Eigen::Vector3d(cross / norm) : Eigen::Vector3d::Zero();
        out.centroids.row(f) = (a + b + c) / 3.0;  // Eq. 2.31
    }
}

FaceGeometry face_geometry(const Vertices& V, const Faces& F) {
    FaceGeometry g;
    compute_face_geometry(V, F, g);
    return g;
}

Adjacency build_adjacency(const Faces& F, int num_vertices) {
    const auto m = static_cast<int>(F.rows());
    for (int f = 0; f < m; ++f) {
        for (int k = 0; k < 3; ++k) {
            if (F(f, k) < 0 || F(f, k) >= num_vertices) {
                throw std::invalid_argument("face " + std::to_string(f) + " refers to vertex " +
                                            std::to_string(F(f, k)) + " of " +
                                            std::to_string(num_vertices));
            }
        }
    }
    Adjacency adj;
    std::vector<std::pair<int, int>> pairs;
    pairs.reserve(static_cast<std::size_t>(m) * 3);
    for (int f = 0; f < m; ++f) {
        for (int k = 0; k < 3; ++k) pairs.emplace_back(F(f, k), f);
    }
    adj.vertex_faces = csr_from_pairs(pairs, num_vertices);

    // Undirected edges (lo, hi, face), sorted so that the faces of one edge are consecutive.
    std::vector<std::array<int, 3>> edges;
    edges.reserve(static_cast<std::size_t>(m) * 3);
    for (int f = 0; f < m; ++f) {
        for (int k = 0; k < 3; ++k) {
            const int a = F(f, k);
            const int b = F(f, (k + 1) % 3);
            edges.push_back({std::min(a, b), std::max(a, b), f});
        }
    }
    std::sort(edges.begin(), edges.end());
    adj.boundary_vertex.assign(static_cast<std::size_t>(num_vertices), 0);
    std::vector<std::pair<int, int>> vv;
    std::vector<std::pair<int, int>> ff;
    vv.reserve(edges.size() * 2);
    ff.reserve(edges.size() * 2);
    for (std::size_t i = 0; i < edges.size();) {
        std::size_t j = i;
        while (j < edges.size() && edges[j][0] == edges[i][0] && edges[j][1] == edges[i][1]) ++j;
        const int lo = edges[i][0];
        const int hi = edges[i][1];
        vv.emplace_back(lo, hi);
        vv.emplace_back(hi, lo);
        const std::size_t count = j - i;
        if (count != 2) {
            adj.boundary_vertex[static_cast<std::size_t>(lo)] = 1;
            adj.boundary_vertex[static_cast<std::size_t>(hi)] = 1;
            if (count == 1) {
                ++adj.boundary_edges;
            } else {
                ++adj.nonmanifold_edges;
            }
        }
        for (std::size_t p = i; p < j; ++p) {
            for (std::size_t q = i; q < j; ++q) {
                if (p != q && edges[p][2] != edges[q][2]) ff.emplace_back(edges[p][2], edges[q][2]);
            }
        }
        i = j;
    }
    adj.vertex_vertices = csr_from_pairs(vv, num_vertices);
    adj.face_faces = csr_from_pairs(ff, m);
    return adj;
}

double mean_centroid_distance(const FaceGeometry& geometry, const Adjacency& adjacency) {
    double sum = 0.0;
    long long count = 0;
    const Csr& ff = adjacency.face_faces;
    for (int f = 0; f < ff.rows(); ++f) {
        for (int k = ff.begin(f); k < ff.end(f); ++k) {
            const int g = ff.item(k);
            if (g <= f) continue;  // each pair once
            sum += (geometry.centroids.row(f) - geometry.centroids.row(g)).norm();
            ++count;
        }
    }
    return count > 0 ? sum / static_cast<double>(count) : 0.0;
}

double mean_edge_length(const Vertices& V, const Faces& F) {
    std::vector<std::pair<int, int>> edges;
    edges.reserve(static_cast<std::size_t>(F.rows()) * 3);
    for (Eigen::Index f = 0; f < F.rows(); ++f) {
        for (int k = 0; k < 3; ++k) {
            const int a = F(f, k);
            const int b = F(f, (k + 1) % 3);
            edges.emplace_back(std::min(a, b), std::max(a, b));
        }
    }
    std::sort(edges.begin(), edges.end());
    edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
    if (edges.empty()) return 0.0;
    double sum = 0.0;
    for (const auto& [a, b] : edges) sum += (V.row(a) - V.row(b)).norm();
    return sum / static_cast<double>(edges.size());
}

Csr disk_neighbourhoods(const Faces& F,
                        const FaceGeometry& geometry,
                        const Adjacency& adjacency,
                        double radius,
                        int threads) {
    if (!(radius >= 0.0) || !std::isfinite(radius)) {
        throw std::invalid_argument("radius must be finite and >= 0, got " +
                                    std::to_string(radius));
    }
    const auto m = static_cast<int>(F.rows());
    std::vector<std::vector<int>> rows(static_cast<std::size_t>(m));
    const double r2 = radius * radius;
    detail::parallel_for(m, threads, [&](int begin, int end) {
        std::vector<int> stamp(static_cast<std::size_t>(m), -1);
        std::vector<int> queue;
        for (int i = begin; i < end; ++i) {
            const Eigen::Vector3d ci = geometry.centroids.row(i);
            std::vector<int>& row = rows[static_cast<std::size_t>(i)];
            queue.assign(1, i);
            stamp[static_cast<std::size_t>(i)] = i;
            for (std::size_t q = 0; q < queue.size(); ++q) {
                const int f = queue[q];
                for (int k = 0; k < 3; ++k) {
                    const int v = F(f, k);
                    const Csr& vf = adjacency.vertex_faces;
                    for (int p = vf.begin(v); p < vf.end(v); ++p) {
                        const int g = vf.item(p);
                        if (stamp[static_cast<std::size_t>(g)] == i) continue;
                        stamp[static_cast<std::size_t>(g)] = i;
                        if ((geometry.centroids.row(g) - ci.transpose()).squaredNorm() <= r2) {
                            queue.push_back(g);
                        }
                    }
                }
            }
            std::sort(queue.begin() + 1, queue.end());
            row = queue;
        }
    });
    return Csr::from_rows(rows);
}

Csr Csr::from_rows(const std::vector<std::vector<int>>& rows) {
    Csr out;
    out.offsets.assign(rows.size() + 1, 0);
    for (std::size_t i = 0; i < rows.size(); ++i) {
        out.offsets[i + 1] = out.offsets[i] + static_cast<int>(rows[i].size());
    }
    out.items.reserve(static_cast<std::size_t>(out.offsets.back()));
    for (const auto& row : rows) out.items.insert(out.items.end(), row.begin(), row.end());
    return out;
}

}  // namespace octshape::mesh
