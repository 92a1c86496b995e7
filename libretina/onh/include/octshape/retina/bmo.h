#pragma once
// Bruch's membrane opening (thesis §8.1.3, docs/algorithms/onh.md): measured BMO
// points (detected from the gap of the device BM line, or read from a user file), the
// Fitzgibbon direct least-squares ellipse through them (cv::fitEllipseDirect) and its uniform
// resampling.

#include <Eigen/Core>
#include <array>
#include <string>
#include <vector>

#include "octshape/io/scan.h"
#include "octshape/retina/onh_surfaces.h"

namespace octshape::retina {

// A measured BMO point in grid mm (z = height).
struct BmoPoint {
    Eigen::Vector3d mm = Eigen::Vector3d::Zero();
    int bscan = -1;  // B-scan it was found in (-1: from a file)
    int side = 0;    // -1 = start (lower A-scan index) of the gap, +1 = its end, 0 = file
};

struct BmoDetectionParams {
    // The disc is the largest 4-connected region of missing BM; smaller ones (vessel shadows,
    // dropouts) are ignored. A region below this area is not a disc.
    double min_gap_area_mm2 = 0.2;

    void validate() const;  // throws UsageError naming the field
};

struct BmoDetection {
    std::vector<BmoPoint> points;
    std::vector<int> points_per_bscan;  // #B-scans: 0, 1 or 2
    double gap_area_mm2 = 0.0;          // area of the chosen missing-BM region (nodes * dx dy)
    int other_gaps = 0;                 // other (ignored) missing-BM regions
    int other_gap_nodes = 0;            // their nodes
};

// Automatic detection on the raw (unfilled) BM height field: in each B-scan crossing the disc's
// missing-BM region, its first and last missing A-scans a0, a1 give the end points at
// x = (a0 - 1/2) dx and x = (a1 + 1/2) dx (half-way between the last present and the first
// missing A-scan), y = b dy, z = the BM height extrapolated linearly by half an A-scan from the
// two present values outside. An end whose outer neighbour is missing or off the grid gives no
// point. Throws AnalysisError when no region qualifies or fewer than 6 points are found.
[[nodiscard]] BmoDetection detect_bmo_points(const GridSurface& bm_raw,
                                             const BmoDetectionParams& params = {});

// Reads BMO points from a CSV file (docs/algorithms/onh.md "BMO file"): lines starting with '#'
// and blank lines are skipped; the first other line is the header, either `x_mm,y_mm,z_mm`
// (grid mm, z = height) or `ascan,bscan,depth_px` (pixel indices, converted with the scan's
// ScaleX, Distance and ScaleZ: x = ascan ScaleX, y = bscan Distance, z = -depth_px ScaleZ);
// then one point per line. Throws InputError (path, line) on a bad file, fewer than 6 points
// or a point outside the scan grid.
// `pixel_header` (optional) receives whether the header was `ascan,bscan,depth_px`.
[[nodiscard]] std::vector<BmoPoint> read_bmo_csv(const std::string& path,
                                                 const io::ScanMeta& meta,
                                                 int num_bscans,
                                                 bool* pixel_header = nullptr);

struct BmoEllipse {
    Eigen::Vector2d centre_mm = Eigen::Vector2d::Zero();  // grid mm
    double semi_major_mm = 0.0;                           // a >= b
    double semi_minor_mm = 0.0;
    double orientation_deg = 0.0;  // major axis from grid +x towards +y, [0, 180)
    double area_mm2 = 0.0;         // pi a b (Eq. 8.24)
    double rms_residual_mm = 0.0;  // RMS over the measured points of their distance to the
                                   // ellipse along the ray from the centre
    // Resampled points: uniform in the parameter angle t (t = 0 on the major axis, counter-
    // clockwise from +x towards +y), (x, y) on the ellipse, z linear in polar angle about the
    // centre between the two measured points that bracket it.
    std::vector<Eigen::Vector3d> points_mm;
    std::vector<double> parameter_rad;

    // True when (x, y) is strictly inside the ellipse.
    [[nodiscard]] bool inside(double x, double y) const;
    // Normalised radius |diag(1/a, 1/b) Rot(-theta) ((x, y) - c)| (1 on the ellipse).
    [[nodiscard]] double normalised_radius(double x, double y) const;
};

// Fits the ellipse (cv::fitEllipseDirect, Fitzgibbon et al.) to the (x, y) of the points and
// resamples it with `num_points` points. Throws AnalysisError for fewer than 6 points or a
// degenerate fit.
[[nodiscard]] BmoEllipse fit_bmo_ellipse(const std::vector<BmoPoint>& points, int num_points);

}  // namespace octshape::retina
