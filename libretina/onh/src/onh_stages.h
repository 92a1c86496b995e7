#pragma once
// The stages of the ONH analysis (analyse_onh, onh.cpp) and what they hand each other;
// internal to octshape::onh. The ILM surface (device line or level set) is built before, by
// build_ilm_surface (onh.h); analyse_onh then runs, in this order:
//
//   check_onh_inputs   volume scan, orientation and spacing notes, a valid ILM mesh
//   bmo_points         the BM height field (docs/algorithms/onh.md "Surfaces") and the
//                      BMO points: from a file or detected at the BM gap (onh.md "BMO",
//                      bmo.cpp)
//   bmo_ellipse        the ellipse through them, resampled; its anatomical orientation
//   rpe_surface        the BM filled inside the BMO (thin plate) and its graph mesh
//   orient_ilm         the ILM with its normals towards the vitreous; mesh quality
//   ilm_regions        correspondence, regions and volumes (Eq. 8.3-8.17); disc and fill QC
//   centre_and_shape   CONHT (Eq. 8.10), bending energy (Eq. 8.18-8.20), local features
//   minimum_rim_width  BMO-MRW per point, per sector and its area (Eq. 8.21-8.23)
//
// Each stage reads the fields of OnhResult that the stages before it wrote and writes the
// fields named at its declaration. Decisions and measurements: docs/algorithms/onh.md.

#include <cstddef>
#include <optional>
#include <vector>

#include "octshape/io/scan.h"
#include "octshape/mesh/mesh.h"
#include "octshape/retina/levelset.h"
#include "octshape/retina/onh.h"
#include "octshape/retina/radial_geometry.h"
#include "octshape/retina/scan_geometry.h"

