#pragma once
// The stages of the level-set ILM (levelset_ilm, levelset.cpp) and what they hand each other;
// internal to octshape::onh. The order, and what each stage decides:
//
//   device_ilm       the scan's checks; the device ILM in pixels, missing values filled for the
//                    start and their columns marked invalid (levelset.cpp)
//   depth_windows    per column the rows around the device ILM that the level set may use
//   despeckle        v^0.25 and binomial passes per B-scan, stored on the windows; columns
//                    without pixel data marked invalid
//   initial_phi      φ0: signed vertical distance to the device ILM
//   ---- the pixels are no longer needed (levelset_ilm_releasing_pixels frees them here) ----
//   evolve           the narrow-band Chan–Vese evolution to convergence (levelset_evolve.cpp)
//   surface          marching cubes (vtkFlyingEdges3D) over slabs of B-scans, merged exactly
//                    (levelset_mesh.cpp)
//   clean_up         clip to the valid area, largest connected component, normals up
//   smooth           RoFi with the level-set defaults
//
// Method, equations (LS-1 …) and measurements: docs/algorithms/levelset.md.

#include <cstdint>
#include <string>
#include <vector>

#include "octshape/io/scan.h"
#include "octshape/mesh/mesh.h"
#include "octshape/retina/levelset.h"

namespace octshape::retina::levelset_detail {

// Voxel spacing along a (x, ScaleX), b (y, Distance) and d (depth, ScaleZ), mm.
struct Spacing {
    double hx = 0.0, hy = 0.0, hz = 0.0;
};

// ---- stage 1: the device ILM ----------------------------------------------------------------

struct DeviceIlm {
    int nb = 0, na = 0, nz = 0;  // B-scans, A-scans, rows
    Spacing h;
    std::vector<float> ilm;            // nb × na depths (px), missing ones filled
    std::vector<std::uint8_t> valid;   // nb × na: 0 = no device ILM (later: no pixels) → clipped
    int missing_columns = 0;           // LevelSetResult::missing_ilm_columns
};

// AnalysisError unless the scan is a volume with pixels and at least one device ILM value.
[[nodiscard]] DeviceIlm device_ilm(const io::Scan& scan);

// AnalysisError unless B-scans [b0, b0 + nb) all have pixels and those with data show some
// contrast (not all equal, not all missing); `where` names them in the message ("the B-scans",
// "radial B-scan 3": numbered from 0, as everywhere).
void require_image(const io::Scan& scan, int b0, int nb, const std::string& where);

// The device ILM of B-scans [b0, b0 + nb) in pixels, with spacing h; missing values NaN (not
// yet filled) and their columns marked invalid and counted.
[[nodiscard]] DeviceIlm device_ilm_rows(const io::Scan& scan, int b0, int nb, const Spacing& h);

// Fills NaN entries of an nb × na grid: linear interpolation along each B-scan (constant beyond
// its first and last value), then B-scans without a value copy the nearest B-scan that has one
// (ties: the lower index). Returns false if no value exists at all.
[[nodiscard]] bool fill_missing(std::vector<float>& ilm, int nb, int na);

// ---- stage 2: depth windows -----------------------------------------------------------------

// Column c = b * na + a holds rows [lo[c], lo[c] + len[c]), stored contiguously from offset[c].
struct Windows {
    int nb = 0, na = 0;
    std::vector<int> lo, len;
    std::vector<std::int64_t> offset;  // nb × na + 1
    std::int64_t size = 0;             // voxels over all windows

