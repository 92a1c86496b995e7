#pragma once
// Iowa Reference Algorithms surfaces XML (OCTExplorer / OCTLayerSeg, `*_Surfaces_Iowa.xml`): the
// layer boundaries another program segmented, as integer pixel rows per A-scan. Read alone (a
// scan of segmentation only: geometry from the file's sizes and voxel size on a regular grid, no
// pixels) or laid over the export it was made from (the export's geometry and pixels, these
// lines). Layout, the label table and the decisions: docs/formats.md "Iowa surfaces XML".

#include <cstddef>
#include <string>
#include <string_view>
#include <vector>

#include "octshape/io/scan.h"

namespace octshape::io {

// Iowa labels of the boundaries the analyses use.
inline constexpr int kIowaIlm = 10;            // ILM
inline constexpr int kIowaInnerRpe = 140;      // IB_RPE, the inner boundary of the RPE
inline constexpr int kIowaOuterRpe = 150;      // OB_RPE, the outer boundary of the RPE

// IowaBm (which surface plays Bruch's membrane) is declared with ReadOptions in scan.h.
[[nodiscard]] std::string_view to_string(IowaBm bm);
// "ob_rpe" | "ib_rpe"; throws UsageError otherwise.
[[nodiscard]] IowaBm parse_iowa_bm(std::string_view s);
[[nodiscard]] int label_of(IowaBm bm);

struct IowaSurface {
    int label = 0;
    std::string name;      // as in the file, e.g. "ILM (ILM)"
    // depth_px[b * size_x + a]: the boundary's row at (B-scan b, A-scan a); NaN = undefined.
    std::vector<float> depth_px;
};

struct IowaSurfaces {
    std::string format_version;      // <version>, e.g. "4.0.0"
    std::string executable;          // <executable><name>, e.g. "OCTLayerSeg"
    std::string executable_version;  // e.g. "3.8.0"
    std::string manufacturer;
    std::string center_type;         // "macula", "onh", ... as stored
    int size_x = 0;                  // A-scans per B-scan
    int size_y = 0;                  // pixels per A-scan
    int size_z = 0;                  // B-scans
    double voxel_x_mm = 0.0;
    double voxel_y_mm = 0.0;
    double voxel_z_mm = 0.0;         // B-scan spacing
    Laterality laterality = Laterality::kUnknown;
    std::vector<IowaSurface> surfaces;  // in file order
    int num_undefined = 0;              // A-scans listed in <undefined_region>

    // The surface with this label, or nullptr.
    [[nodiscard]] const IowaSurface* find(int label) const;
    // "OCTLayerSeg 3.8.0 surfaces (format 4.0.0)".
    [[nodiscard]] std::string describe() const;
};

// True when the first bytes look like an XML document whose root is <surfaces>.
[[nodiscard]] bool looks_like_iowa_surfaces(const char* head, std::size_t n);

// Reads and checks the file: sizes in range and equal to the element counts, every value a
// number, the ILM and both RPE boundaries present. Undefined A-scans are NaN in every surface.
// Memory is bounded by the file size, which is capped (64 MiB). Throws InputError naming the
// file, the problem and its byte offset.
[[nodiscard]] IowaSurfaces read_iowa_surfaces(const std::string& path);
// The same on a document in memory (`name` for messages): the fuzz target's entry.
[[nodiscard]] IowaSurfaces parse_iowa_surfaces(std::string_view doc, const std::string& name);

// The surfaces as a scan of segmentation only: line 0 = ILM (label 10), line 1 = BM (`bm`), the
// other surfaces after them in file order, named in Scan::line_names; a regular grid of
// size_z B-scans voxel_z apart, no B-scan positions on an SLO (the analyses then assume the
// documented orientation and say so), no pixels.
[[nodiscard]] Scan iowa_scan(const IowaSurfaces& s, const std::string& path,
                             IowaBm bm = IowaBm::kOuterRpe);

// Replaces the segmentation of `scan` (an export) by that of `segmentation` (a scan of
// segmentation only, e.g. iowa_scan), keeping the export's geometry and pixels. It must describe
// this scan: the same A-scans per B-scan, pixels per A-scan and number of B-scans, voxel sizes
// within 1 % of the export's scales, and the same eye when both say; else UsageError naming both
// files and what differs. Adds a note saying where the segmentation came from.
void apply_segmentation(Scan& scan, const Scan& segmentation);

}  // namespace octshape::io
