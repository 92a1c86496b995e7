#include "octshape/mesh/components.h"

#include <numeric>
#include <string>

#include "octshape/error.h"

namespace octshape::mesh {
namespace {

// Union-find root with path halving.
int find_root(std::vector<int>& parent, int i) {
    while (parent[static_cast<std::size_t>(i)] != i) {
        parent[static_cast<std::size_t>(i)] =
            parent[static_cast<std::size_t>(parent[static_cast<std::size_t>(i)])];
        i = parent[static_cast<std::size_t>(i)];
    }
    return i;
}

}  // namespace

Components face_components(const Faces& F, int num_vertices) {
    for (Eigen::Index f = 0; f < F.rows(); ++f) {
        for (int k = 0; k < 3; ++k) {
            if (F(f, k) < 0 || F(f, k) >= num_vertices) {
                throw DataError("face " + std::to_string(f) + " indexes vertex " +
                                std::to_string(F(f, k)) + " of " + std::to_string(num_vertices));
            }
        }
    }
    std::vector<int> parent(static_cast<std::size_t>(num_vertices));
    std::iota(parent.begin(), parent.end(), 0);
    for (Eigen::Index f = 0; f < F.rows(); ++f) {
        for (int k = 1; k < 3; ++k) {
            const int r0 = find_root(parent, F(f, 0));
            const int r1 = find_root(parent, F(f, k));
            if (r0 != r1) parent[static_cast<std::size_t>(r1)] = r0;
        }
    }
    Components c;
    c.face_component.resize(static_cast<std::size_t>(F.rows()));
    std::vector<int> label(static_cast<std::size_t>(num_vertices), -1);  // root → component
    for (Eigen::Index f = 0; f < F.rows(); ++f) {
        int& l = label[static_cast<std::size_t>(find_root(parent, F(f, 0)))];
        if (l < 0) {
            l = c.count();
            c.faces.push_back(0);
        }
        c.face_component[static_cast<std::size_t>(f)] = l;
        ++c.faces[static_cast<std::size_t>(l)];
    }
    return c;
}

void compact_faces(Vertices& V, Faces& F, const std::vector<std::uint8_t>& keep) {
    if (keep.size() != static_cast<std::size_t>(F.rows())) {
        throw UsageError("compact_faces: keep has " + std::to_string(keep.size()) +
                         " flags for " + std::to_string(F.rows()) + " faces");
    }
    std::vector<int> map(static_cast<std::size_t>(V.rows()), -1);
    int nf = 0;
    int nv = 0;
    for (Eigen::Index f = 0; f < F.rows(); ++f) {
        if (!keep[static_cast<std::size_t>(f)]) continue;
        for (int k = 0; k < 3; ++k) {
            int& m = map[static_cast<std::size_t>(F(f, k))];
            if (m < 0) m = nv++;
        }
        ++nf;
    }
    Vertices V2(nv, 3);
    for (Eigen::Index i = 0; i < V.rows(); ++i) {
        const int m = map[static_cast<std::size_t>(i)];
        if (m >= 0) V2.row(m) = V.row(i);
    }
    Faces F2(nf, 3);
    int row = 0;
    for (Eigen::Index f = 0; f < F.rows(); ++f) {
        if (!keep[static_cast<std::size_t>(f)]) continue;
        for (int k = 0; k < 3; ++k) F2(row, k) = map[static_cast<std::size_t>(F(f, k))];
        ++row;
    }
    V = std::move(V2);
    F = std::move(F2);
}

int keep_largest_component(Vertices& V, Faces& F) {
    const Components c = face_components(F, static_cast<int>(V.rows()));
    if (c.count() <= 1) return c.count();
    int best = 0;
    for (int k = 1; k < c.count(); ++k) {
        if (c.faces[static_cast<std::size_t>(k)] > c.faces[static_cast<std::size_t>(best)]) best = k;
    }
    std::vector<std::uint8_t> keep(static_cast<std::size_t>(F.rows()));
    for (std::size_t f = 0; f < keep.size(); ++f) keep[f] = c.face_component[f] == best ? 1 : 0;
    compact_faces(V, F, keep);
    return c.count();
}

double weighted_normal_along(const Vertices& V, const Faces& F, const Eigen::Vector3d& direction) {
    double s = 0.0;
    for (Eigen::Index f = 0; f < F.rows(); ++f) {
        const Eigen::Vector3d e1 = (V.row(F(f, 1)) - V.row(F(f, 0))).transpose();
        const Eigen::Vector3d e2 = (V.row(F(f, 2)) - V.row(F(f, 0))).transpose();
        s += e1.cross(e2).dot(direction);
    }
    return s;
}

bool orient_along(const Vertices& V, Faces& F, const Eigen::Vector3d& direction) {
    if (!(weighted_normal_along(V, F, direction) < 0.0)) return false;
    F.col(1).swap(F.col(2));
    return true;
}

}  // namespace octshape::mesh
