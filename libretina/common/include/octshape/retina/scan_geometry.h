#pragma once
// Where every sample of a scan is, in mm, and which way is nasal and superior
// (docs/coordinates.md).
//
// Grid frame (volume and line scans): x along a B-scan (A-scan index * ScaleX), y across B-scans
// (B-scan index * Distance), height z = -depth (up = towards the vitreous).
// Anatomical frame: (nasal, superior) in mm; angles 0 deg = nasal, 90 deg = superior, for both
// eyes. The grid is placed on the SLO by the B-scans' Start/End positions (SLO: x right, y down);
// on the SLO, superior is -y and nasal is +x for OD, -x for OS.

#include <optional>
#include <string>

#include <Eigen/Core>

#include "octshape/io/scan.h"

namespace octshape::retina {

// How evenly the B-scans are spaced, measured from their Start positions on the SLO.
struct SpacingReport {
    int num_gaps = 0;                 // B-scans - 1
    double header_distance_mm = 0.0;  // Distance from the file header
    double mean_mm = 0.0;             // measured from Start positions (0 if unknown)
    double min_mm = 0.0;
    double max_mm = 0.0;
    double max_relative_deviation = 0.0;  // max |gap - mean| / mean
    bool positions_known = false;         // Start positions differ between B-scans
    bool uniform = true;                  // deviation within kUniformTolerance
    bool matches_header = true;           // mean within kUniformTolerance of the header value
    // 2 % of a 125 um gap is 2.5 um, well above the 1e-4 mm rounding of stored positions but far
    // below a missing or doubled B-scan.
    static constexpr double kUniformTolerance = 0.02;
};

class ScanGeometry {
public:
    explicit ScanGeometry(const io::Scan& scan);

    [[nodiscard]] double x_mm(double ascan) const { return ascan * scale_x_mm_; }
    [[nodiscard]] double y_mm(double bscan) const { return bscan * distance_mm_; }
    // Height from a depth in pixels: z = -depth * ScaleZ.
    [[nodiscard]] double z_mm(double depth_px) const { return -depth_px * scale_z_mm_; }

    [[nodiscard]] double scale_x_mm() const { return scale_x_mm_; }
    [[nodiscard]] double scale_z_mm() const { return scale_z_mm_; }
    // The y step used for the grid: the header Distance (0 for a single line).
    [[nodiscard]] double distance_mm() const { return distance_mm_; }

    // Grid mm -> anatomical (nasal, superior) mm, as a linear map (columns: images of +x, +y).
    [[nodiscard]] const Eigen::Matrix2d& grid_to_anatomical() const { return to_anat_; }
    // Direction (dx, dy) in grid mm -> anatomical angle in degrees, in [0, 360).
    [[nodiscard]] double anatomical_angle_deg(double dx, double dy) const;
    // Grid (x, y) mm -> SLO mm, and back.
    [[nodiscard]] Eigen::Vector2d grid_to_slo(const Eigen::Vector2d& grid_mm) const;
    [[nodiscard]] Eigen::Vector2d slo_to_grid(const Eigen::Vector2d& slo_mm) const;

    // True when grid +x points nasally / grid +y points superiorly (after rounding to the
    // nearest axis; real volumes are axis-aligned on the SLO).
    [[nodiscard]] bool x_is_nasal() const { return to_anat_(0, 0) > 0.0; }
    [[nodiscard]] bool y_is_superior() const { return to_anat_(1, 1) > 0.0; }

    [[nodiscard]] const SpacingReport& spacing() const { return spacing_; }
    // True when the B-scan positions on the SLO were usable to orient the grid (a volume's
    // B-scans must also lie at different positions); otherwise the documented default (first
    // B-scan inferior, A-scans left to right) was assumed for what they do not tell.
    [[nodiscard]] bool oriented_from_positions() const { return from_positions_; }

private:
    double scale_x_mm_ = 0.0;
    double scale_z_mm_ = 0.0;
    double distance_mm_ = 0.0;
    Eigen::Vector2d origin_slo_ = Eigen::Vector2d::Zero();  // SLO mm of grid (0, 0)
    Eigen::Matrix2d to_slo_ = Eigen::Matrix2d::Identity();  // grid mm -> SLO mm offsets
    Eigen::Matrix2d to_anat_ = Eigen::Matrix2d::Identity();
    SpacingReport spacing_;
    bool from_positions_ = false;
};

}  // namespace octshape::retina
