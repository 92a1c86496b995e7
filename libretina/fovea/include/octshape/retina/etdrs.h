#pragma once
// ETDRS sectors (docs/algorithms/etdrs.md): the mean thickness between two boundaries in the
// nine sectors of the Early Treatment Diabetic Retinopathy Study grid (circles of 1, 3 and 6 mm
// diameter; the two rings cut into superior, nasal, inferior and temporal quadrants at the 45 deg
// diagonals), the sectors' volumes and the total, centred on a point of the scan; and the
// comparison with the thickness grid the device stored in the export.
//
// The integrals are computed over the thickness map's bilinear interpolant on a polar grid about
// the centre (rings 10 um wide, arcs of at most 10 um) whose rings and rays fall on the sectors'
// borders, so every sector's area is integrated exactly. Missing map values leave holes: a
// sector's mean is over what is measured, and is reported only when at least `min_coverage` of
// its area is. Sector names are anatomical for both eyes (nasal: towards the optic disc).

#include <Eigen/Core>
#include <array>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "octshape/io/scan.h"
#include "octshape/retina/cube.h"
#include "octshape/retina/scan_geometry.h"

namespace octshape::retina {

inline constexpr int kEtdrsSectors = 9;
// Order of every sector array below: the central subfield, the inner ring, the outer ring.
inline constexpr std::array<std::string_view, kEtdrsSectors> kEtdrsSectorNames = {
    "central",        "inner_superior", "inner_nasal",    "inner_inferior", "inner_temporal",
    "outer_superior", "outer_nasal",    "outer_inferior", "outer_temporal"};

struct EtdrsParams {
    std::array<double, 3> diameters_mm{1.0, 3.0, 6.0};
    double step_mm = 0.01;       // ring width and longest arc of the quadrature
    double min_coverage = 0.9;   // measured fraction of a sector's area needed to report it
    // Throws UsageError naming the bad field.
    void validate() const;
};

struct EtdrsSector {
    double thickness_mm = kMissing;  // mean over the measured part of the sector
    double volume_mm3 = kMissing;    // mean x the sector's whole area
    double coverage = 0.0;           // measured fraction of its area
};

struct EtdrsGrid {
    Eigen::Vector2d centre_mm = Eigen::Vector2d::Zero();  // grid mm
    double centre_thickness_mm = kMissing;  // the map's bilinear value at the centre
    std::array<EtdrsSector, kEtdrsSectors> sectors{};
    double total_volume_mm3 = kMissing;  // sum of the nine, when all nine are reported
    double coverage = 0.0;               // measured fraction of the whole disk
};

// The nine sectors of the thickness map `m` about `centre_mm` (grid mm), quadrants from `geo`.
// Throws UsageError for bad params; AnalysisError for a line scan (one row: no sectors).
[[nodiscard]] EtdrsGrid etdrs_grid(const ThicknessMap& m,
                                   const ScanGeometry& geo,
                                   const Eigen::Vector2d& centre_mm,
                                   const EtdrsParams& p = {});

// The device's circular grid's nine cells in kEtdrsSectorNames order (the file stores C0, N1,
// N2, S1, S2, T1, T2, I1, I2), and its centre in grid mm.
struct DeviceEtdrs {
    int type = 0;
    std::array<double, 3> diameters_mm{};
    Eigen::Vector2d centre_mm = Eigen::Vector2d::Zero();
    double centre_off_scan_mm = 0.0;  // line scans: distance of the centre from the line
    double central_thickness_mm = kMissing;
    std::array<double, kEtdrsSectors> thickness_mm{};
    std::array<double, kEtdrsSectors> volume_mm3{};
    double total_volume_mm3 = kMissing;
};
// The first circular grid of the export, or nullopt.
[[nodiscard]] std::optional<DeviceEtdrs> device_etdrs(const io::Scan& scan,
                                                      const ScanGeometry& geo);

// Everything the macula analysis reports about ETDRS sectors and the device's grid.
struct EtdrsReport {
    EtdrsParams params;
    std::string upper_layer = "ILM";
    std::string lower_layer = "BM";
    bool line_scan = false;
    std::optional<EtdrsGrid> at_fovea;   // centred on the analysis's fovea centre (volumes)
    std::optional<EtdrsGrid> at_device;  // centred on the device grid's centre (volumes)
    // Centred on the scan's centre (volumes): the middle of the A-scan x B-scan raster, where
    // the device put the fixation target; the grid a device without a stored grid reports.
    std::optional<EtdrsGrid> at_scan_centre;
    std::optional<DeviceEtdrs> device;
    // Ours at the device grid's centre (volumes: bilinear; line scans: along the line at the
    // centre's projection) and its difference from the device's central thickness.
    double ours_at_device_centre_mm = kMissing;
    double central_difference_um = kMissing;  // ours - device
    std::vector<std::string> qc_flags;
    std::vector<std::string> notes;
};

// A thickness map between two named lines of the scan (upper above lower), with thickness_map's
// rules for missing and impossible values. Throws AnalysisError for a name the scan lacks.
[[nodiscard]] ThicknessMap layer_thickness_map(const io::Scan& scan,
                                               std::string_view upper,
                                               std::string_view lower);

// The report for a macula analysis `res` of `scan`: between `upper` and `lower` (default the
// retina, ILM to BM, which is res.map).
[[nodiscard]] EtdrsReport etdrs_report(const io::Scan& scan,
                                       const CubeResult& res,
                                       const EtdrsParams& p = {},
                                       std::string_view upper = "ILM",
                                       std::string_view lower = "BM");

}  // namespace octshape::retina

#include <nlohmann/json.hpp>

namespace octshape::retina {

// The "etdrs" object of the per-eye JSON (docs/outputs.md): the options, both grids (sector by
// name: thickness, volume, coverage), the device's grid beside them and the differences.
[[nodiscard]] nlohmann::ordered_json etdrs_json(const EtdrsReport& r);
// Stable CSV columns and their values (the fovea-centred grid, the device-centred grid, the
// device's central thickness, ours at its centre and the difference, then the grid at the scan
// centre).
[[nodiscard]] std::vector<std::string> etdrs_csv_header();
[[nodiscard]] std::vector<std::string> etdrs_csv_values(const EtdrsReport& r);

}  // namespace octshape::retina