namespace octshape::retina::onh_detail {

// Writes eye, oriented_from_positions, grid_to_anatomical and their notes / QC flags.
// AnalysisError when the ILM has no faces or is not a valid mesh.
void check_onh_inputs(const io::Scan& scan, const ScanGeometry& geo, const IlmSurface& ilm,
                      OnhResult& r);

// Returns the BM height field; writes bmo_source, bmo_measured and, for the automatic
// detection, bmo_points_per_bscan, bmo_gap_area_mm2, bmo_other_gaps and their notes.
// AnalysisError when the BM line is missing everywhere.
[[nodiscard]] GridSurface bmo_points(const io::Scan& scan, const OnhParams& params,
                                     const std::optional<std::vector<BmoPoint>>& file_points,
                                     OnhResult& r);

// Writes ellipse (from bmo_measured) and bmo_orientation_anatomical_deg; a QC flag when the
// points lie more than 50 µm (RMS) from it.
// Angles are anatomical through r.grid_to_anatomical (check_onh_inputs, or the radial check).
void bmo_ellipse(const OnhParams& params, OnhResult& r);

// Writes rpe (bm filled), rpe_V, rpe_F and the fill's QC: rpe_filled_vertices,
// rpe_fill_residual, rpe_fill_area_mm2, rpe_fill_outside_bmo_mm2 (needs ellipse).
// `scanned` (radial scans): the nodes the scan covers; the others get no RPE (NaN) after the
// fill, count in no fill QC, and the mesh has the cells of the covered nodes only. There the
// fill outside the BMO is reported but not flagged: between two lines whose BMO ends differ the
// interpolated BM is missing by construction (BM gaps on the lines themselves are counted by
// radial_bmo_points).
void rpe_surface(GridSurface bm, OnhResult& r,
                 const std::vector<std::uint8_t>* scanned = nullptr);

// Writes ilm_V, ilm_F (reversed when the signed projected area is negative: ilm_flipped),
// ilm_filled_vertices, face_projected_area_mm2, ilm_quality and the ILM's notes and QC flags.
// Returns the face geometry of the oriented ILM.
[[nodiscard]] mesh::FaceGeometry orient_ilm(const IlmSurface& ilm, OnhResult& r);

// Writes face_height_mm, face_region, faces_outside_rpe, the volumes and has_cup
// (measure_onh_regions), ilm_filled_in_disc and their notes / QC flags.
void ilm_regions(const IlmSurface& ilm, const OnhParams& params, OnhResult& r);

// Writes ilm_centre_height_mm, rpe_centre_height_mm, conht_mm (NaN when the vertical line
// through the BMO centre misses the ILM), bmo_region_area_mm2, bmo_tensor_eigenvalues and
// bending_energy (NaN without an ILM face inside the BMO), face_envt_strength on request.
void centre_and_shape(const mesh::FaceGeometry& g, const OnhParams& params, OnhResult& r);

// Writes mrw_points_mm, mrw_mm, bmo_anatomical_deg, the MRW summaries, the 12 sectors (NaN
// without a point) and mrw_area_mm2.
// dx_mm, dy_mm: the scan's lateral sampling steps (mrw_area_harmonics).
void minimum_rim_width(double dx_mm, double dy_mm, OnhResult& r);

// Harmonics kept of the closest-point curve for the MRW area (Eq. 8.23): its wavelengths down
// to 4 sampling steps of the scan's coarser lateral direction (max(ScaleX, Distance)): what the
// segmented, meshed ILM resolves (2 steps, Nyquist) with a factor 2 of margin. Shorter ones are
// the closest points' jumps between facets from one BMO point to the next
// (docs/algorithms/onh.md "MRW area"). At least 8.
[[nodiscard]] int mrw_area_harmonics(double bmo_perimeter_mm, double dx_mm, double dy_mm);

// A closed curve sampled uniformly in its parameter, low-passed: the truncated discrete Fourier
// series of each coordinate up to `harmonics`. A curve of at most 2 harmonics + 1 points is
// returned as it is.
[[nodiscard]] std::vector<Eigen::Vector3d> low_pass_closed_curve(
    const std::vector<Eigen::Vector3d>& c, int harmonics);

// The last gate: a result that is not finite where it is reported, or not physically possible
// (a BMO ellipse larger than the scanned field or centred outside it; a volume negative or
// larger than the scanned box; a CONHT, MRW or surface height beyond the image's depth) is
// refused with AnalysisError naming the value, what was found and what is possible. A success
// never carries one (docs/algorithms/onh.md "What the analysis refuses").
void check_onh_result(const OnhResult& r, const io::Scan& scan);
// The same for a field of width x height mm (grid frame from 0) and `depth` mm.
void check_onh_result(const OnhResult& r, double width, double height, double depth);

// AnalysisError unless the ILM surface has faces and is a valid mesh.
void check_ilm_mesh(const IlmSurface& ilm);

// Height of the topmost crossing of the vertical line through (x, y) with the mesh: what the
// line meets first coming from the vitreous (docs/algorithms/onh.md, `conht_mm`). NaN if it misses
// the mesh.
[[nodiscard]] double top_crossing(const mesh::Vertices& V, const mesh::Faces& F, double x,
                                  double y);

// Anatomical angle (deg, [0, 360)) of a grid direction under r.grid_to_anatomical.
[[nodiscard]] double anatomical_deg(const OnhResult& r, double dx, double dy);
// Clock-hour sector of an anatomical angle: k holds [30 k - 15, 30 k + 15) deg, k in 0..11.
[[nodiscard]] inline std::size_t clock_hour(double anatomical_deg) {
    return static_cast<std::size_t>(static_cast<int>((anatomical_deg + 15.0) / 30.0) % 12);
}

// ---------------------------------------------------------------------------------------------
// The radial path (onh_radial.cpp, docs/algorithms/onh.md "Radial scans"): analyse_onh_radial
// runs radial_check -> radial_bmo_points -> the volume's bmo_ellipse, rpe_surface (on the
// scanned circle), orient_ilm, ilm_regions, centre_and_shape, minimum_rim_width ->
// inplane_rim_width -> check_onh_result. Between the lines every surface is interpolated
// linearly in angle at constant distance from the crossing (radial_height_field).

// The square grid a radial scan is analysed on: nodes step_mm apart, the crossing at
// crossing_mm, x = SLO +x, y = superior (the radial frame shifted); `scanned` marks the nodes
// within radius_mm of the crossing (the circle every half-line covers).
struct RadialOnhGrid {
    RadialGeometry geo;
    int size_x = 0;  // A-scans per line
    int n = 0;       // nodes per side
    double step_mm = 0.0;
    double radius_mm = 0.0;
    Eigen::Vector2d crossing_mm = Eigen::Vector2d::Zero();
    std::vector<std::uint8_t> scanned;  // n * n, row-major (b * n + a)
    // The 2 x lines half-lines sorted by their angle in the radial frame ([0, 2 pi)).
    std::vector<double> half_angle;
    std::vector<int> half_line;
    std::vector<double> half_sign;  // +1: towards the line's End, -1: towards its Start

