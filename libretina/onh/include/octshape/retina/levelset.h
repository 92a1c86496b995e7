#pragma once
// The true 3-D ILM of an optic-nerve-head volume (thesis §8.1.1, docs/algorithms/levelset.md):
// a Chan–Vese type
// region-based level set on the B-scan intensities, evolved on a narrow band inside a depth
// window around the device ILM, then marching cubes (VTK vtkFlyingEdges3D), the largest
// connected component, clipping to the valid scan area and RoFi smoothing (§5.1).
// Method, defaults and measurements: docs/algorithms/levelset.md.
//
// Frames (docs/coordinates.md): voxel (b, a, d) = (B-scan, A-scan, pixel row); the mesh comes
// out in the grid mm frame x = a * ScaleX, y = b * Distance, z = -d * ScaleZ, with face normals
// pointing into the vitreous (up). φ > 0 in the vitreous, φ < 0 in tissue, in mm.

#include <cstdint>
#include <string>
#include <vector>

#include "octshape/io/scan.h"
#include "octshape/mesh/mesh.h"
#include "octshape/mesh/rofi.h"

namespace octshape::retina {

// RoFi defaults for the level-set surface (docs/algorithms/levelset.md, "RoFi defaults"):
// σ_s = 1.0 (a wide Tukey window: the marching-cubes steps, whose normals differ by tens of
// degrees on this anisotropic grid, are smoothed rather than kept as features), λ_I = 0 (the
// isotropic term of Eq. 5.9 moved the cupped surface 0.1–0.3 µm towards the vitreous on the
// phantoms; without it the mean offset is unchanged to 0.01 µm), p = 10 iterations.
[[nodiscard]] mesh::RofiParams levelset_default_rofi();

struct LevelSetParams {
    // --- Depth window (restricts all work to a band of rows around the device ILM) ---
    // Every column's window spans the device ILM depths found within `lateral_radius_mm`
    // (a box in x and y), widened by `margin_mm` above and below. The lateral reach is what
    // lets the surface grow under a rim lip: the cup wall a few tenths of a mm inward sets the
    // window's bottom under the lip. > 0.
    double lateral_radius_mm = 0.25;
    double margin_mm = 0.06;  // > 0; ~15 px at ScaleZ 3.87 µm

    // --- Pre-processing ---
    // Display transform v^0.25, then per B-scan a binomial blur [1 4 6 4 1]/16
    // applied `despeckle_passes` times in x and in depth (σ = 1 px per pass). ≥ 0.
    int despeckle_passes = 1;
    // The blur in x is 1 px but at most this wide (σ, mm): 1 px of the 384-A-scan Spectralis
    // ONH volume and radial line (11.33 / 11.36 µm), where the defaults were measured. Coarser
    // A-scans get σ = this / ScaleX px ([q, 1−2q, q] twice, q = σ²/4): a blur wider than that
    // moves the steep cup wall towards the vitreous (docs/algorithms/levelset.md, "Coarse
    // A-scan spacing"). ≥ 0.
    double despeckle_max_sigma_x_mm = 0.0114;

