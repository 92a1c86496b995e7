// Graph surfaces of the ONH analysis: the thin-plate (biharmonic) fill reproduces a quadratic
// BM exactly where a harmonic fill cannot (docs/algorithms/onh.md "Surfaces"), bilinear
// interpolation, graph meshes.

#include "octshape/retina/onh_surfaces.h"

#include <gtest/gtest.h>

#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>
#include <cmath>
#include <limits>

#include "octshape/error.h"

namespace octshape::retina {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// The full-size ONH phantom's anisotropic grid (ScaleX 11.3 um, Distance 30.2 um).
GridSurface quadratic_grid(int cols, int rows, double (*f)(double, double)) {
    GridSurface s;
    s.cols = cols;
    s.rows = rows;
    s.dx_mm = 4.35 / 384;
    s.dy_mm = 4.35 / 144;
    for (int b = 0; b < rows; ++b) {
        for (int a = 0; a < cols; ++a) s.z.push_back(f(a * s.dx_mm, b * s.dy_mm));
    }
    s.filled.assign(s.z.size(), 0);
    return s;
}

// Eye-wall quadratic of the ONH phantom: curvature radius 12 mm, tilt (0.03, -0.02), plus a
// mixed term so that every second derivative is present.
double eye_wall(double x, double y) {
    const double dx = x - 1.1;
    const double dy = y - 1.0;
    return -1.19 + (dx * dx + dy * dy) / 24.0 + 0.03 * dx - 0.02 * dy + 0.01 * dx * dy;
}

// The eye wall without tilt: (x^2 + y^2) / (2R), R = 12 mm.
double paraboloid(double x, double y) {
    const double dx = x - 1.1;
    const double dy = y - 1.0;
    return (dx * dx + dy * dy) / 24.0;
}

// Removes the nodes inside an ellipse around (1.1, 1.0) mm (a BMO-like hole); returns them.
std::vector<std::size_t> punch_hole(GridSurface& s, double ra, double rb) {
    std::vector<std::size_t> hole;
    for (int b = 0; b < s.rows; ++b) {
        for (int a = 0; a < s.cols; ++a) {
            const double u = (a * s.dx_mm - 1.1) / ra;
            const double v = (b * s.dy_mm - 1.0) / rb;
            if (u * u + v * v < 1.0) {
                const auto i = static_cast<std::size_t>(b * s.cols + a);
                s.z[i] = kNaN;
                hole.push_back(i);
            }
        }
    }
    return hole;
}

// A harmonic (membrane) fill: 5-point Laplace equation on the hole, for comparison only.
std::vector<double> harmonic_fill(const GridSurface& s) {
    std::vector<int> id(s.z.size(), -1);
    int n = 0;
    for (std::size_t i = 0; i < s.z.size(); ++i) {
        if (std::isnan(s.z[i])) id[i] = n++;
    }
    std::vector<Eigen::Triplet<double>> t;
    Eigen::VectorXd rhs = Eigen::VectorXd::Zero(n);
    const double cx = 1.0 / (s.dx_mm * s.dx_mm);
    const double cy = 1.0 / (s.dy_mm * s.dy_mm);
    for (int b = 0; b < s.rows; ++b) {
        for (int a = 0; a < s.cols; ++a) {
            const auto i = static_cast<std::size_t>(b * s.cols + a);
            if (id[i] < 0) continue;
            t.emplace_back(id[i], id[i], 2 * cx + 2 * cy);
            const std::array<std::pair<std::size_t, double>, 4> nb{
                {{i - 1, cx},
                 {i + 1, cx},
                 {i - static_cast<std::size_t>(s.cols), cy},
                 {i + static_cast<std::size_t>(s.cols), cy}}};
            for (const auto& [j, c] : nb) {
                if (id[j] >= 0) {
                    t.emplace_back(id[i], id[j], -c);
                } else {
                    rhs(id[i]) += c * s.z[j];
                }
            }
        }
    }
    Eigen::SparseMatrix<double> L(n, n);
    L.setFromTriplets(t.begin(), t.end());
    const Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(L);
    const Eigen::VectorXd u = solver.solve(rhs);
    std::vector<double> out = s.z;
    for (std::size_t i = 0; i < out.size(); ++i) {
        if (id[i] >= 0) out[i] = u(id[i]);
    }
    return out;
}

TEST(ThinPlateFill, ReproducesAQuadraticBmExactly) {
    GridSurface s = quadratic_grid(200, 70, eye_wall);
    const GridSurface truth = s;
    const auto hole = punch_hole(s, 0.92, 0.76);  // the phantom BMO: ~6400 missing nodes
    ASSERT_GT(hole.size(), 5000U);
    const ThinPlateFillResult r = thin_plate_fill(s);
    EXPECT_EQ(r.filled, static_cast<int>(hole.size()));
    EXPECT_EQ(s.num_filled(), r.filled);
    double err = 0.0;
    for (const std::size_t i : hole) err = std::max(err, std::fabs(s.z[i] - truth.z[i]));
    // Exact up to rounding: the hole spans ~160 x 50 nodes, so the normal equations of the
    // 4th-order operator have a condition number ~ 160^4 ~ 1e9; with values ~1.2 mm and one step
    // of iterative refinement the error is ~1e-16 * 1e9 * 1 mm = 1e-7 um -- far below the
    // 1e-6 mm (1 nm) bound, and 10^4 times below what a harmonic fill errs (next test).
    EXPECT_LT(err, 1e-6);
    for (std::size_t i = 0; i < s.z.size(); ++i) {
        if (!s.filled[i]) {
            EXPECT_EQ(s.z[i], truth.z[i]);  // present values are untouched
        }
    }
}

TEST(ThinPlateFill, HarmonicFillCannotReproduceTheEyeWallCurvature) {
    // docs/algorithms/onh.md "Thin-plate fill": for the eye wall (x^2 + y^2) / 2R over a disc of
    // radius 0.8 mm a harmonic fill errs by ~25 um at the centre: the membrane solution with the
    // constant boundary value r^2 / 2R is flat, 0.64 / 24 mm = 26.7 um above the true centre (the
    // discrete hole's boundary ring lies a little outside r, so slightly more).
    GridSurface s = quadratic_grid(200, 70, paraboloid);
    punch_hole(s, 0.8, 0.8);
    const std::vector<double> harmonic = harmonic_fill(s);
    GridSurface tp = s;
    thin_plate_fill(tp);
    double harm_err = 0.0;
    double tp_err = 0.0;
    for (std::size_t i = 0; i < s.z.size(); ++i) {
        if (!std::isnan(s.z[i])) continue;
        const int a = static_cast<int>(i) % s.cols;
        const int b = static_cast<int>(i) / s.cols;
        const double t = paraboloid(a * s.dx_mm, b * s.dy_mm);
        harm_err = std::max(harm_err, std::fabs(harmonic[i] - t));
        tp_err = std::max(tp_err, std::fabs(tp.z[i] - t));
    }
    EXPECT_GT(harm_err, 0.02);  // > 20 um
    EXPECT_LT(tp_err, 1e-6);    // same rounding argument as above
}

TEST(ThinPlateFill, HolesAtTheBorderAreFilledWithFiniteValues) {
    GridSurface s = quadratic_grid(40, 30, eye_wall);
    const GridSurface truth = s;
    for (int b = 0; b < 6; ++b) {
        for (int a = 0; a < 5; ++a) s.z[static_cast<std::size_t>(b * s.cols + a)] = kNaN;
    }
    thin_plate_fill(s);
    for (std::size_t i = 0; i < s.z.size(); ++i) {
        ASSERT_TRUE(std::isfinite(s.z[i]));
        // Near the corner the boundary stencils are one-sided: no exactness, but the energy
        // still pins the fill to the quadratic's scale (values ~1.2 mm, slopes < 0.1).
        EXPECT_NEAR(s.z[i], truth.z[i], 0.01);
    }
}

TEST(ThinPlateFill, RefusesWithoutThreeNonCollinearValues) {
    GridSurface s = quadratic_grid(20, 10, eye_wall);
    for (std::size_t i = 0; i < s.z.size(); ++i) {
        if (i % static_cast<std::size_t>(s.cols) != 3) s.z[i] = kNaN;  // one column left
    }
    EXPECT_THROW(thin_plate_fill(s), AnalysisError);
    GridSurface none = quadratic_grid(20, 10, eye_wall);
    for (auto& v : none.z) v = kNaN;
    EXPECT_THROW(thin_plate_fill(none), AnalysisError);
}

TEST(GridSurface, BilinearIsExactForBilinearFunctionsAndNanOutside) {
    GridSurface s = quadratic_grid(10, 8, [](double x, double y) { return 2 * x - y + 3 * x * y; });
    for (const auto& [x, y] : {std::pair{0.013, 0.05}, {0.09, 0.2}, {0.0, 0.0}}) {
        EXPECT_NEAR(s.bilinear(x, y), 2 * x - y + 3 * x * y, 1e-14);
    }
    const double xmax = 9 * s.dx_mm;
    const double ymax = 7 * s.dy_mm;
    EXPECT_NEAR(s.bilinear(xmax, ymax), 2 * xmax - ymax + 3 * xmax * ymax, 1e-14);
    EXPECT_TRUE(std::isnan(s.bilinear(-0.01, 0.1)));
    EXPECT_TRUE(std::isnan(s.bilinear(0.05, ymax + 0.01)));
}

TEST(GridSurface, GraphMeshFacesUpWithPositiveProjectedAreasCoveringTheGrid) {
    const GridSurface s = quadratic_grid(12, 9, eye_wall);
    mesh::Vertices V;
    mesh::Faces F;
    graph_mesh(s, V, F);
    ASSERT_EQ(V.rows(), 12 * 9);
    ASSERT_EQ(F.rows(), 2 * 11 * 8);
    double total = 0.0;
    for (Eigen::Index f = 0; f < F.rows(); ++f) {
        const Eigen::Vector3d a = V.row(F(f, 0));
        const Eigen::Vector3d b = V.row(F(f, 1));
        const Eigen::Vector3d c = V.row(F(f, 2));
        const double area = 0.5 * (b - a).cross(c - a).z();
        EXPECT_GT(area, 0.0);
        total += area;
    }
    EXPECT_NEAR(total, 11 * s.dx_mm * 8 * s.dy_mm, 1e-14);
    GridSurface holed = s;
    holed.z[5] = kNaN;
    EXPECT_THROW(graph_mesh(holed, V, F), AnalysisError);
}

}  // namespace
}  // namespace octshape::retina
