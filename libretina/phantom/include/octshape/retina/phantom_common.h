#pragma once
// Machinery shared by the phantom generators (macula, ONH): a portable deterministic random
// generator, the layout of a synthetic Spectralis volume on the SLO with the frame derived from
// that layout, layered retinal reflectance, speckle rendering of B-scans and a small SLO image.
//
// The frame here is derived only from how `make_scan_frame` places the B-scans; it does not use
// ScanGeometry, so a bug in the analysis' geometry shows up as a test failure instead of being
// shared by the truth and the analysis (docs/phantoms.md).
//
// Placement (SLO mm: origin top-left, x right, y down): the grid is centred on the SLO image;
// A-scans run left to right (grid +x = SLO +x); the FIRST B-scan is the most inferior (largest
// SLO y), so grid +y = SLO -y = superior. Nasal is SLO +x for OD and SLO -x for OS. Vertical
// B-scans (VolumeLayout::vertical): A-scans top to bottom (grid +x = SLO +y, inferior), the
// first B-scan leftmost (grid +y = SLO +x).

#include <array>
#include <cstdint>
#include <functional>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "octshape/io/scan.h"

namespace octshape::retina::phantom {

// xoshiro256** seeded through splitmix64, with its own normal and gamma samplers, so a phantom
// is bit-for-bit the same for a seed on every platform (std:: distributions are not).
class Rng {
public:
    // `stream` selects an independent sequence for the same seed (e.g. one per B-scan).
    explicit Rng(std::uint64_t seed, std::uint64_t stream = 0);
    std::uint64_t next();
    double uniform();  // in [0, 1), 53 random bits
    double normal();   // N(0, 1), Marsaglia polar method
    // Gamma(shape, scale 1), Marsaglia-Tsang; shape > 0.
    double gamma(double shape);

private:
    std::array<std::uint64_t, 4> s_{};
    double spare_ = 0.0;
    bool has_spare_ = false;
};

// Sizes and placement of a synthetic scan. Defaults: a Spectralis 25 x 30 deg macula volume.
struct VolumeLayout {
    // kVolume, kLine (one B-scan) or kRadial (the frame of the field the lines cross: the
    // generator places the lines itself, phantom_macula.h)
    io::ScanPattern pattern = io::ScanPattern::kVolume;
    io::Laterality laterality = io::Laterality::kOD;
    // Volumes and lines: B-scans run vertically (A-scans from superior to inferior, grid +x =
    // SLO +y; the first B-scan leftmost, grid +y = SLO +x) instead of the horizontal placement
    // above. The eye (anatomical frame) is the same; only the scan grid is turned.
    bool vertical = false;
    int size_x = 768;               // A-scans per B-scan
    int size_z = 496;               // pixels per A-scan
    int num_bscans = 61;            // 1 for a line scan
    double scale_x_mm = 0.01169;    // mm per A-scan (768 -> 8.98 mm)
    double scale_z_mm = 0.0038717;  // mm per pixel in depth
    double distance_mm = 0.125;     // mm between B-scans (ignored for one B-scan: written as 0)
    int num_seg = 17;               // segmentation lines per B-scan header
    int slo_size_px = 256;          // square SLO image
    double slo_margin = 1.1;        // SLO side = margin * the larger grid extent
    std::uint32_t slo_field_deg = 30;
    // Throws UsageError naming the bad field.
    void validate() const;
};

// Where the grid of a layout lies, derived from the placement described above.
struct GridFrame {
    Eigen::Vector2d origin_slo_mm = Eigen::Vector2d::Zero();  // SLO position of grid (0, 0)
    Eigen::Matrix2d grid_to_slo = Eigen::Matrix2d::Identity();  // columns: SLO dirs of +x, +y
    // Columns: anatomical (nasal, superior) components of grid +x and +y.
    Eigen::Matrix2d grid_to_anatomical = Eigen::Matrix2d::Identity();
    double width_mm = 0.0;   // (size_x - 1) * scale_x
    double height_mm = 0.0;  // (num_bscans - 1) * distance
    double slo_scale_mm = 0.0;  // mm per SLO pixel (both axes)

