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

}  // namespace octshape::io