    // --- Energy (Chan–Vese, Eq. LS-1 in docs/algorithms/levelset.md) ---
    // Length weight μ (mm): the curvature speed μκ is compared with the normalised region
    // force (|F| ≤ 1). The default is the largest μ whose explicit diffusion limit does not
    // lower the time step below the advection limit at the usual Spectralis spacing (see the
    // doc): μ = Σ(1/h) / (2 Σ 1/h²) ≈ 2.5 µm. ≥ 0.
    double mu_mm = 0.0025;
    double lambda_vitreous = 1.0;  // λ1: weight of (I − c_vitreous)², > 0
    double lambda_tissue = 1.0;    // λ2: weight of (I − c_tissue)², > 0
    // Where the region means c_vitreous, c_tissue (Eq. LS-2) are taken: over the narrow band —
    // the voxels within `band_layers` steps of the interface, kept per tile and re-taken
    // wherever the band is rebuilt (default) — or over the whole depth windows (classic
    // Chan–Vese). The zero level settles
    // where the despeckled image crosses (c_v + c_t) / 2. Window means put that level below the
    // midpoint of the edge (the tissue mean includes the dimmer layers under the bright
    // surface), ~0.2 px further into the vitreous than band means, which are symmetric about
    // the edge (docs/algorithms/levelset.md, "Where the zero level settles").
    enum class RegionMeans { kBand, kWindow };
    RegionMeans region_means = RegionMeans::kBand;
    // Under a rim lip the tissue is dimmer than at the open surfaces that set the region means,
    // so the one decision level (c_v + c_t) / 2 lies inside that tissue and the cavity comes out
    // too large. true: once the main run has stopped, the interface more than leak_depth_mm
    // below its column's first tissue row, in columns that hold vitreous that deep (a cavity
    // under a lip) or lie within band_layers A-scans and one B-scan of one (the cavity's
    // ceiling, hidden wall and floor), is evolved again (at most max_iterations / 4 more
    // iterations) about the midpoint of the band means on either side of it in a box of
    // ±band_layers voxels (±1 B-scan), where that box holds an edge
    // (docs/algorithms/levelset.md "Refinement under lips"). A scan without such a cavity is
    // unchanged.
    bool hidden_local_level = true;
    // true: c_vitreous is the mean of the open vitreous only — vitreous voxels more than
    // leak_depth_mm below the device ILM (a cavity under a lip, or a front that ran into
    // shadowed tissue) do not count towards it, so a leak cannot raise the decision level and
    // pull more shadowed tissue in after it (docs/algorithms/levelset.md "Vitreous mean").
    // false: every vitreous band voxel counts (before issue 32).
    bool open_vitreous_mean = true;

    // --- Narrow band evolution ---
    // W: band = voxels ≤ W 6-neighbour steps from the interface; layers < W are updated, layer
    // W only feeds the differences. In [2, 100].
    int band_layers = 2;
    // Iterations between band rebuild + re-initialisation; in [1, W]. The front moves at most
    // cfl of a voxel along its normal per step (LS-7); where it would leave the updated layers
    // 0..W−1 before the next rebuild it waits at their edge, and the rebuild moves the band on.
    int reinit_interval = 2;
    double cfl = 0.9;           // dt = cfl / (Σ 1/h + 2 μ Σ 1/h²); in (0, 1]
    int max_iterations = 400;   // cap; the result says whether it converged; ≥ 1
    // The volume's columns are grouped in tiles of about tile_mm × tile_mm (rounded to whole
    // A-scans and B-scans; 9 × 3 columns at the full 145 × 384 size). A tile freezes when
    // neither it nor its 8 neighbours had a sign change in the last `patience` iterations; the
    // run stops (converged) when every tile is frozen: "the band stops changing sign". The
    // tile must be wide enough that a front moving sideways (into an overhang) flips some
    // voxel of it every few iterations (measured in docs/algorithms/levelset.md). Both > 0.
    double tile_mm = 0.1;
    int patience = 3;

    // --- Mesh ---
    int slab_bscans = 16;  // marching cubes runs on slabs of this many B-scans (memory); ≥ 2
    bool smooth = true;    // RoFi on the clipped component
    mesh::RofiParams rofi = levelset_default_rofi();

    // --- Leaks (every B-scan: a radial scan's 2-D level sets, a volume's columns) ---
    // A front that entered the tissue (a dark cleft, a vessel's shadow) leaves its top crossing
    // more than `leak_depth_mm` below the device ILM's running median over >= 3 A-scans (an
    // overhang's cavity lies under the lip both see first); those A-scans fall back to the
    // device ILM, flagged and counted (docs/algorithms/levelset.md "Leaks"). Vitreous more than
    // `leak_depth_mm` below the device ILM (only a cavity under a lip can be there) that is
    // brighter than a quarter of the way from the vitreous to the tissue, in a group holding a
    // 3 x 3 block, is tissue in a vessel's shadow: cut from the vitreous, flagged and counted.
    // false: keep every leak (for measuring it). leak_depth_mm > 0.
    bool leak_fallback = true;
    double leak_depth_mm = 0.016;

