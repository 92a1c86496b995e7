#pragma once
// Where the lines of a radial scan (ScanPattern 5: B-scans rotated about one point, the star
// pattern) lie, measured from each B-scan's Start/End positions on the SLO; shared by the
// macula and ONH analyses (docs/coordinates.md "Radial scans").
//
// Nothing is taken from the header but ScaleX: each line is the segment Start -> End, the
// crossing is the point nearest to every line in least squares, and each line's miss is its
// perpendicular distance from that point. Line angles are anatomical (0 deg nasal, 90 deg
// superior, both eyes).
//
// Radial frame (mm): origin at the crossing, x = SLO +x, y = SLO -y (up on the fundus image,
// superior). It is the grid frame a horizontal volume would have there (docs/coordinates.md),
// so nasal is +x for OD and -x for OS, and disk normals mean the same in both.

#include <string>
#include <vector>

#include <Eigen/Core>

#include "octshape/io/scan.h"

namespace octshape::retina {

struct RadialLine {
    int bscan = 0;
    Eigen::Vector2d start_slo_mm = Eigen::Vector2d::Zero();
    Eigen::Vector2d end_slo_mm = Eigen::Vector2d::Zero();
    double length_mm = 0.0;       // |End - Start|
    double angle_deg = 0.0;       // anatomical direction of Start -> End, [0, 360)
    double line_angle_deg = 0.0;  // the line's orientation, angle_deg mod 180, [0, 180)
    double miss_mm = 0.0;         // distance of the crossing from the line
    // The crossing's foot on the line, as mm from Start along Start -> End.
    double crossing_along_mm = 0.0;
};

struct RadialGeometry {
    std::vector<RadialLine> lines;  // in B-scan order
    Eigen::Vector2d crossing_slo_mm = Eigen::Vector2d::Zero();
    double max_miss_mm = 0.0;
    double rms_miss_mm = 0.0;
    double mean_length_mm = 0.0;
    double header_length_mm = 0.0;  // (SizeX - 1) * ScaleX
    // Angular steps between neighbouring line orientations (sorted, cyclic over 180 deg).
    double nominal_step_deg = 0.0;  // 180 / number of lines
    double min_step_deg = 0.0;
    double max_step_deg = 0.0;
    bool regular = true;  // every step within kStepTolerance of the nominal one
    bool lines_cross = true;  // max_miss_mm <= kMissTolerance A-scan spacings
    std::vector<std::string> irregular_steps;  // "between B-scans 3 and 4: 21.0 deg", ...
    // HSF-OCT-104 B-scan BMO fields: how many B-scans carry them. Their meaning is unverified
    // (no public 104 file), so no analysis uses them; the summaries say so.
    int num_bmo_fields = 0;
    Eigen::Matrix2d radial_to_anatomical = Eigen::Matrix2d::Identity();

    // 2 % of the nominal step (0.3 deg at 12 lines, 0.15 deg at 24): the rule of the parallel
    // B-scan spacing check (docs/coordinates.md); stored positions rounded to 1e-4 mm move a
    // 6 mm line's angle by < 0.002 deg, while a missing line doubles a step.
    static constexpr double kStepTolerance = 0.02;
    // A line that misses the crossing by more than one A-scan spacing does not pass through the
    // A-scan nearest to it.
    static constexpr double kMissTolerance = 1.0;

    [[nodiscard]] Eigen::Vector2d slo_to_radial(const Eigen::Vector2d& slo_mm) const {
        return {slo_mm.x() - crossing_slo_mm.x(), crossing_slo_mm.y() - slo_mm.y()};
    }
    // Radial-frame position (mm) of A-scan `ascan` (0 .. SizeX - 1) of line `line`, placed
    // uniformly between Start and End.
    [[nodiscard]] Eigen::Vector2d ascan_mm(int line, double ascan, int size_x) const;
    // Unit direction Start -> End of a line in the radial frame.
    [[nodiscard]] Eigen::Vector2d direction(int line) const;
    // Anatomical angle (deg, [0, 360)) of a radial-frame direction.
    [[nodiscard]] double anatomical_angle_deg(const Eigen::Vector2d& d) const;
};

// True for ScanPattern 5, and for a scan of unknown pattern whose B-scans are not parallel
// (their Start -> End directions differ by more than 1 deg).
[[nodiscard]] bool is_radial_scan(const io::Scan& scan);

// The geometry of a radial scan. AnalysisError when there are fewer than 2 B-scans, a line of
// zero length, or no two lines that cross (all parallel).
[[nodiscard]] RadialGeometry radial_geometry(const io::Scan& scan);

// The QC of a radial scan's lines, the same for every analysis of one: stable flags
// ("radial angular steps irregular", "radial lines miss their crossing") with their details
// (the largest and the nominal step, each irregular step, how far the lines miss) as notes,
// and a note when HSF-OCT-104 BMO fields are present (never used: their meaning is unverified).
struct RadialGeometryQc {
    std::vector<std::string> flags;
    std::vector<std::string> notes;
};
[[nodiscard]] RadialGeometryQc radial_geometry_qc(const RadialGeometry& g);

}  // namespace octshape::retina
