#pragma once
// Opening any supported export: the format is detected from the content, not the file name.

#include <string>

#include "octshape/io/scan.h"

namespace octshape::io {

enum class FileFormat { kUnknown, kVol, kHeyexXml, kIowaSurfaces, kTopcon };

// Checks that `path` is an existing, readable regular file and detects its format from its
// first bytes. Throws InputError (missing / not regular / unreadable).
[[nodiscard]] FileFormat detect_format(const std::string& path);

// Reads a scan of any supported format. Throws InputError; kUnsupported for an unknown format.
[[nodiscard]] Scan read_scan(const std::string& path, const ReadOptions& options = {});

// A scan with the SHA-256 of the file it was read from.
struct HashedScan {
    Scan scan;
    std::string sha256;  // lower-case hex of the input file's bytes
};

// read_scan and the SHA-256 of the same bytes: the file is hashed, then parsed (the second
// reading comes from the page cache), and its version (device, inode, size, modification and
// change times) is compared before and after. A file that changes in between, or while either
// reading runs, is refused with InputError (corrupt: "the file changed while it was being
// read"), so the hash always describes the bytes that were analysed. Nothing is mapped: a file
// truncated under the reader is a short read and the usual "file truncated" error, never a
// signal. Safe to call from several threads at once. Throws InputError as read_scan.
[[nodiscard]] HashedScan read_scan_hashed(const std::string& path, const ReadOptions& options = {});

}  // namespace octshape::io
