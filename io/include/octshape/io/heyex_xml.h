#pragma once
// Heidelberg XML export (HEDX): an XML file with segmentation lines by name, and the B-scans
// and the localizer (SLO) as 8-bit images beside it. Layout and decisions: docs/formats.md.

#include <cstddef>
#include <string>

#include "octshape/io/scan.h"

namespace octshape::io {

// True when the first bytes look like an XML document whose root is <HEDX>
// (after an optional BOM, white space, declaration and comments within `n` bytes).
[[nodiscard]] bool looks_like_heyex_xml(const char* head, std::size_t n);

// Reads the export at `path`. B-scan images (named by ImageData/ExamURL's basename, looked up
// beside the XML) are read through OpenCV only when options.pixels; their 8-bit display values
// are turned back into linear reflectance with the inverse of the v^0.25 display transform.
// Throws InputError naming the file and the problem.
[[nodiscard]] Scan read_heyex_xml(const std::string& path, const ReadOptions& options = {});

}  // namespace octshape::io
