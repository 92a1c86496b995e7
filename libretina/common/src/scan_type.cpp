#include "octshape/retina/scan_type.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "octshape/error.h"

namespace octshape::retina {

const char* to_string(ScanType t) {
    switch (t) {
        case ScanType::kMacula:
            return "macula";
        case ScanType::kOnh:
            return "onh";
        case ScanType::kUnsupported:
            return "unsupported";
    }
    return "unsupported";
}

void ScanTypeParams::validate() const {
    if (!(std::isfinite(min_gap_mm) && min_gap_mm > 0.0)) {
        throw UsageError("ScanTypeParams.min_gap_mm must be > 0");
    }
    if (min_bscans < 1) throw UsageError("ScanTypeParams.min_bscans must be >= 1");
}

namespace {

// Longest run of missing values with a valid value on both sides (A-scans).
int longest_interior_gap(const std::vector<float>& line) {
    int best = 0;
    int last_valid = -1;
    for (int a = 0; a < static_cast<int>(line.size()); ++a) {
        if (!io::is_valid(line[static_cast<std::size_t>(a)])) continue;
        if (last_valid >= 0) best = std::max(best, a - last_valid - 1);
        last_valid = a;
    }
    return best;
}

}  // namespace

ScanTypeResult classify_scan(const io::Scan& scan, const ScanTypeParams& params) {
    params.validate();
    ScanTypeResult r;
    const auto pattern = scan.meta.pattern;
    // Radial scans (lines through one point) are classified like volumes: a line through the
    // disc crosses the whole BMO (an interior gap of its diameter there), a line through the
    // fovea has BM everywhere. Circles (and the radial-plus-circles pattern, whose circle
    // B-scans are no lines) are peripapillary RNFL scans without a shape analysis.
    if (pattern == io::ScanPattern::kCircle || pattern == io::ScanPattern::kRadialCircles) {
        r.reason = std::string("scan pattern '") + std::string(io::to_string(pattern)) +
                   "': peripapillary circle scans have no fovea or ONH shape analysis";
        return r;
    }
    if (scan.num_bscans() == 0) {
        r.reason = "no B-scans";
        return r;
    }
    const int bm = static_cast<int>(io::Layer::kBM);
    if (scan.num_lines() <= bm || scan.valid_fraction(bm) == 0.0) {
        r.reason = "no BM segmentation: the scan type cannot be decided";
        return r;
    }
    const double sx = scan.meta.scale_x_mm;
    for (const auto& b : scan.bscans) {
        const double gap_mm = longest_interior_gap(b.seg[static_cast<std::size_t>(bm)]) * sx;
        r.longest_gap_mm = std::max(r.longest_gap_mm, gap_mm);
        if (gap_mm >= params.min_gap_mm) ++r.bscans_with_gap;
    }
    const int needed = std::min(params.min_bscans, scan.num_bscans());
    std::ostringstream why;
    why.precision(3);
    if (r.bscans_with_gap >= needed) {
        r.type = ScanType::kOnh;
        why << r.bscans_with_gap << " B-scan(s) with an interior BM gap >= " << params.min_gap_mm
            << " mm (longest " << r.longest_gap_mm << " mm): the BM opening of the optic disc";
    } else {
        r.type = ScanType::kMacula;
        why << "BM continuous (longest interior gap " << r.longest_gap_mm << " mm < "
            << params.min_gap_mm << " mm in at least " << needed << " B-scan(s))";
    }
    r.reason = why.str();
    return r;
}

}  // namespace octshape::retina
