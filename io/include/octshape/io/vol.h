#pragma once
// Heidelberg Spectralis raw export (.vol, HSF-OCT-100 ... 104): reader and HSF-OCT-103 writer.
// Byte layout: docs/formats.md.

#include <cstdint>
#include <iosfwd>
#include <string>

#include "octshape/io/scan.h"

namespace octshape::io {

// True when the first bytes are a Spectralis .vol magic ("HSF-OCT-").
[[nodiscard]] bool looks_like_vol(const char* head, std::size_t n);

// Reads a .vol from `in`, which holds `size` bytes; `name` is used in error messages.
// Throws InputError (truncated / corrupt / unsupported) with the byte offset of the problem.
// Never allocates more than the declared sizes, and checks those against `size` first.
[[nodiscard]] Scan read_vol(std::istream& in, std::uint64_t size, const std::string& name,
                            const ReadOptions& options = {});

// Writes `scan` as HSF-OCT-103. Every header field, segmentation value (NaN -> FLT_MAX) and
// pixel is written so that read_vol gives the same Scan back. Without pixels, B-scans and the
// SLO are written as kNoPixelData / zeros. Throws UsageError for a scan that cannot be written
// (inconsistent sizes, more lines than fit in the B-scan header).
void write_vol(const Scan& scan, std::ostream& out);

}  // namespace octshape::io
