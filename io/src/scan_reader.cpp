#include "octshape/io/scan_reader.h"

#include <sys/stat.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <vector>

#include "octshape/error.h"
#include "octshape/io/heyex_xml.h"
#include "octshape/io/iowa_surfaces.h"
#include "octshape/io/sha256.h"
#include "octshape/io/topcon.h"
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

// ---- a file that must not change while it is read (read_scan_hashed) ---------------------------

// What identifies one version of a file: a file replaced, truncated, extended or rewritten while
// it is read differs in at least one of these (the modification time has nanosecond resolution
// on the file systems octshape runs on; the change time moves with every write and truncate).
struct FileVersion {
    dev_t dev = 0;
    ino_t ino = 0;
    off_t size = 0;
    timespec mtime{};
    timespec ctime{};

    [[nodiscard]] bool operator==(const FileVersion& o) const {
        return dev == o.dev && ino == o.ino && size == o.size && mtime.tv_sec == o.mtime.tv_sec &&
               mtime.tv_nsec == o.mtime.tv_nsec && ctime.tv_sec == o.ctime.tv_sec &&
               ctime.tv_nsec == o.ctime.tv_nsec;
    }
};

FileVersion file_version(const std::string& path) {
    struct stat st {};
    if (::stat(path.c_str(), &st) != 0) {
        if (errno == ENOENT) throw InputError::missing(path);
        throw InputError::unreadable(path, std::strerror(errno));
    }
    return {st.st_dev, st.st_ino, st.st_size, st.st_mtim, st.st_ctim};
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
    if (looks_like_iowa_surfaces(head.data(), n)) return FileFormat::kIowaSurfaces;
    if (looks_like_topcon(head.data(), n)) return FileFormat::kTopcon;
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
        case FileFormat::kIowaSurfaces:
            return iowa_scan(read_iowa_surfaces(path), path, options.iowa_bm);
        case FileFormat::kTopcon:
            return read_topcon(path, options);
        case FileFormat::kUnknown:
            break;
    }
    std::ifstream in(path, std::ios::binary);
    std::array<char, 16> head{};
    in.read(head.data(), head.size());
    throw InputError::unsupported(
        path,
        "not a Spectralis .vol, Heidelberg XML export, Iowa surfaces XML or Topcon .fda/.fds "
        "(starts with \"" +
            describe_head(head.data(), static_cast<std::size_t>(in.gcount())) + "\")",
        0);
}

HashedScan read_scan_hashed(const std::string& path, const ReadOptions& options) {
    // Two ordinary reads (the second from the page cache) between two looks at the file's
    // version: a file that changes in between (truncated, rewritten, replaced) is refused with a
    // typed error, and one truncated during either read fails there as any truncated file does.
    // Ordinary reads, never a mapping: a mapped file that shrinks raises SIGBUS, which a library
    // cannot turn into an error without a process-wide handler.
    (void)detect_format(path);  // missing, not regular, empty: the usual errors first
    const FileVersion before = file_version(path);
    HashedScan out;
    // The hash of exactly `before.size` bytes: a file cut while it is hashed hashes fewer, and
    // the timestamps alone may not move (they tick at the kernel's clock granularity).
    {
        std::ifstream in(path, std::ios::binary);
        if (!in) throw InputError::unreadable(path, "cannot open");
        Sha256 hash;
        std::vector<char> chunk(std::size_t{1} << 20U);
        std::uint64_t hashed = 0;
        while (in) {
            in.read(chunk.data(), static_cast<std::streamsize>(chunk.size()));
            const auto got = static_cast<std::size_t>(in.gcount());
            if (got == 0) break;
            hash.update(chunk.data(), got);
            hashed += got;
        }
        if (in.bad()) throw InputError::unreadable(path, "read error");
        if (hashed != static_cast<std::uint64_t>(before.size)) {
            throw InputError::corrupt(path,
                                      "the file changed while it was being read (read it "
                                      "again once whatever writes it has finished)");
        }
        out.sha256 = hash.hex();
    }
    out.scan = read_scan(path, options);
    if (!(file_version(path) == before)) {
        throw InputError::corrupt(path,
                                  "the file changed while it was being read (read it again "
                                  "once whatever writes it has finished)");
    }
    return out;
}

}  // namespace octshape::io
