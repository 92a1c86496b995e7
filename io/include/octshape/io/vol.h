#pragma once
// Heidelberg Spectralis raw export (.vol, HSF-OCT-100 ... 104): reader and HSF-OCT-103 writer.
// Byte layout, validation rules and the writer's choices: docs/formats.md.

#include <cstddef>
#include <cstdint>
#include <iosfwd>
#include <string>

#include "octshape/io/scan.h"

namespace octshape::io {

// Size of the .vol file header; the SLO image starts right after it.
inline constexpr std::uint64_t kVolFileHeaderSize = 2048;

// True when the first bytes are a Spectralis .vol magic ("HSF-OCT-").
[[nodiscard]] bool looks_like_vol(const char* head, std::size_t n);

// Reads a .vol from `in`, which holds `size` bytes; `name` is used in error messages.
// Throws InputError (truncated / corrupt / unsupported) with the byte offset of the problem.
// Never allocates more than the declared sizes, and checks those against `size` first.
// With options.pixels == false the B-scan pixels and the SLO are skipped (seeked past), but the
// stream must still be long enough to hold them.
[[nodiscard]] Scan read_vol(std::istream& in,
                            std::uint64_t size,
                            const std::string& name,
                            const ReadOptions& options = {});

// Writes `scan` as HSF-OCT-103. Every header field, segmentation value (NaN -> FLT_MAX) and
// pixel is written so that read_vol gives the same Scan back. Without pixels, B-scans and the
// SLO are written as kNoPixelData / zeros. Derived fields are recomputed, not copied from
// scan.meta: BScanHdrSize (meta.bscan_hdr_size if it is large enough, else the smallest
// multiple of 256 that holds every B-scan's segmentation), GridType/GridOffset (from
// scan.grids; grids are placed after the last B-scan). v104 BMO fields are not written.
// Throws UsageError for a scan that cannot be written (inconsistent sizes, values the reader
// would reject, more lines than fit), OutputError when the stream fails.
void write_vol(const Scan& scan, std::ostream& out);

// write_vol to `path` atomically (temporary file in the same directory, fsync, rename): the
// file appears complete or not at all. Throws UsageError as write_vol (before any file is
// created) and OutputError when the file cannot be written.
void write_vol_file(const Scan& scan, const std::string& path);

}  // namespace octshape::io
