#pragma once
// Optic nerve head shape analysis (thesis §8.1, docs/algorithms/onh.md).
//
// The analysis measures an ILM given as a triangle mesh in the grid mm frame (x = A-scan index
// * ScaleX, y = B-scan index * Distance, z = -depth * ScaleZ), never as a height field, so an
// ILM that folds over itself is measured right: every volume is a sum of h_i times the *signed*
// projected area of face i (Eq. 8.8-8.9). Where the ILM comes from is the caller's choice
// (IlmSource); the RPE/BM surface, the BMO and every parameter come from here.

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "octshape/io/scan.h"
#include "octshape/mesh/mesh.h"
#include "octshape/retina/axial_registration.h"
#include "octshape/retina/lateral_registration.h"
#include "octshape/retina/bmo.h"
#include "octshape/retina/onh_surfaces.h"

namespace octshape::retina {

// Where the ILM surface comes from. `kDevice`: the device ILM line as a graph mesh (its missing
// values thin-plate filled). A level-set ILM plugs in as another source of an IlmSurface.
enum class IlmSource { kLevelSet, kDevice };

[[nodiscard]] std::string to_string(IlmSource source);
// Parses "levelset" or "device"; throws UsageError naming the valid sources otherwise.
[[nodiscard]] IlmSource ilm_source_from_string(const std::string& name);

// A segment of a curve in one B-scan's vertical plane: (s, z) mm, s along the line from its
// first A-scan, z the height (-depth).
struct PlaneSegment {
    double s0 = 0.0, z0 = 0.0, s1 = 0.0, z1 = 0.0;
};

// An ILM surface ready for the analysis.
struct IlmSurface {
    mesh::Vertices V;    // grid mm
    mesh::Faces F;       // any orientation; the analysis orients it (normals towards the vitreous)
    std::string source;  // "device", ...
    int filled_vertices = 0;  // vertices whose height was filled (device: missing ILM values)
    std::vector<std::uint8_t> vertex_filled;  // #V flags (1 = filled), or empty
    std::vector<std::string> notes;
    std::vector<std::string> qc_flags;  // e.g. "level set did not converge"
    // Radial scans with the level-set ILM: per B-scan (index = B-scan) the zero-level curve of
    // its 2-D level set in the B-scan's own plane; the in-plane MRW is measured on it. Empty
    // for the device ILM (the in-plane MRW then uses each B-scan's device ILM line).
    std::vector<std::vector<PlaneSegment>> bscan_curves;
    // Radial level set: the B-scans where the front leaked into the tissue (a cleft, a shadow),
    // how many A-scans fell back to the device ILM (a top-crossing leak) and in how many the
    // shadowed tissue under the ILM was cut from the vitreous (docs/algorithms/levelset.md
    // "Leaks").
    std::vector<int> leak_bscans;
    int leak_fallback_ascans = 0;
    int leak_cut_ascans = 0;
};

// The device ILM line as a graph mesh on the scan grid, missing values thin-plate filled
// (docs/algorithms/onh.md "Device ILM"). Throws AnalysisError if the line is absent or too
// sparse to fill.
[[nodiscard]] IlmSurface device_ilm_surface(const io::Scan& scan);

// The level-set ILM (retina/levelset.h: Chan–Vese narrow band on the B-scan intensities,
// marching cubes, RoFi) with its diagnostics as notes and QC flags. Needs the pixels. On a
// radial scan a 2-D level set per B-scan, interpolated between the lines (bscan_curves filled;
// docs/algorithms/onh.md "Radial scans").
[[nodiscard]] IlmSurface levelset_ilm_surface(const io::Scan& scan);

// Builds the ILM of `source` (the one place a new source is added).
[[nodiscard]] IlmSurface build_ilm_surface(const io::Scan& scan, IlmSource source);
// The same, but the level set frees the B-scan pixels (and clears scan.pixels_loaded) as soon as
// it has copied the intensities it needs (levelset_ilm_releasing_pixels): for callers that need
// no pixels afterwards (no QC pictures), so that the volume and the mesh stages never occupy
// memory together (docs/algorithms/levelset.md, "Speed and memory").
[[nodiscard]] IlmSurface build_ilm_surface_releasing_pixels(io::Scan& scan, IlmSource source);
// True when `source` needs the B-scan pixels (read_scan with ReadOptions::pixels).
[[nodiscard]] bool ilm_needs_pixels(IlmSource source);

struct OnhParams {
    int bmo_points = 360;          // resampled ellipse points (uniform in the parameter angle)
    double disc_radius_mm = 1.5;   // radius of the total-volume disc around the BMO centre
    bool local_features = false;   // per-face local ENVT feature strength (a mesh scalar for
                                   // pictures; ~0.5 s on a full-size graph, so only on request)
    BmoDetectionParams detection;  // automatic BMO detection
    // Axial registration of the B-scans before any surface is built (the caller applies it to
    // the scan: register_axially; analyse_onh only reports it).
    AxialRegistrationParams axial_registration;
    // Lateral registration of a volume's B-scans, before the axial one (the caller applies it:
    // register_laterally). The cut-off at most 25 B-scans: a full-size volume (145 B-scans
    // 30 um apart, 25 of them 0.755 mm) keeps the 0.75 mm cut-off, denser volumes keep its
    // share of the modes, K ~ 2N / 25 (docs/algorithms/onh.md "Lateral registration", dense
    // volumes: on 289 B-scans K = 12 read 6.9-8.0 um of shift on a still overhanging disc).
    LateralRegistrationParams lateral_registration{.smooth_wavelength_bscans = 25.0};