    [[nodiscard]] Eigen::Vector2d centre_mm() const { return {width_mm / 2, height_mm / 2}; }
    [[nodiscard]] Eigen::Vector2d to_slo(const Eigen::Vector2d& grid_mm) const {
        return origin_slo_mm + grid_to_slo * grid_mm;
    }
    // Anatomical angle in degrees, [0, 360), of a grid direction (dx, dy).
    [[nodiscard]] double anatomical_angle_deg(double dx, double dy) const;
    // Unit grid direction of an anatomical angle (inverse of anatomical_angle_deg).
    [[nodiscard]] Eigen::Vector2d grid_direction(double anatomical_deg) const;
};

[[nodiscard]] GridFrame grid_frame(const VolumeLayout& layout);

// A scan with every header field set (HSF-OCT-103), B-scan Start/End on the SLO per the
// placement above, `num_seg` all-missing segmentation lines per B-scan, no pixels, no SLO
// image, obviously fake identifiers and fixed exam/visit dates (2024-03-14).
[[nodiscard]] io::Scan make_scan_frame(const VolumeLayout& layout);

// Layered retinal reflectance along an A-scan. Linear reflectance values (the display transform
// is v^0.25, so e.g. 0.32 displays as 0.75). Inner layers share the thickness above
// `outer_mm` in fixed proportions and vanish where the retina is thinner (the foveal pit).
struct RetinaLayers {
    double vitreous = 2e-4;  // display 0.12
    double rnfl = 0.32;      // display 0.75
    double gcl = 0.06;
    double ipl = 0.15;
    double inl = 0.02;
    double opl = 0.13;
    double onl = 0.008;      // display 0.30
    double inner_segments = 0.015;
    double ez = 0.32;        // ellipsoid zone
    double outer_segments = 0.025;
    double rpe = 0.5;        // RPE/BM complex, display 0.84
    double choroid = 0.05;   // just below BM (display 0.47), decaying with depth
    double choroid_decay_mm = 0.08;  // dark (display < 0.2) 0.3 mm below BM
    double outer_mm = 0.20;  // OPL/ONL boundary to BM where the retina is thick enough
    double photoreceptor_mm = 0.085;  // ELM to BM
    // Fractions of the inner retina (ILM to OPL/ONL): RNFL, GCL, IPL, INL, OPL (sum 1).
    std::array<double, 5> inner_fractions{0.2, 0.3, 0.2, 0.18, 0.12};
};

// Boundary depths in pixels of one A-scan from its ILM and BM depths (ilm < bm).
struct ColumnBoundaries {
    // ILM, RNFL/GCL, GCL/IPL, IPL/INL, INL/OPL, OPL/ONL, ELM, EZ top, EZ bottom, RPE top, BM.
    std::array<double, 11> depth_px{};
};
[[nodiscard]] ColumnBoundaries retina_boundaries(double ilm_px,
                                                 double bm_px,
                                                 double scale_z_mm,
                                                 const RetinaLayers& layers = {});

// Noise-free linear reflectance of an A-scan: each pixel p (covering depths [p - 0.5, p + 0.5))
// is the average of the piecewise-constant layer profile over the pixel (so a boundary at a
// sub-pixel depth shows as a partial pixel), times exp(-(depth below BM)/decay) in the choroid.
void layered_retina_column(const ColumnBoundaries& b,
                           double scale_z_mm,
                           const RetinaLayers& layers,
                           std::span<float> column);

// Per-A-scan reflectance: fills `column` (size_z values, linear, >= 0) for A-scan `ascan`.
using ColumnFunction = std::function<void(int ascan, std::span<float> column)>;

struct SpeckleParams {
    // Multiplicative speckle Gamma(looks, 1/looks) (mean 1; looks = 1 is fully developed
    // exponential speckle, Spectralis ART averaging of 9-15 frames reduces it).
    double looks = 3.0;
    // Speckle grain: the half-widths (pixels) at which the intensity's autocorrelation falls to
    // 0.5 along the A-scan and across A-scans. Both 0 (the default): one independent value per
    // pixel. Otherwise each of round(looks) looks is |F|^2 of a complex Gaussian field smoothed
    // by a Gaussian of SD half_width / sqrt(2 ln 2) (the intensity correlation is the field's
    // squared), so the marginal stays Gamma(looks, 1/looks); looks must then be a whole number.
    double axial_half_width_px = 0.0;
    double lateral_half_width_px = 0.0;
};

// Renders `bscan.pixels` (size_z x size_x, row-major): reflectance times speckle, clamped to
// [0, 1]. Deterministic for (seed, stream).
void render_bscan(io::BScan& bscan,
                  int size_x,
                  int size_z,
                  const ColumnFunction& reflectance,
                  const SpeckleParams& speckle,
                  std::uint64_t seed,
                  std::uint64_t stream);

// Renders `scan.slo` (u8, size_y_slo x size_x_slo) from a brightness in [0, 1] at SLO mm
// positions, with mild multiplicative noise. Deterministic for the seed.
void render_slo(io::Scan& scan,
                const std::function<double(double x_slo_mm, double y_slo_mm)>& brightness,
                std::uint64_t seed);

// What the acquisition adds to a phantom (docs/phantoms.md, "Acquisition artefacts"): the eye,
// and so the truth, stay the same; only the B-scans and the device lines change.
struct AcquisitionArtefacts {
    // Axial eye motion: one depth shift per B-scan, a random walk with occasional jumps,
    // rescaled to zero mean and exactly this standard deviation (um); 0 = still.
    double motion_sd_um = 0.0;
    // Lateral jitter of volume B-scans along their A-scans (SD, um; radial scans: ignored).
    double lateral_jitter_um = 0.0;
    bool vessel_shadows = false;  // vessels: bright lumen under the ILM, a shadow below it
    bool cleft = false;           // a dark cleft from the ILM into the tissue under one vessel
    bool segmentation_faults = false;  // device ILM spike and a BM gap, both off the disc/fovea

