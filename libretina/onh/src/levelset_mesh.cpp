// The mesh stages of the level-set ILM (levelset_stages.h): marching cubes over slabs, the
// clean-up (valid-area clip, largest component, orientation) and RoFi.

#include <vtkCellArray.h>
#include <vtkCellArrayIterator.h>
#include <vtkFloatArray.h>
#include <vtkFlyingEdges3D.h>
#include <vtkImageData.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkSmartPointer.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <string>
#include <unordered_map>
#include <vector>

#include "levelset_stages.h"
#include "octshape/error.h"
#include "octshape/io/vtk_errors.h"
#include "octshape/mesh/components.h"
#include "octshape/mesh/rofi.h"

namespace octshape::retina::levelset_detail {

Surface surface(const Windows& w, const std::vector<float>& phi, const Spacing& h,
                int slab_bscans) {
    const int nb = w.nb, na = w.na;
    const double hx = h.hx, hy = h.hy, hz = h.hz;
    const std::size_t ncol = w.lo.size();
    std::vector<Eigen::Vector3d> points;
    std::vector<std::array<int, 3>> tris;
    // Rows outside a window: ±ScaleZ (vitreous above, tissue below), a distance-like value
    // for the depth edge that joins them to the window.
    const auto far = static_cast<float>(hz);
    // |φ| below 0.1 ScaleZ (0.39 µm) is set to ±0.1 ScaleZ (φ ≤ 0 counts as tissue): every
    // surface point then lies well inside its grid edge, far above the float rounding of the
    // output points (~5e-7 mm), so no two points coincide and the merge of the slabs' shared
    // planes by exact coordinates is unambiguous (manifold output). Where the zero level
    // passes through a voxel (φ ≈ 0 out of the evolution, most likely a voxel that oscillated
    // about its equilibrium until its tile froze), every edge at it gets a point next to it:
    // slivers with almost no area, which RoFi turned over (the fold of the cupped volume with
    // the cleft, 1.1e-4 mm² at 1e-2 ScaleZ; docs/algorithms/levelset.md "Folds"). 0.1 ScaleZ
    // moves the zero level by at most 0.1 px there, a tenth of the level set's own offset.
    const auto eps = static_cast<float>(0.1 * hz);
    std::unordered_map<std::uint64_t, int> shared_prev, shared_next;
    std::vector<float> dense;
    // One depth range for all slabs, so that a point on a shared B-scan plane is computed
    // from the same inputs (edge, end values, origin) in both slabs and comes out
    // bit-identical: the merge below is exact, never by tolerance.
    int k0 = std::numeric_limits<int>::max(), k1 = 0;
    for (std::size_t c = 0; c < ncol; ++c) {
        k0 = std::min(k0, w.lo[c]);
        k1 = std::max(k1, w.lo[c] + w.len[c]);
    }
    k0 -= 1;  // one row of vitreous above and of tissue below every window
    const int nk = k1 - k0 + 1;
    int b0 = 0;
    while (true) {
        const int b1 = std::min(nb - 1, b0 + slab_bscans - 1);
        const int ns = b1 - b0 + 1;
        dense.assign(static_cast<std::size_t>(na) * static_cast<std::size_t>(ns) * static_cast<std::size_t>(nk), 0.0F);
        for (int bb = 0; bb < ns; ++bb) {
            for (int a = 0; a < na; ++a) {
                const auto c = static_cast<std::size_t>((b0 + bb) * na + a);
                const int lo = w.lo[c], hi = lo + w.len[c];
                for (int k = 0; k < nk; ++k) {
                    const int d = k0 + k;
                    float v = d < lo ? far : (d >= hi ? -far : phi[static_cast<std::size_t>(w.offset[c] + (d - lo))]);
                    if (std::abs(v) < eps) v = v > 0.0F ? eps : -eps;
                    dense[(static_cast<std::size_t>(k) * static_cast<std::size_t>(ns) + static_cast<std::size_t>(bb)) *
                              static_cast<std::size_t>(na) +
                          static_cast<std::size_t>(a)] = v;
                }
            }
        }
        vtkNew<vtkFloatArray> arr;
        arr->SetNumberOfComponents(1);
        arr->SetArray(dense.data(), static_cast<vtkIdType>(dense.size()), 1);
        vtkNew<vtkImageData> img;
        img->SetDimensions(na, ns, nk);
        img->SetSpacing(hx, hy, hz);
        img->SetOrigin(0.0, b0 * hy, k0 * hz);
        img->GetPointData()->SetScalars(arr);
        vtkNew<vtkFlyingEdges3D> fe;
        fe->SetInputData(img);
        fe->SetValue(0, 0.0);
        fe->ComputeNormalsOff();
        fe->ComputeGradientsOff();
        fe->ComputeScalarsOff();
        fe->InterpolateAttributesOff();
        io::run_vtk(fe, [&] { fe->Update(); }, [](const std::string& m) {
            return AnalysisError("level-set ILM: marching cubes (VTK): " + m);
        });
        vtkPolyData* out = fe->GetOutput();
        const vtkIdType np = out->GetNumberOfPoints();
        std::vector<int> map(static_cast<std::size_t>(np));
        shared_next.clear();
        for (vtkIdType i = 0; i < np; ++i) {
            double q[3];
            out->GetPoint(i, q);
            // Points on the first / last B-scan plane of the slab are shared with the
            // neighbouring slab: keyed by the exact (float) bits of x and depth.
            const double j = q[1] / hy;
            const bool on_first = b0 > 0 && std::abs(j - b0) < 1e-3;
            const bool on_last = std::abs(j - b1) < 1e-3;
            std::uint64_t key = 0;
            if (on_first || on_last) {
                const float fx = static_cast<float>(q[0]);
                const float fz = static_cast<float>(q[2]);
                std::uint32_t ux = 0, uz = 0;
                std::memcpy(&ux, &fx, sizeof ux);
                std::memcpy(&uz, &fz, sizeof uz);
                key = (static_cast<std::uint64_t>(ux) << 32U) | uz;
            }
            int index = -1;
            if (on_first) {
                auto it = shared_prev.find(key);
                if (it != shared_prev.end()) index = it->second;
            }
            if (index < 0) {
                index = static_cast<int>(points.size());
                points.emplace_back(q[0], q[1], -q[2]);
            }
            if (on_last) shared_next.emplace(key, index);
            map[static_cast<std::size_t>(i)] = index;
        }
        auto iter = vtk::TakeSmartPointer(out->GetPolys()->NewIterator());
        for (iter->GoToFirstCell(); !iter->IsDoneWithTraversal(); iter->GoToNextCell()) {
            vtkIdType n = 0;
            const vtkIdType* ids = nullptr;
            iter->GetCurrentCell(n, ids);
            if (n != 3) continue;
            const std::array<int, 3> t = {map[static_cast<std::size_t>(ids[0])], map[static_cast<std::size_t>(ids[1])],
                                          map[static_cast<std::size_t>(ids[2])]};
            if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) continue;
            tris.push_back(t);
        }
        shared_prev.swap(shared_next);
        if (b1 == nb - 1) break;
        b0 = b1;
    }
    if (tris.empty()) throw AnalysisError("level-set ILM: marching cubes found no surface");
    Surface s;
    s.V.resize(static_cast<Eigen::Index>(points.size()), 3);
    for (std::size_t i = 0; i < points.size(); ++i) s.V.row(static_cast<Eigen::Index>(i)) = points[i].transpose();
    points = std::vector<Eigen::Vector3d>();
    s.F.resize(static_cast<Eigen::Index>(tris.size()), 3);
    for (std::size_t f = 0; f < tris.size(); ++f) {
        s.F.row(static_cast<Eigen::Index>(f)) << tris[f][0], tris[f][1], tris[f][2];
    }
    return s;
}

