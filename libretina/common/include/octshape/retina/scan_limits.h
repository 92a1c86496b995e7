#pragma once
// What a Spectralis can produce, as a gate before any analysis allocates: scales and spacings
// outside these ranges describe no real eye scan (a corrupt or hostile header that still parses)
// and are refused with AnalysisError saying what was found and what is expected. The ranges
// (docs/coordinates.md "Plausible scans"):
//   ScaleZ      3.87 um per pixel on every Spectralis (the spectrometer's fixed sampling); we
//               accept 1-20 um.
//   ScaleX      scan angles of 10-30 deg (55 deg with the wide-field objective, ~16 mm) over
//               256-1536 A-scans give 1.9-63 um per A-scan; we accept 1-100 um.
//   Distance    volumes of 7-1536 B-scans over up to 16 mm: 5 um (dense ART volumes) to 2.7 mm
//               (7 lines over 16 mm) between B-scans; we accept 1 um-3 mm.
// Source: Heidelberg Engineering, SPECTRALIS HRA+OCT technical data and user manual (scan angle,
// A-scans per B-scan, B-scans per volume, 3.9 um digital axial resolution).

#include "octshape/io/scan.h"

namespace octshape::retina {

struct ScanLimits {
    double min_scale_z_mm = 0.001, max_scale_z_mm = 0.020;
    double min_scale_x_mm = 0.001, max_scale_x_mm = 0.100;
    double min_distance_mm = 0.001, max_distance_mm = 3.0;
};

// Throws AnalysisError("ScaleX 1e-08 mm per A-scan is not a Spectralis scan (expected 0.001 to
// 0.1 mm)" ...) when ScaleX or ScaleZ, or with `needs_distance` the B-scan Distance, lies
// outside `limits`.
void check_scan_scales(const io::Scan& scan, bool needs_distance, const ScanLimits& limits = {});

}  // namespace octshape::retina