    // Throws UsageError naming the bad field.
    void validate() const;
};

struct LevelSetResult {
    // The ILM after RoFi (V) and before (V_raw): same faces F, normals into the vitreous.
    mesh::Vertices V;
    mesh::Vertices V_raw;
    mesh::Faces F;

    // Evolution diagnostics.
    int iterations = 0;
    bool converged = false;              // every tile frozen before max_iterations
    std::int64_t window_voxels = 0;      // voxels inside the depth windows
    std::int64_t band_voxels = 0;        // band size at the last rebuild (all tiles active)
    std::int64_t last_updated_voxels = 0;  // voxels updated in the last iteration
    std::int64_t last_sign_changes = 0;    // of those, how many changed sign
    double last_sign_change_fraction = 0.0;  // last_sign_changes / last_updated_voxels (0 if 0)
    std::int64_t voxel_updates = 0;      // total over all iterations
    double time_step = 0.0;              // global dt (mm per unit speed); voxels use local steps
    double c_vitreous = 0.0;             // final region means (display units; see region_means)
    double c_tissue = 0.0;
    bool front_reached_window_edge = false;  // interface touched a window's top or bottom row
    // The refinement under lips (LevelSetParams::hidden_local_level): its iterations (included
    // in `iterations`; 0 when nothing lay under a lip), the band voxels that took a local level
    // (summed over its rebuilds) and their mean level (display units).
    int refine_iterations = 0;
    std::int64_t local_level_voxels = 0;
    double mean_local_level = 0.0;
    int missing_ilm_columns = 0;         // device ILM missing: filled from neighbours, clipped
    int invalid_pixel_columns = 0;       // columns without pixel data: clipped

    // Mesh diagnostics.
    std::int64_t raw_vertices = 0;  // marching cubes output (merged over slabs)
    std::int64_t raw_faces = 0;
    int components = 0;             // connected components after the valid-area clip
    std::int64_t clipped_faces = 0;   // faces removed by the valid-area clip
    int rofi_iterations = 0;

    // Timing per stage: wall clock and CPU time of the process (s).
    struct StageTime {
        double wall_s = 0.0;
        double cpu_s = 0.0;
    };
    StageTime prepare;         // windows, display transform, despeckle, φ0
    StageTime evolve;          // narrow-band evolution incl. re-initialisation
    StageTime marching_cubes;  // vtkFlyingEdges3D on the slabs + vertex merging
    StageTime component_clip;  // valid-area clip, largest component, orientation
    StageTime rofi;            // RoFi smoothing

    std::vector<std::string> warnings;
};

// Computes the ILM surface of a volume scan with pixels and a device ILM (line 0).
// Throws UsageError for bad params, AnalysisError when the scan is not a volume with pixels
// and at least one valid ILM value, or when no surface is found.
[[nodiscard]] LevelSetResult levelset_ilm(const io::Scan& scan, const LevelSetParams& params = {});

// The same result, but frees every B-scan's pixels (and clears scan.pixels_loaded) as soon as
// the intensities have been copied onto the depth windows (the stages before "evolve" in
// libretina/onh/src/levelset_stages.h), so that the volume and the mesh stages
// (RoFi's neighbourhoods) never occupy memory together: the per-eye pipeline's peak then stays
// well below what holding the pixels to the end costs (docs/algorithms/levelset.md, "Memory").
[[nodiscard]] LevelSetResult levelset_ilm_releasing_pixels(io::Scan& scan,
                                                           const LevelSetParams& params = {});

}  // namespace octshape::retina