    void validate() const;  // throws UsageError naming the field
};

// Region bits of an ILM face (projected centroid).
enum OnhRegion : std::uint8_t {
    kRegionBmo = 1,      // inside the BMO ellipse
    kRegionDisc = 2,     // within disc_radius_mm of the BMO centre
    kRegionCup = 4,      // h < 0 (below the RPE)
    kRegionOutside = 8,  // centroid outside the RPE grid: no height, in no volume
};

struct MeshQuality {
    int vertices = 0;
    int faces = 0;
    int boundary_edges = 0;
    int nonmanifold_edges = 0;
    int degenerate_faces = 0;                  // zero area
    double negative_projected_area_mm2 = 0.0;  // faces facing down (undersides of overhangs)
    double quality = 0.0;                      // mean circumradius / shortest edge (1/sqrt 3 ideal)
};

// BMO-MRW in one B-scan's plane (radial scans, the device's definition): from a measured BMO
// point to the closest point of that B-scan's ILM curve.
struct InplaneMrw {
    int bscan = -1;
    int side = 0;  // -1: the gap's start (lower A-scan index), +1: its end
    Eigen::Vector3d bmo_mm = Eigen::Vector3d::Zero();  // grid mm
    Eigen::Vector3d ilm_mm = Eigen::Vector3d::Zero();  // the closest ILM point, grid mm
    double mrw_mm = 0.0;
    double anatomical_deg = 0.0;  // of the BMO point about the BMO ellipse centre
};

struct OnhResult {
    // A value the analysis could not measure (as CubeResult's kMissing): JSON null, CSV NA.
    static constexpr double kMissing = std::numeric_limits<double>::quiet_NaN();

    // Inputs as measured.
    std::string ilm_source;
    std::string bmo_source;  // "automatic" or "file"
    std::string eye;         // OD / OS / unknown
    bool oriented_from_positions = false;
    Eigen::Matrix2d grid_to_anatomical = Eigen::Matrix2d::Identity();  // ScanGeometry's map

    // Surfaces (grid mm). The ILM is oriented with its normals towards the vitreous.
    GridSurface rpe;  // BM heights, filled inside the BMO (flags in .filled)
    mesh::Vertices rpe_V;
    mesh::Faces rpe_F;
    mesh::Vertices ilm_V;
    mesh::Faces ilm_F;
    bool ilm_flipped = false;  // the input's faces were reversed to orient it
    // Per ILM face.
    Eigen::VectorXd face_height_mm;           // h = c_z - RPE(c_xy) (NaN outside the RPE grid)
    Eigen::VectorXd face_projected_area_mm2;  // signed (Eq. 8.9)
    std::vector<std::uint8_t> face_region;    // OnhRegion bits
    Eigen::VectorXd face_envt_strength;       // local lambda2 + lambda3 (empty if not asked)

