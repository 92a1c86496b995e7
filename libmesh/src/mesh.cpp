#include "octshape/mesh/mesh.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>
#include <string>

#include "parallel.h"

#include "octshape/error.h"

namespace octshape::mesh {
namespace {

// Rows of (row, item) pairs, each row sorted ascending without repeats (the same result as
// sorting the pairs and dropping duplicates). A counting sort by row and a sort of each short
// row: O(#pairs) instead of O(#pairs log #pairs), no pair array.
Csr csr_from_pairs(const std::vector<std::pair<int, int>>& pairs, int rows) {
    Csr out;
    out.offsets.assign(static_cast<std::size_t>(rows) + 1, 0);
    for (const auto& pr : pairs) ++out.offsets[static_cast<std::size_t>(pr.first) + 1];
    for (std::size_t i = 1; i < out.offsets.size(); ++i) out.offsets[i] += out.offsets[i - 1];
    out.items.resize(pairs.size());
    std::vector<int> fill(out.offsets.begin(), out.offsets.end() - 1);
    for (const auto& [row, item] : pairs) {
        out.items[static_cast<std::size_t>(fill[static_cast<std::size_t>(row)]++)] = item;
    }
    // Sort each row, drop repeats and close the gaps in place.
    int write = 0;
    for (int r = 0; r < rows; ++r) {
        const auto b = out.items.begin() + out.offsets[static_cast<std::size_t>(r)];
        const auto e = out.items.begin() + out.offsets[static_cast<std::size_t>(r) + 1];
        std::sort(b, e);
        const auto last = std::unique(b, e);
        out.offsets[static_cast<std::size_t>(r)] = write;
        write = static_cast<int>(std::copy(b, last, out.items.begin() + write) -
                                 out.items.begin());
    }
    out.offsets[static_cast<std::size_t>(rows)] = write;
    out.items.resize(static_cast<std::size_t>(write));
    out.items.shrink_to_fit();
    return out;
}

}  // namespace

void validate_mesh(const Vertices& V, const Faces& F) {
    for (Eigen::Index i = 0; i < V.rows(); ++i) {
        if (!V.row(i).allFinite()) {
            throw DataError("vertex " + std::to_string(i) + " is not finite");
        }
    }
    const auto n = static_cast<int>(V.rows());
    for (Eigen::Index f = 0; f < F.rows(); ++f) {
        for (int k = 0; k < 3; ++k) {
            const int v = F(f, k);
            if (v < 0 || v >= n) {
                throw DataError("face " + std::to_string(f) + " refers to vertex " +
                                            std::to_string(v) + " of " + std::to_string(n));
            }
        }
        if (F(f, 0) == F(f, 1) || F(f, 1) == F(f, 2) || F(f, 2) == F(f, 0)) {
            throw DataError("face " + std::to_string(f) + " repeats a vertex");
        }
    }
    // Single faces of no area are tolerated (their normal is zero, the filters skip them); a
    // mesh whose every face has no area has no normal field, no neighbourhood scale c_a and no
    // surface to measure.
    bool some_area = F.rows() == 0;
    for (Eigen::Index f = 0; f < F.rows() && !some_area; ++f) {
        const Eigen::Vector3d a = V.row(F(f, 0));
        some_area = (Eigen::Vector3d(V.row(F(f, 1))) - a)
                        .cross(Eigen::Vector3d(V.row(F(f, 2))) - a)
                        .squaredNorm() > 0.0;
    }
    if (!some_area) {
        throw DataError("every face has zero area (the vertices coincide or lie on one line): "
                        "no surface");
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
                throw DataError("face " + std::to_string(f) + " refers to vertex " +
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

    // Undirected edges (lo, hi, face), ordered by (lo, hi, face) so that the faces of one edge
    // are consecutive: bucketed by lo (counting sort), then each short bucket sorted.
    std::vector<int> edge_offsets(static_cast<std::size_t>(num_vertices) + 1, 0);
    for (int f = 0; f < m; ++f) {
        for (int k = 0; k < 3; ++k) {
            const int lo = std::min(F(f, k), F(f, (k + 1) % 3));
            ++edge_offsets[static_cast<std::size_t>(lo) + 1];
        }
    }
    for (std::size_t i = 1; i < edge_offsets.size(); ++i) edge_offsets[i] += edge_offsets[i - 1];
    std::vector<std::array<int, 3>> edges(static_cast<std::size_t>(m) * 3);
    {
        std::vector<int> fill(edge_offsets.begin(), edge_offsets.end() - 1);
        for (int f = 0; f < m; ++f) {
            for (int k = 0; k < 3; ++k) {
                const int a = F(f, k);
                const int b = F(f, (k + 1) % 3);
                const int lo = std::min(a, b);
                edges[static_cast<std::size_t>(fill[static_cast<std::size_t>(lo)]++)] = {
                    lo, std::max(a, b), f};
            }
        }
    }
    for (int v = 0; v < num_vertices; ++v) {
        std::sort(edges.begin() + edge_offsets[static_cast<std::size_t>(v)],
                  edges.begin() + edge_offsets[static_cast<std::size_t>(v) + 1]);
    }
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

std::size_t max_neighbourhood_faces(int faces) {
    return static_cast<std::size_t>(std::clamp(faces / 4, 64, 4096));
}

Csr disk_neighbourhoods(const Faces& F,
                        const FaceGeometry& geometry,
                        const Adjacency& adjacency,
                        double radius,
                        int threads) {
    if (!(radius >= 0.0) || !std::isfinite(radius)) {
        throw UsageError("radius must be finite and >= 0, got " +
                                    std::to_string(radius));
    }
    const auto m = static_cast<int>(F.rows());
    const int n = adjacency.vertex_faces.rows();
    const double r2 = radius * radius;
    const std::size_t limit = max_neighbourhood_faces(m);
    const int* vf_off = adjacency.vertex_faces.offsets.data();
    const int* vf = adjacency.vertex_faces.items.data();
    const double* cen = geometry.centroids.data();  // row-major: face f at cen[3f .. 3f+2]
    const int* tri = F.data();
    // Each worker grows the rows of its contiguous range of faces into its own flat buffer
    // (no allocation per face); the buffers are joined in order, so the result does not depend
    // on the number of workers. Stamps: a face is tested once per row, and the faces around a
    // vertex are scanned once per row (scanning them again from another face of the disk finds
    // only stamped faces), which gives the same set as the plain growth.
    const int workers = std::clamp(threads, 1, std::max(1, m / 256));
    std::vector<std::vector<int>> counts(static_cast<std::size_t>(workers));
    std::vector<std::vector<int>> buffers(static_cast<std::size_t>(workers));
    detail::parallel_for(m, threads, [&](int begin, int end) {
        // parallel_for splits [0, m) into `workers` chunks starting at m·w/workers.
        int w = 0;
        while (w + 1 < workers && static_cast<long long>(m) * (w + 1) / workers <= begin) ++w;
        // Local copies of the pointers: the writes into the buffer could alias captured ones,
        // which the compiler would then reload at every access.
        const int* const vfo = vf_off;
        const int* const vfi = vf;
        const double* const c = cen;
        const int* const t = tri;
        std::vector<int> face_stamp(static_cast<std::size_t>(m), -1);
        std::vector<int> vertex_stamp(static_cast<std::size_t>(n), -1);
        int* const fs = face_stamp.data();
        int* const vs = vertex_stamp.data();
        std::vector<int>& count = counts[static_cast<std::size_t>(w)];
        std::vector<int>& out = buffers[static_cast<std::size_t>(w)];
        count.resize(static_cast<std::size_t>(end - begin));
        // out[0, size) is the worker's rows so far; out is grown before each vertex's faces
        // are scanned, so that every candidate can be written without a branch and kept by
        // advancing `size` (no mispredicted branch per tested face).
        std::size_t size = 0;
        out.resize(16 * static_cast<std::size_t>(end - begin) + 64);
        for (int i = begin; i < end; ++i) {
            const double cx = c[3 * i];
            const double cy = c[3 * i + 1];
            const double cz = c[3 * i + 2];
            const std::size_t start = size;
            if (size + 1 > out.size()) out.resize(2 * out.size());
            out[size++] = i;
            fs[i] = i;
            for (std::size_t q = start; q < size; ++q) {
                const int f = out[q];
                for (int k = 0; k < 3; ++k) {
                    const int v = t[3 * f + k];
                    if (vs[v] == i) continue;
                    vs[v] = i;
                    const int pb = vfo[v];
                    const int pe = vfo[v + 1];
                    const auto need = size + static_cast<std::size_t>(pe - pb);
                    if (need > out.size()) out.resize(2 * need);
                    int* const o = out.data();
                    for (int p = pb; p < pe; ++p) {
                        const int g = vfi[p];
                        const bool fresh = fs[g] != i;
                        fs[g] = i;
                        const double dx = c[3 * g] - cx;
                        const double dy = c[3 * g + 1] - cy;
                        const double dz = c[3 * g + 2] - cz;
                        const bool inside = dx * dx + dy * dy + dz * dz <= r2;
                        o[size] = g;
                        size += static_cast<std::size_t>(fresh & inside);
                    }
                    if (size - start > limit) {
                        throw DataError(
                            "the disk of radius " + std::to_string(radius) + " around face " +
                            std::to_string(i) + " holds more than " + std::to_string(limit) +
                            " of the " + std::to_string(m) +
                            " faces (the bound of a neighbourhood: a radius too large for the "
                            "mesh, or a vertex far from the others)");
                    }
                }
            }
            std::sort(out.begin() + static_cast<std::ptrdiff_t>(start) + 1,
                      out.begin() + static_cast<std::ptrdiff_t>(size));
            count[static_cast<std::size_t>(i - begin)] = static_cast<int>(size - start);
        }
        out.resize(size);
    });
    Csr omega;
    omega.offsets.assign(static_cast<std::size_t>(m) + 1, 0);
    std::size_t row = 0;
    for (int w = 0; w < workers; ++w) {
        for (const int c : counts[static_cast<std::size_t>(w)]) {
            omega.offsets[row + 1] = omega.offsets[row] + c;
            ++row;
        }
    }
    if (workers == 1) {
        // One buffer is already the item list: no joined copy beside it (the copy doubled
        // the set-up's peak: ~4|Ω_i| bytes per face more).
        omega.items = std::move(buffers[0]);
        return omega;
    }
    std::size_t total = 0;
    for (const auto& b : buffers) total += b.size();
    omega.items.reserve(total);
    for (auto& b : buffers) {
        omega.items.insert(omega.items.end(), b.begin(), b.end());
        std::vector<int>().swap(b);
    }
    return omega;
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
