#pragma once
// Opening any supported export: the format is detected from the content, not the file name.

#include <string>

#include "octshape/io/scan.h"

namespace octshape::io {

enum class FileFormat { kUnknown, kVol, kHeyexXml };

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

// read_scan and the file's SHA-256 from ONE reading of the file: a .vol is mapped into memory
// once, hashed and parsed from the same bytes, so the hash always describes the bytes that were
// analysed (a file replaced between two readings cannot give a result under a wrong hash) and
// the 100-300 MB of a volume pass through memory once. An XML export is read from its files and
// its XML file hashed. If another process truncates the file while it is mapped, the process
// stops with a one-line message naming the file and exit code 65 (the kernel's SIGBUS, caught).
// Throws InputError as read_scan.
[[nodiscard]] HashedScan read_scan_hashed(const std::string& path, const ReadOptions& options = {});

}  // namespace octshape::io