CleanUp clean_up(Surface& s, const std::vector<std::uint8_t>& valid, int nb, int na,
                 const Spacing& h) {
    CleanUp out;
    std::vector<std::uint8_t> keep(static_cast<std::size_t>(s.F.rows()), 1);
    for (Eigen::Index f = 0; f < s.F.rows(); ++f) {
        const Eigen::Vector3d c =
            (s.V.row(s.F(f, 0)) + s.V.row(s.F(f, 1)) + s.V.row(s.F(f, 2))).transpose() / 3.0;
        const int a = std::clamp(static_cast<int>(std::lround(c.x() / h.hx)), 0, na - 1);
        const int b = std::clamp(static_cast<int>(std::lround(c.y() / h.hy)), 0, nb - 1);
        if (!valid[static_cast<std::size_t>(b * na + a)]) {
            keep[static_cast<std::size_t>(f)] = 0;
            ++out.clipped_faces;
        }
    }
    if (out.clipped_faces > 0) mesh::compact_faces(s.V, s.F, keep);
    if (s.F.rows() == 0) throw AnalysisError("level-set ILM: no surface inside the valid scan area");
    out.components = mesh::keep_largest_component(s.V, s.F);
    // The ILM faces the vitreous: the area-weighted normal points up.
    (void)mesh::orient_along(s.V, s.F, Eigen::Vector3d::UnitZ());
    return out;
}

void to_line_frame(Surface& s, const std::vector<double>& line_offset_px, const Spacing& h) {
    const bool moved = std::any_of(line_offset_px.begin(), line_offset_px.end(),
                                   [](double r) { return r != 0.0; });
    if (!moved) return;
    const int nb = static_cast<int>(line_offset_px.size());
    for (Eigen::Index i = 0; i < s.V.rows(); ++i) {
        const double j = std::clamp(s.V(i, 1) / h.hy, 0.0, nb - 1.0);
        const int b = std::min(static_cast<int>(std::floor(j)), std::max(0, nb - 2));
        const double f = nb > 1 ? j - b : 0.0;
        const double r = (1.0 - f) * line_offset_px[static_cast<std::size_t>(b)] +
                         (nb > 1 ? f * line_offset_px[static_cast<std::size_t>(b) + 1] : 0.0);
        s.V(i, 2) -= r * h.hz;  // z = -depth: deeper by r rows
    }
}

void smooth(Surface s, const LevelSetParams& params, LevelSetResult& res) {
    res.V_raw = s.V;
    if (params.smooth && params.rofi.iterations > 0) {
        try {
            mesh::DenoiseResult d = mesh::rofi_denoise(s.V, s.F, params.rofi);
            res.V = std::move(d.V);
            res.rofi_iterations = d.iterations;
            for (auto& wmsg : d.warnings) res.warnings.push_back("RoFi: " + wmsg);
        } catch (const DataError& e) {
            throw AnalysisError(std::string("level-set ILM: RoFi failed: ") + e.what());
        }
    } else {
        res.V = std::move(s.V);
    }
    res.F = std::move(s.F);
}

}  // namespace octshape::retina::levelset_detail
