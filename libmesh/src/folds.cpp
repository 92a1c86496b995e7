#include "octshape/mesh/folds.h"

#include <cmath>
#include <stdexcept>
#include <string>

#include "octshape/error.h"

namespace octshape::mesh {
namespace {

// Calls visit(g) for every face g ≠ f sharing an edge with f (kAbove: only those g > f),
// found through vertex→faces (the denoisers keep that list; face→faces is not needed), in
// the order of f's edges and of vertex_faces. kAbove skips a face g ≤ f before reading its
// corners: the same visits as filtering by g > f afterwards, at about half the tests.
template <bool kAbove = false, typename Visit>
void for_each_edge_neighbour(const Faces& F, const Csr& vertex_faces, int f, Visit&& visit) {
    const int* const items = vertex_faces.items.data();
    for (int k = 0; k < 3; ++k) {
        const int u = F(f, k);
        const int w = F(f, (k + 1) % 3);
        for (int p = vertex_faces.begin(u); p < vertex_faces.end(u); ++p) {
            const int g = items[p];
            if ((kAbove ? g > f : g != f) && (F(g, 0) == w || F(g, 1) == w || F(g, 2) == w)) {
                visit(g);
            }
        }
    }
}

// Agreement of face f with its edge-neighbours other than g: n_f · Σ_{h ≠ g} a_h n_h.
double agreement(const FaceGeometry& geo, const Faces& F, const Csr& vertex_faces, int f,
                 int g) {
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for_each_edge_neighbour(F, vertex_faces, f, [&](int h) {
        if (h != g) sum += geo.areas(h) * geo.normals.row(h).transpose();
    });
    return geo.normals.row(f).dot(sum);
}

template <typename Visit>
void for_each_fold(const FaceGeometry& geo, const Faces& F, const Csr& vertex_faces,
                   double cos_fold, Visit&& visit) {
    for (int f = 0; f < static_cast<int>(F.rows()); ++f) {
        for_each_edge_neighbour<true>(F, vertex_faces, f, [&](int g) {
            // Each edge once (g > f); a fold is rare, so the dot product is the test that fails.
            if (geo.normals.row(f).dot(geo.normals.row(g)) < -cos_fold) visit(f, g);
        });
    }
}

}  // namespace

void FoldRepairParams::validate() const {
    if (!(std::isfinite(cos_fold) && cos_fold > 0.0 && cos_fold <= 1.0)) {
        throw UsageError("FoldRepairParams.cos_fold must be in (0, 1], got " +
                                    std::to_string(cos_fold));
    }
    if (max_rounds < 0) {
        throw UsageError("FoldRepairParams.max_rounds must be >= 0, got " +
                                    std::to_string(max_rounds));
    }
}

int count_folds(const Vertices& V, const Faces& F, double cos_fold) {
    validate_mesh(V, F);
    const Adjacency adj = build_adjacency(F, static_cast<int>(V.rows()));
    const FaceGeometry geo = face_geometry(V, F);
    int n = 0;
    for_each_fold(geo, F, adj.vertex_faces, cos_fold, [&](int, int) { ++n; });
    return n;
}

FoldRepairResult repair_folds(Vertices& V,
                              const Faces& F,
                              const std::vector<std::uint8_t>& fixed,
                              const FoldRepairParams& params) {
    validate_mesh(V, F);
    return repair_folds(V, F, build_adjacency(F, static_cast<int>(V.rows())), fixed, params);
}

FoldRepairResult repair_folds(Vertices& V,
                              const Faces& F,
                              const Adjacency& adj,
                              const std::vector<std::uint8_t>& fixed,
                              const FoldRepairParams& params) {
    params.validate();
    if (!fixed.empty() && fixed.size() != static_cast<std::size_t>(V.rows())) {
        throw DataError("fixed: " + std::to_string(fixed.size()) + " entries for " +
                        std::to_string(V.rows()) + " vertices");
    }
    if (adj.vertex_faces.rows() != V.rows() || adj.vertex_vertices.rows() != V.rows()) {
        throw DataError("adjacency: not built for these " + std::to_string(V.rows()) +
                        " vertices");
    }
    FoldRepairResult out;
    std::vector<std::uint8_t> move(static_cast<std::size_t>(V.rows()), 0);
    std::vector<int> moved;
    const auto ring_centroid = [&](int v) {
        Eigen::Vector3d c = Eigen::Vector3d::Zero();
        for (int p = adj.vertex_vertices.begin(v); p < adj.vertex_vertices.end(v); ++p) {
            c += V.row(adj.vertex_vertices.item(p)).transpose();
        }
        return Eigen::Vector3d(c / adj.vertex_vertices.size(v));
    };
    for (;;) {
        const FaceGeometry geo = face_geometry(V, F);
        moved.clear();
        int found = 0;
        for_each_fold(geo, F, adj.vertex_faces, params.cos_fold, [&](int f, int g) {
            ++found;
            // The turned face of the two: the one its other neighbours agree with less.
            const int turned = agreement(geo, F, adj.vertex_faces, f, g) <=
                                       agreement(geo, F, adj.vertex_faces, g, f)
                                   ? f
                                   : g;
            // Its misplaced corner: the one farthest from the centroid of its own 1-ring.
            int worst = -1;
            double worst_d2 = -1.0;
            for (int k = 0; k < 3; ++k) {
                const int v = F(turned, k);
                const double d2 = (V.row(v).transpose() - ring_centroid(v)).squaredNorm();
                if (d2 > worst_d2) {
                    worst = v;
                    worst_d2 = d2;
                }
            }
            const auto w = static_cast<std::size_t>(worst);
            if (move[w] != 0 || (!fixed.empty() && fixed[w] != 0)) return;
            move[w] = 1;
            moved.push_back(worst);
        });
        if (out.rounds == 0) out.folds_found = found;
        out.folds_left = found;
        if (found == 0 || moved.empty() || out.rounds == params.max_rounds) break;
        // Every target from the round's start, then all moves at once.
        std::vector<Eigen::Vector3d> target;
        target.reserve(moved.size());
        for (const int v : moved) target.push_back(ring_centroid(v));
        for (std::size_t k = 0; k < moved.size(); ++k) {
            V.row(moved[k]) = target[k].transpose();
            move[static_cast<std::size_t>(moved[k])] = 0;
        }
        out.vertices_moved += static_cast<int>(moved.size());
        ++out.rounds;
    }
    return out;
}

}  // namespace octshape::mesh
