#include "octshape/io/registration.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>

#include <vtkCellArray.h>
#include <vtkIterativeClosestPointTransform.h>
#include <vtkLandmarkTransform.h>
#include <vtkMatrix4x4.h>
#include <vtkNew.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkSmartPointer.h>

#include "octshape/mesh/closest_point.h"

namespace octshape::io {
namespace {

vtkSmartPointer<vtkPolyData> polydata(const mesh::Vertices& V, const mesh::Faces* F) {
    vtkNew<vtkPoints> points;
    points->SetDataTypeToDouble();
    points->SetNumberOfPoints(V.rows());
    for (Eigen::Index i = 0; i < V.rows(); ++i) points->SetPoint(i, V(i, 0), V(i, 1), V(i, 2));
    auto poly = vtkSmartPointer<vtkPolyData>::New();
    poly->SetPoints(points);
    if (F != nullptr) {
        vtkNew<vtkCellArray> polys;
        polys->AllocateExact(F->rows(), F->rows() * 3);
        for (Eigen::Index f = 0; f < F->rows(); ++f) {
            const std::array<vtkIdType, 3> ids{(*F)(f, 0), (*F)(f, 1), (*F)(f, 2)};
            polys->InsertNextCell(3, ids.data());
        }
        poly->SetPolys(polys);
    }
    return poly;
}

}  // namespace

void IcpParams::validate() const {
    if (max_iterations < 1) throw std::invalid_argument("max_iterations must be >= 1");
    if (max_landmarks < 0) throw std::invalid_argument("max_landmarks must be >= 0");
    if (!(tolerance > 0.0) || !std::isfinite(tolerance)) {
        throw std::invalid_argument("tolerance must be > 0");
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
        throw std::invalid_argument("source: no vertex or a non-finite vertex");
    }
    const mesh::TriangleTree tree(target_V, target_F);  // validates the target
    const auto source = polydata(source_V, nullptr);
    const auto target = polydata(target_V, &target_F);
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
    icp->Update();

    IcpResult out;
    vtkMatrix4x4* M = icp->GetMatrix();
    Eigen::Matrix4d m;
    for (int r = 0; r < 4; ++r) {
        for (int c = 0; c < 4; ++c) m(r, c) = M->GetElement(r, c);
    }
    out.transform.matrix() = m;
    out.iterations = icp->GetNumberOfIterations();
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
