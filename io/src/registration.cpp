#include "octshape/io/registration.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>
#include <vector>

#include <Eigen/Eigenvalues>

#include <vtkCellArray.h>
#include <vtkIterativeClosestPointTransform.h>
#include <vtkLandmarkTransform.h>
#include <vtkMatrix4x4.h>
#include <vtkNew.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkSmartPointer.h>

#include "mesh_io_detail.h"
#include "octshape/error.h"
#include "octshape/io/vtk_errors.h"
#include "octshape/mesh/closest_point.h"

namespace octshape::io {
namespace {

// Point-to-plane refinement of `T` (source → target), see registration.h. Returns the steps
// run.
int refine_point_to_plane(const mesh::Vertices& source_V,
                          const mesh::Vertices& target_V,
                          const mesh::Faces& target_F,
                          const mesh::TriangleTree& tree,
                          double diagonal,
                          int max_steps,
                          Eigen::Isometry3d& T) {
    const mesh::FaceGeometry geometry = mesh::face_geometry(target_V, target_F);
    const Eigen::Index n = source_V.rows();
    std::vector<Eigen::Vector3d> p(static_cast<std::size_t>(n));
    std::vector<mesh::SurfaceHit> hit(static_cast<std::size_t>(n));
    std::vector<double> dist(static_cast<std::size_t>(n));
    for (int step = 0; step < max_steps; ++step) {
        Eigen::Vector3d centre = Eigen::Vector3d::Zero();
        for (Eigen::Index i = 0; i < n; ++i) {
            const auto k = static_cast<std::size_t>(i);
            p[k] = T * Eigen::Vector3d(source_V.row(i).transpose());
            hit[k] = tree.closest(p[k]);
            dist[k] = hit[k].distance;
            centre += p[k];
        }
        centre /= static_cast<double>(n);
        std::vector<double> sorted = dist;
        std::nth_element(sorted.begin(), sorted.begin() + n / 2, sorted.end());
        const double cut = 3.0 * sorted[static_cast<std::size_t>(n / 2)] + 1e-12 * diagonal;
        // Normal equations of r_i + [(p_i − c) × n_i, n_i] · (ω, τ), rotation about the centre c.
        Eigen::Matrix<double, 6, 6> A = Eigen::Matrix<double, 6, 6>::Zero();
        Eigen::Matrix<double, 6, 1> b = Eigen::Matrix<double, 6, 1>::Zero();
        int used = 0;
        for (std::size_t k = 0; k < p.size(); ++k) {
            if (dist[k] > cut) continue;
            const Eigen::Vector3d nrm = geometry.normals.row(hit[k].face).transpose();
            Eigen::Matrix<double, 6, 1> J;
            J << (p[k] - centre).cross(nrm), nrm;
            const double r = nrm.dot(p[k] - hit[k].point);
            A.selfadjointView<Eigen::Lower>().rankUpdate(J);
            b -= r * J;
            ++used;
        }
        if (used < 6) break;
        A.triangularView<Eigen::Upper>() = A.transpose();
        // A surface with a symmetry (a plane, a sphere) leaves directions undetermined: solve
        // in the well-determined eigen-directions only.
        const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 6, 6>> eig(A);
        const double top = eig.eigenvalues().maxCoeff();
        if (!(top > 0.0)) break;
        Eigen::Matrix<double, 6, 1> x = Eigen::Matrix<double, 6, 1>::Zero();
        for (int e = 0; e < 6; ++e) {
            const double lambda = eig.eigenvalues()(e);
            if (lambda > 1e-12 * top) {
                const auto v = eig.eigenvectors().col(e);
                x += (v.dot(b) / lambda) * v;
            }
        }
        const Eigen::Vector3d omega = x.head<3>();
        const Eigen::Vector3d tau = x.tail<3>();
        Eigen::Isometry3d D = Eigen::Isometry3d::Identity();
        if (omega.norm() > 0.0) {
            D.linear() = Eigen::AngleAxisd(omega.norm(), omega.normalized()).toRotationMatrix();
        }
        D.translation() = centre - D.linear() * centre + tau;
        T = D * T;
        // Largest movement of a source point: |ω| × lever arm + |τ| bounds it.
        double arm = 0.0;
        for (const auto& q : p) arm = std::max(arm, (q - centre).norm());
        if (omega.norm() * arm + tau.norm() < 1e-12 * diagonal) return step + 1;
    }
    return max_steps;
}

}  // namespace

void IcpParams::validate() const {
    if (max_iterations < 1) throw UsageError("max_iterations must be >= 1");
    if (max_landmarks < 0) throw UsageError("max_landmarks must be >= 0");
    if (refine_iterations < 0) throw UsageError("refine_iterations must be >= 0");
    if (!(tolerance > 0.0) || !std::isfinite(tolerance)) {
        throw UsageError("tolerance must be > 0");
    }
}

mesh::Vertices transformed(const mesh::Vertices& V, const Eigen::Isometry3d& T) {
    mesh::Vertices out = V * T.linear().transpose();
    out.rowwise() += T.translation().transpose();
    return out;
}

IcpResult icp_rigid(const mesh::Vertices& source_V,
                    const mesh::Vertices& target_V,
                    const mesh::Faces& target_F,
                    const IcpParams& params) {
    params.validate();
    if (source_V.rows() == 0 || !source_V.allFinite()) {
        throw DataError("source: no vertex or a non-finite vertex");
    }
    const mesh::TriangleTree tree(target_V, target_F);  // validates the target
    const auto source = detail::to_polydata(source_V, mesh::Faces(0, 3), {}, {});
    const auto target = detail::to_polydata(target_V, target_F, {}, {});
    const double diagonal =
        (target_V.colwise().maxCoeff() - target_V.colwise().minCoeff()).norm();

    vtkNew<vtkIterativeClosestPointTransform> icp;
    icp->SetSource(source);
    icp->SetTarget(target);
    icp->GetLandmarkTransform()->SetModeToRigidBody();
    icp->SetMaximumNumberOfIterations(params.max_iterations);
    // VTK's default is 200 landmarks; 0 asks for every vertex.
    const auto nv = static_cast<int>(source_V.rows());
    icp->SetMaximumNumberOfLandmarks(params.max_landmarks == 0 ? nv
                                                                : std::min(nv, params.max_landmarks));
    icp->SetStartByMatchingCentroids(params.match_centroids ? 1 : 0);
    icp->SetCheckMeanDistance(1);
    icp->SetMeanDistanceModeToRMS();
    icp->SetMaximumMeanDistance(params.tolerance * std::max(diagonal, 1e-300));
    icp->Modified();
    run_vtk(icp, [&] { icp->Update(); }, [](const std::string& m) {
        return AnalysisError("rigid registration (VTK ICP): " + m);
    });

    IcpResult out;
    vtkMatrix4x4* M = icp->GetMatrix();
    Eigen::Matrix4d m;
    for (int r = 0; r < 4; ++r) {
        for (int c = 0; c < 4; ++c) m(r, c) = M->GetElement(r, c);
    }
    out.transform.matrix() = m;
    out.iterations = icp->GetNumberOfIterations();
    if (params.refine_iterations > 0) {
        out.refine_iterations = refine_point_to_plane(source_V, target_V, target_F, tree,
                                                      std::max(diagonal, 1e-300),
                                                      params.refine_iterations, out.transform);
    }
    out.rotation_deg =
        Eigen::AngleAxisd(out.transform.linear()).angle() * 180.0 / 3.14159265358979323846;
    out.translation = out.transform.translation().norm();
    const mesh::Vertices moved = transformed(source_V, out.transform);
    double sum = 0.0;
    double sum2 = 0.0;
    for (Eigen::Index i = 0; i < moved.rows(); ++i) {
        const double d = tree.closest(moved.row(i).transpose()).distance;
        sum += d;
        sum2 += d * d;
        out.max_distance = std::max(out.max_distance, d);
    }
    const auto n = static_cast<double>(moved.rows());
    out.mean_distance = sum / n;
    out.rms_distance = std::sqrt(sum2 / n);
    return out;
}

}  // namespace octshape::io
