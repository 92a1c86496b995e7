#include "octshape/retina/onh_surfaces.h"

#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include "octshape/error.h"

namespace octshape::retina {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

}  // namespace

int GridSurface::num_filled() const {
    return static_cast<int>(std::count(filled.begin(), filled.end(), std::uint8_t{1}));
}

double GridSurface::bilinear(double x, double y) const {
    if (cols < 2 || rows < 2) return kNaN;
    const double u = x / dx_mm;
    const double v = y / dy_mm;
    // A tolerance of 1e-9 cells keeps points on the last grid line inside.
    if (!(u >= -1e-9 && v >= -1e-9 && u <= cols - 1 + 1e-9 && v <= rows - 1 + 1e-9)) return kNaN;
    const int a = std::clamp(static_cast<int>(std::floor(u)), 0, cols - 2);
    const int b = std::clamp(static_cast<int>(std::floor(v)), 0, rows - 2);
    const double fu = u - a;
    const double fv = v - b;
    return (1.0 - fv) * ((1.0 - fu) * at(a, b) + fu * at(a + 1, b)) +
           fv * ((1.0 - fu) * at(a, b + 1) + fu * at(a + 1, b + 1));
}

GridSurface line_height_field(const io::Scan& scan, io::Layer layer) {
    const int k = static_cast<int>(layer);
    GridSurface s;
    s.cols = scan.meta.size_x;
    s.rows = scan.num_bscans();
    s.dx_mm = scan.meta.scale_x_mm;
    s.dy_mm = scan.meta.distance_mm;
    const auto n = static_cast<std::size_t>(s.cols) * static_cast<std::size_t>(s.rows);
    s.z.assign(n, kNaN);
    s.filled.assign(n, 0);
    for (int b = 0; b < s.rows; ++b) {
        const io::BScan& bs = scan.bscans[static_cast<std::size_t>(b)];
        if (!bs.has_line(k)) {
            throw AnalysisError("B-scan " + std::to_string(b) + " has no " + io::layer_name(k) +
                                " segmentation line");
        }
        const auto& line = bs.seg[static_cast<std::size_t>(k)];
        const int m = std::min(s.cols, static_cast<int>(line.size()));
        for (int a = 0; a < m; ++a) {
            const float d = line[static_cast<std::size_t>(a)];
            if (io::is_valid(d)) {
                s.z[static_cast<std::size_t>(b) * static_cast<std::size_t>(s.cols) +
                    static_cast<std::size_t>(a)] = -static_cast<double>(d) * scan.meta.scale_z_mm;
            }
        }
    }
    return s;
}

ThinPlateFillResult thin_plate_fill(GridSurface& s) {
    ThinPlateFillResult res;
    const int nx = s.cols;
    const int ny = s.rows;
    const auto idx = [nx](int a, int b) {
        return static_cast<std::size_t>(b) * static_cast<std::size_t>(nx) +
               static_cast<std::size_t>(a);
    };
    // Unknown numbering.
    std::vector<int> unknown(s.z.size(), -1);
    int nu = 0;
    std::vector<Eigen::Vector2d> known_xy;
    for (int b = 0; b < ny; ++b) {
        for (int a = 0; a < nx; ++a) {
            if (std::isnan(s.z[idx(a, b)])) {
                unknown[idx(a, b)] = nu++;
            } else if (known_xy.size() < 3 || a % 7 == 0) {
                known_xy.emplace_back(a, b);
            }
        }
    }
    if (nu == 0) return res;
    // At least three non-collinear present values pin down the affine null space of the energy.
    bool spans = false;
    for (std::size_t i = 2; i < known_xy.size() && !spans; ++i) {
        const Eigen::Vector2d d1 = known_xy[1] - known_xy[0];
        const Eigen::Vector2d d2 = known_xy[i] - known_xy[0];
        spans = std::fabs(d1.x() * d2.y() - d1.y() * d2.x()) > 0.5;
    }
    if (!spans) {
        throw AnalysisError(
            "thin-plate fill: fewer than three non-collinear present values on the grid");
    }
    if (nx < 2 || ny < 2) throw AnalysisError("thin-plate fill: the grid needs 2 x 2 nodes");

    // Rows of the least-squares system: each second difference touching an unknown.
    using Triplet = Eigen::Triplet<double>;
    std::vector<Triplet> trip;
    std::vector<double> rhs;
    const double cx = 1.0 / (s.dx_mm * s.dx_mm);
    const double cy = 1.0 / (s.dy_mm * s.dy_mm);
    const double cxy = std::sqrt(2.0) / (s.dx_mm * s.dy_mm);
    auto add_row = [&](const std::array<std::pair<std::size_t, double>, 4>& terms, int n) {
        bool any = false;
        for (int t = 0; t < n; ++t)
            any = any || unknown[terms[static_cast<std::size_t>(t)].first] >= 0;
        if (!any) return;
        const int row = static_cast<int>(rhs.size());
        double b = 0.0;
        for (int t = 0; t < n; ++t) {
            const auto& [node, c] = terms[static_cast<std::size_t>(t)];
            if (unknown[node] >= 0) {
                trip.emplace_back(row, unknown[node], c);
            } else {
                b -= c * s.z[node];
            }
        }
        rhs.push_back(b);
    };
    for (int b = 0; b < ny; ++b) {
        for (int a = 0; a < nx; ++a) {
            if (a >= 1 && a + 1 < nx) {  // z_xx at node (a, b)
                add_row({{{idx(a - 1, b), cx}, {idx(a, b), -2.0 * cx}, {idx(a + 1, b), cx}, {}}},
                        3);
            }
            if (b >= 1 && b + 1 < ny) {  // z_yy
                add_row({{{idx(a, b - 1), cy}, {idx(a, b), -2.0 * cy}, {idx(a, b + 1), cy}, {}}},
                        3);
            }
            if (a + 1 < nx && b + 1 < ny) {  // sqrt(2) z_xy on the cell
                add_row({{{idx(a, b), cxy},
                          {idx(a + 1, b), -cxy},
                          {idx(a, b + 1), -cxy},
                          {idx(a + 1, b + 1), cxy}}},
                        4);
            }
        }
    }
    Eigen::SparseMatrix<double> A(static_cast<Eigen::Index>(rhs.size()), nu);
    A.setFromTriplets(trip.begin(), trip.end());
    const Eigen::Map<const Eigen::VectorXd> r(rhs.data(), static_cast<Eigen::Index>(rhs.size()));
    const Eigen::SparseMatrix<double> N = A.transpose() * A;
    const Eigen::VectorXd g = A.transpose() * r;
    Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(N);
    if (solver.info() != Eigen::Success) {
        throw AnalysisError("thin-plate fill: the normal equations are singular");
    }
    Eigen::VectorXd u = solver.solve(g);
    // One step of iterative refinement recovers the digits the normal equations lose.
    const Eigen::VectorXd d = g - N * u;
    u += solver.solve(d);
    const double gmax = std::max(g.cwiseAbs().maxCoeff(), 1e-300);
    res.residual = (g - N * u).cwiseAbs().maxCoeff() / gmax;
    for (std::size_t i = 0; i < s.z.size(); ++i) {
        if (unknown[i] >= 0) {
            s.z[i] = u(unknown[i]);
            s.filled[i] = 1;
        }
    }
    res.filled = nu;
    return res;
}