    [[nodiscard]] int column(int b, int a) const { return b * na + a; }
};

// Every column's window spans the device ILM depths within lateral_radius_mm (a box), widened
// by margin_mm above and below, clamped to the rows (docs: "Depth window"). AnalysisError when
// the windows are too large to index.
[[nodiscard]] Windows depth_windows(const DeviceIlm& ilm, const LevelSetParams& params);

// ---- stage 3: despeckle and φ0 --------------------------------------------------------------

// v^0.25 of every pixel, then despeckle_passes binomial [1 4 6 4 1]/16 passes per B-scan in x
// and depth over the rows the B-scan's windows use (padded by 2 per pass), stored on the
// windows; in x σ = min(1 px, max_sigma_x_mm / hx) (binomial_pass). A pixel at or above
// io::kInvalidThreshold (or NaN) counts as 0 and clears its column's valid flag. Needs
// ilm.valid sized nb × na.
// The windows' B-scan b is the scan's B-scan b0 + b.
[[nodiscard]] std::vector<float> despeckle(const io::Scan& scan, const Windows& w,
                                           int despeckle_passes, double max_sigma_x_mm,
                                           DeviceIlm& ilm, int b0 = 0);

// One [1 4 6 4 1]/16 pass along x (rows of length na) and then along depth over rows
// [0, rows), edge samples repeated. sigma_x_px < 1: along x the kernel [q, 1−2q, q] applied
// twice instead, q = sigma_x_px² / 4 (variance sigma_x_px²; q = 1/4 is the binomial).
void binomial_pass(std::vector<float>& buf, std::vector<float>& tmp, int rows, int na,
                   double sigma_x_px = 1.0);

// φ0 on the windows: (ilm − d) * hz, positive above the device ILM (mm).
[[nodiscard]] std::vector<float> initial_phi(const Windows& w, const DeviceIlm& ilm);

// ---- stage 4: evolution (levelset_evolve.cpp) ------------------------------------------------

// Evolves phi in place to convergence (or max_iterations) and fills the evolution diagnostics
// of `res` (iterations, converged, band_voxels, voxel updates, time_step, region means,
// front_reached_window_edge, warnings).
// `device_ilm` (nb × na, px; may be null): vitreous more than leak_depth_mm below it does not
// count towards c_vitreous (docs/algorithms/levelset.md "Vitreous mean").
void evolve(const Windows& w, std::vector<float>& phi, const std::vector<float>& image,
            const LevelSetParams& params, const Spacing& h, LevelSetResult& res,
            const float* device_ilm = nullptr);

// ---- stage 4b: leaks (docs/algorithms/levelset.md "Leaks") -----------------------------------

// The first words of the QC flag a leak raises (levelset_ilm puts the whole flag among its
// warnings; the ONH analysis moves it to the QC flags).
inline constexpr const char* kLeakFlag = "level-set front leaked into the tissue";

// One B-scan's leaking A-scans: `top` = each A-scan's top crossing (the first tissue row from
// the top, px), `device` its device ILM (px), `valid` its valid A-scans. An A-scan leaks when its
// top crossing lies more than `leak_rows` below the device ILM's running median over 9 A-scans,
// in a run of at least 3 leaking A-scans; returns 1 per A-scan of such a run, widened by 2
// A-scans on either side.
[[nodiscard]] std::vector<std::uint8_t> leak_runs(const std::vector<double>& top,
                                                  const float* device,
                                                  const std::uint8_t* valid,
                                                  int na,
                                                  double leak_rows);

// Shadowed tissue taken for vitreous (docs/algorithms/levelset.md "Leaks", "Hidden vitreous").
// Vitreous below the ILM seen from above (phi > 0 more than `leak_depth_mm` below the device
// ILM: a cavity under a rim lip, or a leak) must look like vitreous. Per B-scan, v = the median
// despeckled intensity of the vitreous above the device ILM (phi > 0, >= 3 rows above it); a
// hidden vitreous voxel brighter than v + (c_tissue - v) / 4 is tissue when it belongs to a
// 4-connected group of such voxels holding a 3 x 3 block of them (thicker than the one- or
// two-voxel blur of a true cavity wall). There, and in the hidden vitreous beside it, phi is
// lowered to the ramp hz (thr - I) / ((c_tissue - v) / 4), zero at the threshold. Returns the
// number of columns holding such a group and appends the B-scans they lie in.
[[nodiscard]] std::int64_t cut_shadowed_tissue(const Windows& w, std::vector<float>& phi,
                                               const std::vector<float>& image,
                                               const DeviceIlm& ilm, double c_tissue,
                                               double leak_depth_mm, std::vector<int>& bscans);

// The volume's leaks after the evolution: per B-scan the columns' top crossings on phi (rows
// above a window are vitreous, below tissue), leak_runs, and phi of every leaking column set to
// phi0 (the device ILM's signed vertical distance). Returns the number of such columns and the
// B-scans they lie in.
[[nodiscard]] std::int64_t fall_back_leaks(const Windows& w, std::vector<float>& phi,
                                           const DeviceIlm& ilm, double leak_depth_mm,
                                           std::vector<int>& bscans);

// ---- stages 5-7: the mesh (levelset_mesh.cpp) ------------------------------------------------

struct Surface {
    mesh::Vertices V;  // grid mm, z = −depth
    mesh::Faces F;
};

// The zero level of phi by marching cubes on slabs of slab_bscans B-scans sharing their last
// B-scan; the shared points are merged by their exact coordinates. Rows outside a window are
// ±hz (vitreous above, tissue below). AnalysisError when no surface is found.
[[nodiscard]] Surface surface(const Windows& w, const std::vector<float>& phi, const Spacing& h,
                              int slab_bscans);

struct CleanUp {
    std::int64_t clipped_faces = 0;  // faces whose centroid's column is not valid
    int components = 0;              // connected components after the clip
};

// Removes the faces whose centroid lies over an invalid column (nearest column), keeps the
// largest connected component and orients the normals up (+z). AnalysisError when no face is
// left inside the valid area.
// Moves the surface of a volume's level set from the pixels' frame into the lines' (registered)
// frame: each vertex deeper by the line offset (io::BScan::line_offset_px, rows) of its B-scan,
// interpolated linearly between B-scans at y / hy. No-op when every offset is 0.
void to_line_frame(Surface& s, const std::vector<double>& line_offset_px, const Spacing& h);

[[nodiscard]] CleanUp clean_up(Surface& s, const std::vector<std::uint8_t>& valid, int nb, int na,
                               const Spacing& h);

// RoFi with params.rofi when params.smooth (else V unchanged): sets res.V, res.V_raw, res.F,
// res.rofi_iterations and RoFi's warnings. AnalysisError when RoFi rejects the mesh.
void smooth(Surface s, const LevelSetParams& params, LevelSetResult& res);

}  // namespace octshape::retina::levelset_detail
