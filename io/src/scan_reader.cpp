#include "octshape/io/scan_reader.h"

#include <array>
#include <filesystem>
#include <fstream>

#include "octshape/io/error.h"
#include "octshape/io/heyex_xml.h"
#include "octshape/io/vol.h"

namespace octshape::io {
namespace {

namespace fs = std::filesystem;

// Enough bytes to see past an XML declaration and a comment to the root element.
constexpr std::size_t kSniffBytes = 1024;

// The first bytes of a file, printable for an error message.
std::string describe_head(const char* head, std::size_t n) {
    std::string out;
    for (std::size_t i = 0; i < std::min<std::size_t>(n, 12); ++i) {
        const auto c = static_cast<unsigned char>(head[i]);
        if (c >= 0x20 && c < 0x7F) {
            out += static_cast<char>(c);
        } else {
            static constexpr char kHex[] = "0123456789abcdef";
            out += "\\x";
            out += kHex[c >> 4];
            out += kHex[c & 15];
        }
    }
    return out;
}

}  // namespace

FileFormat detect_format(const std::string& path) {
    std::error_code ec;
    const fs::file_status st = fs::status(path, ec);
    if (ec || !fs::exists(st)) throw InputError::missing(path);
    if (!fs::is_regular_file(st)) throw InputError::not_regular(path);
    std::ifstream in(path, std::ios::binary);
    if (!in) throw InputError::unreadable(path, "permission denied or I/O error");
    std::array<char, kSniffBytes> head{};
    in.read(head.data(), head.size());
    const auto n = static_cast<std::size_t>(in.gcount());
    if (n == 0) throw InputError::truncated(path, "the file is empty", 0);
    if (looks_like_vol(head.data(), n)) return FileFormat::kVol;
    if (looks_like_heyex_xml(head.data(), n)) return FileFormat::kHeyexXml;
    return FileFormat::kUnknown;
}

Scan read_scan(const std::string& path, const ReadOptions& options) {
    switch (detect_format(path)) {
        case FileFormat::kVol: {
            std::ifstream in(path, std::ios::binary);
            if (!in) throw InputError::unreadable(path, "cannot open");
            std::error_code ec;
            const auto size = fs::file_size(path, ec);
            if (ec) throw InputError::unreadable(path, ec.message());
            Scan scan = read_vol(in, size, path, options);
            scan.source_path = path;
            return scan;
        }
        case FileFormat::kHeyexXml:
            return read_heyex_xml(path, options);
        case FileFormat::kUnknown:
            break;
    }
    std::ifstream in(path, std::ios::binary);
    std::array<char, 16> head{};
    in.read(head.data(), head.size());
    throw InputError::unsupported(
        path, "not a Spectralis .vol or Heidelberg XML export (starts with \"" +
                  describe_head(head.data(), static_cast<std::size_t>(in.gcount())) + "\")",
        0);
}

}  // namespace octshape::io