void graph_mesh(const GridSurface& s, mesh::Vertices& V, mesh::Faces& F) {
    if (std::any_of(s.z.begin(), s.z.end(), [](double v) { return std::isnan(v); })) {
        throw AnalysisError("graph mesh: the height field has missing values (fill them first)");
    }
    // Every node is a corner of a finite cell: vertex i is node i.
    graph_mesh_finite(s, V, F);
}

void graph_mesh_finite(const GridSurface& s, mesh::Vertices& V, mesh::Faces& F,
                       std::vector<int>* node_of_vertex) {
    const auto node = [&s](int a, int b) { return b * s.cols + a; };
    const auto finite = [&s](int a, int b) { return std::isfinite(s.at(a, b)); };
    std::vector<std::uint8_t> used(s.z.size(), 0);
    std::vector<std::array<int, 3>> tris;
    tris.reserve(static_cast<std::size_t>(std::max(0, 2 * (s.cols - 1) * (s.rows - 1))));
    for (int b = 0; b + 1 < s.rows; ++b) {
        for (int a = 0; a + 1 < s.cols; ++a) {
            if (!finite(a, b) || !finite(a + 1, b) || !finite(a, b + 1) || !finite(a + 1, b + 1)) {
                continue;
            }
            const int v00 = node(a, b);
            const int v10 = v00 + 1;
            const int v01 = v00 + s.cols;
            const int v11 = v01 + 1;
            tris.push_back({v00, v10, v11});
            tris.push_back({v00, v11, v01});
            for (const int v : {v00, v10, v01, v11}) used[static_cast<std::size_t>(v)] = 1;
        }
    }
    std::vector<int> vertex_of(s.z.size(), -1);
    int nv = 0;
    for (std::size_t i = 0; i < used.size(); ++i) {
        if (used[i]) vertex_of[i] = nv++;
    }
    V.resize(nv, 3);
    if (node_of_vertex != nullptr) node_of_vertex->assign(static_cast<std::size_t>(nv), -1);
    for (int b = 0; b < s.rows; ++b) {
        for (int a = 0; a < s.cols; ++a) {
            const int v = vertex_of[static_cast<std::size_t>(node(a, b))];
            if (v < 0) continue;
            V.row(v) << a * s.dx_mm, b * s.dy_mm, s.at(a, b);
            if (node_of_vertex != nullptr) (*node_of_vertex)[static_cast<std::size_t>(v)] = node(a, b);
        }
    }
    F.resize(static_cast<Eigen::Index>(tris.size()), 3);
    for (std::size_t f = 0; f < tris.size(); ++f) {
        F.row(static_cast<Eigen::Index>(f)) << vertex_of[static_cast<std::size_t>(tris[f][0])],
            vertex_of[static_cast<std::size_t>(tris[f][1])],
            vertex_of[static_cast<std::size_t>(tris[f][2])];
    }
}

}  // namespace octshape::retina