    // Grid mm of A-scan `ascan` (fractional) of line `line`.
    [[nodiscard]] Eigen::Vector2d ascan_grid_mm(int line, double ascan) const {
        return crossing_mm + geo.ascan_mm(line, ascan, size_x);
    }
    // Fractional A-scan index of the point `r` mm from the crossing along half-line h.
    [[nodiscard]] double half_line_ascan(int h, double r) const;
    // The two half-lines about a point p (grid mm relative to the crossing, p != 0) and the
    // weight of the second: h0, h1 neighbours in angle (a_h0 <= theta < a_h1, cyclic), w =
    // (theta - a_h0) / (a_h1 - a_h0) — the interpolation linear in angle of every surface.
    struct Blend {
        int h0 = 0, h1 = 0;
        double w = 0.0;
    };
    [[nodiscard]] Blend blend_at(const Eigen::Vector2d& p) const;
};

// AnalysisError (one line) when the radial scan cannot be placed or analysed (radial_geometry;
// fewer than 3 lines or A-scans; non-positive scales; lines shorter than 0.5 mm each side).
[[nodiscard]] RadialOnhGrid radial_onh_grid(const io::Scan& scan);

// Segmentation line `layer` interpolated onto the grid: at a node r from the crossing between
// half-lines j and j+1 (angles a_j <= theta < a_j+1), (1 - w) f_j(r) + w f_j+1(r) with
// w = (theta - a_j) / (a_j+1 - a_j) and f(r) linear between the line's A-scans. NaN outside
// the scanned circle and where a value used is missing.
[[nodiscard]] GridSurface radial_height_field(const io::Scan& scan, const RadialOnhGrid& grid,
                                              io::Layer layer);

// The device ILM of a radial scan on its grid (missing values thin-plate filled inside the
// scanned circle), meshed over the scanned circle.
[[nodiscard]] IlmSurface radial_device_ilm_surface(const io::Scan& scan);

// The level-set ILM of a radial scan (onh_radial_levelset.cpp): a 2-D level set per B-scan
// (the volume's stages on one B-scan), each B-scan's signed distance to its zero-level curve
// interpolated between the lines like radial_height_field onto the grid, marching cubes, the
// clean-up (clip to the scanned circle, largest component, normals up) and RoFi. The curves go
// to bscan_curves (the in-plane MRW). AnalysisError for a B-scan without pixels, without an
// image or without a device ILM (naming it).
[[nodiscard]] IlmSurface radial_levelset_ilm_surface(const io::Scan& scan,
                                                     const LevelSetParams& params = {});

// The radial driver (analyse_onh dispatches to it).
[[nodiscard]] OnhResult analyse_onh_radial(
    const io::Scan& scan, const IlmSurface& ilm, const OnhParams& params,
    const std::optional<std::vector<BmoPoint>>& bmo_file_points);

}  // namespace octshape::retina::onh_detail