    [[nodiscard]] bool any() const {
        return motion_sd_um > 0.0 || lateral_jitter_um > 0.0 || vessel_shadows || cleft ||
               segmentation_faults;
    }
    // Throws UsageError naming the bad field.
    void validate() const;
};

// The per-B-scan shifts of an acquisition (pixels: depth, and A-scans along the B-scan), a pure
// function of (artefacts, seed, sizes), so the truth file can state them without the pixels.
struct AcquisitionShifts {
    std::vector<double> axial_px;    // + = the B-scan's content lies deeper
    std::vector<double> lateral_px;  // + = towards higher A-scan indices (volumes only)
};
[[nodiscard]] AcquisitionShifts acquisition_shifts(const AcquisitionArtefacts& artefacts,
                                                   int num_bscans,
                                                   double scale_z_mm,
                                                   double scale_x_mm,
                                                   bool radial,
                                                   std::uint64_t seed);

// Where the A-scans of a moving acquisition sample the eye: `points` (the still grid positions,
// B-scan-major, `size_x` per B-scan) with B-scan b's moved by -lateral_px[b] of its own A-scan
// steps (points[b][1] - points[b][0]), so that its content lies lateral_px[b] A-scans towards
// higher indices. The eye moves and the scanner samples it: a generator renders each A-scan
// from the eye at these positions (and its depths axial_px[b] deeper), so the pixels are drawn,
// speckle included, after the geometry moved; no pixel or line is interpolated. `points`
// itself when no B-scan moves laterally.
[[nodiscard]] std::vector<Eigen::Vector2d> acquired_points(
    const std::vector<Eigen::Vector2d>& points, int size_x, const AcquisitionShifts& shifts);

// A vessel path on the grid (mm) and its lumen width (mm).
struct VesselPath {
    std::vector<Eigen::Vector2d> line;
    double width_mm = 0.1;
};

// Applies `artefacts` to a scan rendered from the moved eye (acquired_points, depths shifted by
// the axial shifts), in acquisition order: vessel lumen and shadow (drawn under the device ILM
// line `ilm_line` at every A-scan whose grid position, `points` B-scan major and moved as
// rendered, lies within half a width of a vessel), the cleft, then the device-line faults (at
// A-scans whose grid position is farther than `spare_radius_mm` from `spare_centre_mm`: off the
// disc or the fovea). Nothing is shifted here: the motion is already in the pixels and lines.
// Throws UsageError when a B-scan's moved retina (its ILM and BM lines) leaves the image (a
// larger depth is needed).
void apply_acquisition_artefacts(io::Scan& scan,
                                 const std::vector<Eigen::Vector2d>& points,
                                 const std::vector<VesselPath>& vessels,
                                 const AcquisitionArtefacts& artefacts,
                                 int ilm_line,
                                 int bm_line,
                                 const Eigen::Vector2d& spare_centre_mm,
                                 double spare_radius_mm);

}  // namespace octshape::retina::phantom
