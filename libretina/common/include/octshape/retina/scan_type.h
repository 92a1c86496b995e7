#pragma once
// Which analysis a scan is for, decided from its content (docs/cohort.md, "Classifier").
//
// The optic nerve head has no Bruch's membrane inside the BM opening (BMO, 1.2-2.5 mm across),
// so the device's BM segmentation of a B-scan through the disc has a long *interior* gap:
// missing values with valid BM on both sides. A macula scan has BM everywhere; its gaps are a
// few missing A-scans (shadows, dropouts) or runs that touch the end of the B-scan (a line
// scan reaching the disc edge). Radial scans are classified by the same rule (a line through
// the disc crosses the whole BMO). Circle patterns are peripapillary RNFL scans that octshape
// does not analyse.

#include <string>

#include "octshape/io/scan.h"

namespace octshape::retina {

enum class ScanType { kMacula, kOnh, kUnsupported };

[[nodiscard]] const char* to_string(ScanType t);

struct ScanTypeParams {
    // An interior BM gap at least this long (mm along the B-scan) is a BMO crossing. Half the
    // smallest BMO diameter (1.2 mm): a B-scan through the middle third of any disc has one,
    // while random dropouts would need ~40 consecutive missing A-scans at ScaleX 11.7 um.
    double min_gap_mm = 0.5;
    // Number of B-scans that must show such a gap (a single B-scan when the scan has one).
    int min_bscans = 2;

    void validate() const;  // throws UsageError naming the bad field
};

struct ScanTypeResult {
    ScanType type = ScanType::kUnsupported;
    std::string reason;           // one sentence: why this type
    double longest_gap_mm = 0.0;  // longest interior BM gap over all B-scans
    int bscans_with_gap = 0;      // B-scans with an interior gap >= min_gap_mm
};

[[nodiscard]] ScanTypeResult classify_scan(const io::Scan& scan, const ScanTypeParams& params = {});

}  // namespace octshape::retina