    // BMO.
    std::vector<BmoPoint> bmo_measured;
    std::vector<int> bmo_points_per_bscan;  // automatic detection only
    double bmo_gap_area_mm2 = kMissing;     // automatic detection only (NaN for a file)
    int bmo_other_gaps = 0;
    BmoEllipse ellipse;
    double bmo_orientation_anatomical_deg = kMissing;  // major axis from nasal towards superior

    // Parameters. NaN (kMissing) where a parameter cannot be measured: CONHT when
    // the vertical line through the BMO centre misses the ILM, the BMO tensor and bending energy
    // when no ILM face lies inside the BMO, an MRW sector without a BMO point.
    bool has_cup = false;
    double cup_volume_mm3 = kMissing;  // Eq. 8.8, positive
    double conht_mm = kMissing;        // Eq. 8.10 (top ILM crossing above the BMO centre)
    double ilm_centre_height_mm = kMissing;
    double rpe_centre_height_mm = kMissing;
    double bmo_volume_mm3 = kMissing;        // Eq. 8.11-8.12
    double total_volume_mm3 = kMissing;      // Eq. 8.14-8.15
    double annular_volume_mm3 = kMissing;    // Eq. 8.16-8.17 (annulus minus cup)
    double bending_energy = kMissing;        // Eq. 8.18-8.20, one tensor for the BMO region
    std::array<double, 3> bmo_tensor_eigenvalues{kMissing, kMissing, kMissing};  // descending
    double bmo_region_area_mm2 = kMissing;   // 3-D area of the ILM faces inside the BMO (0: none)
    // MRW (Eq. 8.21-8.23), per resampled BMO point and summarised.
    std::vector<Eigen::Vector3d> mrw_points_mm;
    std::vector<double> mrw_mm;
    std::vector<double> bmo_anatomical_deg;
    double mrw_mean_mm = kMissing;
    double mrw_min_mm = kMissing;
    double mrw_max_mm = kMissing;
    std::array<double, 12> mrw_sector_mm{kMissing, kMissing, kMissing, kMissing, kMissing, kMissing,
                                         kMissing, kMissing, kMissing, kMissing, kMissing, kMissing};
    // ^ anatomical 0, 30, ..., 330 (NaN: no point)
    std::array<int, 12> mrw_sector_points{};
    double mrw_area_mm2 = kMissing;  // Eq. 8.23

    // Radial scans (ScanPattern 5; docs/algorithms/onh.md "Radial scans"). The grid frame is
    // then a square grid about the lines' crossing (radial_crossing_mm), x = SLO +x, y =
    // superior, on which the BM and the ILM are interpolated between the lines.
    bool radial = false;
    int radial_lines = 0;
    Eigen::Vector2d radial_crossing_mm = Eigen::Vector2d::Zero();
    double radial_scanned_radius_mm = kMissing;  // the circle every half-line covers
    double radial_grid_step_mm = kMissing;
    double radial_max_miss_mm = kMissing;  // largest distance of a line from the crossing
    double radial_max_step_deg = kMissing;  // largest angle between neighbouring lines
    std::vector<InplaneMrw> mrw_inplane;  // per measured BMO point
    double mrw_inplane_mean_mm = kMissing;
    double mrw_inplane_min_mm = kMissing;
    double mrw_inplane_max_mm = kMissing;
    std::array<double, 12> mrw_inplane_sector_mm{kMissing, kMissing, kMissing, kMissing,
                                                 kMissing, kMissing, kMissing, kMissing,
                                                 kMissing, kMissing, kMissing, kMissing};
    std::array<int, 12> mrw_inplane_sector_points{};
    std::vector<int> levelset_leak_bscans;  // IlmSurface::leak_bscans (radial level set)
    int levelset_leak_fallback_ascans = 0;
    int levelset_leak_cut_ascans = 0;       // IlmSurface::leak_cut_ascans

    // Axial registration of the B-scans (set by the caller that registered the scan).
    AxialRegistration axial_registration;
    LateralRegistration lateral_registration;

