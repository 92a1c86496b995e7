// Point-set and shape-analysis benchmark: one table (case, size, wall time, process CPU time,
// wall time per point or vertex, ratio).
//  - point-set NVT denoising (libmesh pointset.h, 30 iterations) of a ~50k-point noisy cube
//    with 1 and 2 threads, PCA (default) and shifted initial normals (ratio = time / PCA
//    1-thread time); the CPU column shows the work when
//    the machine is shared (wall > CPU for 1 thread means the process waited for a core);
//  - VTK ICP of a 5°-rotated copy of a ~50k-vertex ILM-like surface (io/registration.h) and the
//    mean shape of 3 aligned surfaces (mesh/meanshape.h; ratio = time / ICP time).
//
// Usage: octshape_shape_bench   (scripts/bench.sh runs it on Release)

#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <random>
#include <vector>

#include "fixtures/ilm_patch.h"
#include "octshape/io/registration.h"
#include "octshape/mesh/meanshape.h"
#include "octshape/mesh/pointset.h"

namespace {

using octshape::mesh::Faces;
using octshape::mesh::Vertices;
using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t0) {
    return std::chrono::duration<double>(Clock::now() - t0).count();
}

double cpu_seconds() { return static_cast<double>(std::clock()) / CLOCKS_PER_SEC; }

void row(const char* name, long long size, double wall, double cpu, double ratio) {
    std::printf("%-34s %8lld %9.3f %9.3f %9.2f %7.2f", name, size, wall, cpu,
                size > 0 ? 1e6 * wall / static_cast<double>(size) : 0.0, ratio);
}

// m×m cell-centred points on each face of the unit cube, Gaussian noise 0.3 × spacing.
Vertices noisy_cube(int m) {
    Vertices P(6 * m * m, 3);
    std::mt19937 rng(1);
    std::normal_distribution<double> gauss(0.0, 0.3 / m);
    int i = 0;
    for (int face = 0; face < 6; ++face) {
        const int axis = face / 2;
        for (int a = 0; a < m; ++a) {
            for (int b = 0; b < m; ++b) {
                Eigen::Vector3d p;
                p(axis) = face % 2 == 0 ? 0.5 : -0.5;
                p((axis + 1) % 3) = (a + 0.5) / m - 0.5;
                p((axis + 2) % 3) = (b + 0.5) / m - 0.5;
                for (int k = 0; k < 3; ++k) p(k) += gauss(rng);
                P.row(i++) = p.transpose();
            }
        }
    }
    return P;
}

}  // namespace

int main() {
    std::printf("%-34s %8s %9s %9s %9s %7s\n", "case", "points", "time_s", "cpu_s", "us/point",
                "ratio");
    const Vertices cube = noisy_cube(91);  // 6 × 91² = 49 686 points
    double t1 = 0.0;
    struct Case {
        const char* name;
        octshape::mesh::NormalEstimator normals;
        int threads;
        bool snap;
    };
    constexpr auto kPca = octshape::mesh::NormalEstimator::kPca;
    constexpr auto kShifted = octshape::mesh::NormalEstimator::kShifted;
    for (const Case& k : {Case{"pointset denoise p=30, 1 thread", kPca, 1, true},
                          Case{"pointset denoise p=30, 2 threads", kPca, 2, true},
                          Case{"  no edge snapping, 1 thread", kPca, 1, false},
                          Case{"  no edge snapping, 2 threads", kPca, 2, false},
                          Case{"  shifted normals, 1 thread", kShifted, 1, true},
                          Case{"  shifted normals, 2 threads", kShifted, 2, true}}) {
        const int threads = k.threads;
        octshape::mesh::PointSetParams p;
        p.threads = threads;
        p.normals = k.normals;
        p.snap_edges = k.snap;
        const auto t0 = Clock::now();
        const double c0 = cpu_seconds();
        const auto r = octshape::mesh::pointset_denoise(cube, p);
        const double t = seconds_since(t0);
        const double c = cpu_seconds() - c0;
        if (t1 == 0.0) t1 = t;
        row(k.name, static_cast<long long>(cube.rows()), t, c, t / t1);
        std::printf("\n%-34s %8s %9.3f %9s %9s %7.2f\n", "  of which set-up (tree, normals)", "",
                    r.seconds_setup, "", "", r.seconds_setup / t1);
        std::printf("%-34s %8s %9.3f %9s %9s %7.2f\n", "  of which iterations", "",
                    r.seconds_iterations, "", "", r.seconds_iterations / t1);
        std::printf("%-34s %8d %9.3f %9s %9s %7.2f\n", "  of which edge snapping (points)",
                    r.snapped_points, r.seconds_snap, "", "", r.seconds_snap / t1);
    }

    const octshape::mesh::Surface ref = octshape::test::ilm_patch(223);  // 224² = 50 176 vertices
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = Eigen::AngleAxisd(5.0 * M_PI / 180.0, Eigen::Vector3d(0.3, 0.2, 1.0).normalized())
                     .toRotationMatrix();
    T.translation() << 0.05, -0.03, 0.02;
    const Vertices moved = octshape::io::transformed(ref.V, T);
    auto t0 = Clock::now();
    double c0 = cpu_seconds();
    const auto icp = octshape::io::icp_rigid(moved, ref.V, ref.F);
    const double t_icp = seconds_since(t0);
    const double c_icp = cpu_seconds() - c0;
    const double err = Eigen::AngleAxisd(icp.transform.linear() * T.linear()).angle() * 180 / M_PI;
    row("ICP (VTK, 5000 landmarks; refined)", static_cast<long long>(ref.V.rows()), t_icp, c_icp,
        1.0);
    std::printf("   (%d VTK + %d point-to-plane iterations, rotation error %.1e deg)\n",
                icp.iterations, icp.refine_iterations, err);
    const std::vector<octshape::mesh::Surface> others{
        {octshape::io::transformed(moved, icp.transform), ref.F}, {ref.V, ref.F}};
    t0 = Clock::now();
    c0 = cpu_seconds();
    const auto mean = octshape::mesh::mean_shape(ref, others);
    const double t_mean = seconds_since(t0);
    row("mean shape of 3, 1 thread", static_cast<long long>(ref.V.rows()), t_mean,
        cpu_seconds() - c0, t_mean / t_icp);
    std::printf("   (max SD %.1e mm)\n", mean.sd.maxCoeff());
    return 0;
}
