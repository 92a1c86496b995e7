#pragma once
// Topcon 3D OCT exports (.fda, and .fds with raw B-scans), as the 3D OCT-1000 / 2000 write them
// and as UK Biobank stores its macular cubes: a 15-byte header ("FOCT" + "FDA"/"FDS"/"FAA") and
// named chunks. Read: the scan geometry, the eye, the exam date and patient fields (private),
// and the device's layer contours (@CONTOUR_INFO) as segmentation lines; B-scan pixels when asked
// (JPEG 2000 frames of .fda, decoded with OpenJPEG; raw .fds B-scans are not decoded). Layout, which contour is which boundary and how that was
// established, orientation and B-scan order: docs/formats.md "Topcon .fda / .fds".

#include <cstddef>
#include <cstdint>
#include <iosfwd>
#include <string>
#include <string_view>

#include "octshape/io/scan.h"

namespace octshape::io {

// The largest file read (the whole file is held in memory while it is parsed). A UK Biobank
// .fda is ~30-60 MB, a 512 x 885 x 128 .fds with raw 16-bit B-scans ~116 MB.
inline constexpr std::uint64_t kTopconMaxFileBytes = std::uint64_t{1} << 30;  // 1 GiB

// True when the first bytes are a Topcon header ("FOCT" then "FDA", "FDS" or "FAA").
[[nodiscard]] bool looks_like_topcon(const char* head, std::size_t n);

// Parses a Topcon file held in `data` (`name` for messages). Line 0 = ILM (RETINA_1), line 1 =
// BM: the outer boundary of the RPE (RETINA_4) for IowaBm::kOuterRpe (the default), the inner
// one (RETINA_3) for kInnerRpe; the other contours follow, named. Throws InputError (truncated /
// corrupt / unsupported) with the byte offset of the problem; every size is checked against the
// bytes present before anything is allocated.
[[nodiscard]] Scan parse_topcon(std::string_view data,
                                const std::string& name,
                                const ReadOptions& options = {});

// Reads the file (at most kTopconMaxFileBytes) and parses it.
[[nodiscard]] Scan read_topcon(const std::string& path, const ReadOptions& options = {});

// Writes `scan` (a volume of parallel B-scans with ILM and BM lines, e.g. a phantom) as an .fda
// that parse_topcon reads back with the same geometry and lines: @HW_INFO_03 naming octshape,
// @CAPTURE_INFO_02 (eye), @PARAM_SCAN_04, an @IMG_JPEG header without frames, and the contours
// RETINA_1 (ILM), RETINA_3 (BM line moved up by `inner_rpe_px`, at least 1 px) and RETINA_4 (BM).
// Depths are rounded to whole pixels, as the device stores them. Throws UsageError for a scan
// that cannot be written (not a volume, missing lines, depths outside the B-scan), OutputError
// when the stream fails.
void write_topcon(const Scan& scan, std::ostream& out, int inner_rpe_px = 12);
// write_topcon to `path` atomically (the file appears complete or not at all).
void write_topcon_file(const Scan& scan, const std::string& path);

}  // namespace octshape::io