    // QC.
    int rpe_filled_vertices = 0;
    double rpe_fill_area_mm2 = 0.0;         // filled nodes * dx dy
    double rpe_fill_outside_bmo_mm2 = 0.0;  // of it, outside the BMO ellipse
    double rpe_fill_residual = 0.0;         // relative residual of the fill's solve
    int ilm_filled_vertices = 0;
    int ilm_filled_in_disc = 0;
    int faces_outside_rpe = 0;
    MeshQuality ilm_quality;
    std::vector<std::string> qc_flags;
    std::vector<std::string> notes;
    double seconds = 0.0;  // analysis time (without building the ILM)
};

// The en-face map of an analysis (the QC pictures draw it): over each cell of the RPE grid
// (r.rpe's (cols - 1) x (rows - 1) cells, cell (a, b) = [a dx, (a + 1) dx) x [b dy, (b + 1) dy)
// grid mm) the height above the RPE (face_height_mm) of the topmost ILM face whose centroid lies
// over it, the ILM seen from the vitreous; a centroid beyond the grid's edge counts in the
// edge's cell. NaN where no face with a height lies.
struct OnhEnfaceGrid {
    int cols = 0;                   // cells along grid x
    int rows = 0;                   // cells along grid y
    double dx_mm = 0.0;             // cell size (the RPE grid's step)
    double dy_mm = 0.0;
    std::vector<double> height_mm;  // rows * cols, row-major (b * cols + a)
    [[nodiscard]] double at(int a, int b) const {
        return height_mm[static_cast<std::size_t>(b) * static_cast<std::size_t>(cols) +
                         static_cast<std::size_t>(a)];
    }
};
[[nodiscard]] OnhEnfaceGrid onh_enface_heights(const OnhResult& r);

// Correspondence, regions and volumes of an ILM mesh over an RPE grid (Eq. 8.3-8.17): for
// every face the RPE height under its centroid (bilinear), h = c_z - RPE, the region bits, and
// the volumes as sums of h_i times the signed projected area A_i. A face whose centroid lies
// outside the RPE grid gets h = NaN, kRegionOutside, and counts in no volume.
struct OnhRegions {
    Eigen::VectorXd face_height_mm;
    std::vector<std::uint8_t> face_region;
    int faces_outside_rpe = 0;
    double cup_volume_mm3 = 0.0;      // -sum over h < 0 (every face below the RPE)
    double bmo_volume_mm3 = 0.0;      // inside the ellipse, h >= 0
    double total_volume_mm3 = 0.0;    // within disc_radius_mm of the ellipse centre, h >= 0
    double annular_volume_mm3 = 0.0;  // the same outside the ellipse
};
[[nodiscard]] OnhRegions measure_onh_regions(const mesh::Vertices& V,
                                             const mesh::Faces& F,
                                             const GridSurface& rpe,
                                             const BmoEllipse& ellipse,
                                             double disc_radius_mm);

// Runs the analysis of `scan` with the ILM surface `ilm`. `bmo_file_points`: measured BMO
// points from a file instead of the automatic detection. Throws AnalysisError when the scan is
// neither a volume nor a radial scan, has no BM line, or no BMO can be found. A radial scan
// (is_radial_scan) takes the radial path (onh_radial.cpp): its ILM must come from
// build_ilm_surface of the same scan, its file points from read_radial_bmo_csv.
[[nodiscard]] OnhResult analyse_onh(
    const io::Scan& scan,
    const IlmSurface& ilm,
    const OnhParams& params = {},
    const std::optional<std::vector<BmoPoint>>& bmo_file_points = std::nullopt);

// Throws AnalysisError with a one-line reason unless `scan` is a volume scan with a B-scan
// distance (the ONH analysis needs the 3-D grid).
void require_onh_volume(const io::Scan& scan);

// BMO points of a radial scan from a CSV file (read_bmo_csv's format): only the header
// `ascan,bscan,depth_px` (each point on its B-scan, A-scan index along the line, as a radial
// export gives them); the points come back in the radial analysis's grid mm with their B-scan.
// InputError (path, reason) for an `x_mm,y_mm,z_mm` file, a point off the scan or fewer than 6.
[[nodiscard]] std::vector<BmoPoint> read_radial_bmo_csv(const std::string& path,
                                                        const io::Scan& scan);

// A volume (require_onh_volume) or a radial scan whose lines can be placed (radial_geometry:
// AnalysisError for lines that do not cross, a zero-length or non-finite line) with at least
// 3 lines and 3 A-scans per line and positive scales.
void require_onh_scan(const io::Scan& scan);

}  // namespace octshape::retina
