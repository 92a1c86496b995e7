#pragma once
// Speckle statistics of a B-scan band: measured on real Spectralis B-scans and on the phantoms'
// (docs/phantoms.md, "Speckle").

#include <array>
#include <cstddef>
#include <span>

#include "octshape/io/scan.h"

namespace octshape::retina::phantom {

// Speckle statistics of a band of a B-scan (docs/phantoms.md, "Speckle"): the rows
// top_row[a] .. top_row[a] + rows - 1 of every A-scan a with top_row[a] >= 0 (a band following
// a boundary, so the layer is flat in it). Each pixel is divided by the mean of the
// (2 box_half + 1)^2 box about it in the band's own coordinates (A-scan, row below top_row):
// the slow structure goes, the speckle stays. A pixel whose box leaves the band's A-scans or the
// image is not used. Contrast = SD / mean of the normalised values, shape = mean^2 / variance
// (a Gamma's shape, the "looks"), the autocorrelation of the normalised values at lags 1..3
// along the A-scan (axial) and across A-scans (lateral), and its half-width: the lag where it
// falls to 0.5, linearly interpolated between lags (from lag 0, where it is 1, when lag 1 is
// already below 0.5).
struct SpeckleStats {
    std::size_t count = 0;
    double mean_raw = 0.0;      // mean pixel value (file units) of the used pixels
    double zero_fraction = 0.0; // pixels exactly 0 (clipped)
    double contrast = 0.0;
    double shape = 0.0;
    std::array<double, 4> acf_axial{};    // lags 0..3 px
    std::array<double, 4> acf_lateral{};  // lags 0..3 A-scans
    double half_width_axial_px = 0.0;     // NaN when still >= 0.5 at lag 3
    double half_width_lateral_px = 0.0;
};
// Throws UsageError for a bad size or box_half < 1, AnalysisError when no pixel is usable.
[[nodiscard]] SpeckleStats speckle_statistics(const io::BScan& bscan,
                                              int size_x,
                                              int size_z,
                                              std::span<const int> top_row,
                                              int rows,
                                              int box_half = 4);

}  // namespace octshape::retina::phantom
