#include "octshape/io/scan_reader.h"

#include <fcntl.h>
#include <signal.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <streambuf>

#include "octshape/io/error.h"
#include "octshape/io/heyex_xml.h"
#include "octshape/io/sha256.h"
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

// ---- one reading of a mapped file (read_scan_hashed) -------------------------------------------

// The path of the file being read from a mapping, for the SIGBUS message (set before the
// mapping is touched; a fixed buffer because the handler may only use async-signal-safe calls).
char g_mapped_path[4096] = {};
std::atomic<bool> g_mapped_active{false};

extern "C" void on_sigbus(int sig) {
    if (!g_mapped_active.load()) {  // not ours: the default action (a core dump as before)
        ::signal(sig, SIG_DFL);
        ::raise(sig);
        return;
    }
    static constexpr char kHead[] = "octshape: error: ";
    static constexpr char kTail[] = ": the file shrank while it was being read\n";
    (void)!::write(STDERR_FILENO, kHead, sizeof kHead - 1);
    (void)!::write(STDERR_FILENO, g_mapped_path, ::strnlen(g_mapped_path, sizeof g_mapped_path));
    (void)!::write(STDERR_FILENO, kTail, sizeof kTail - 1);
    ::_exit(static_cast<int>(ExitCode::kDataError));
}

void install_sigbus_handler() {
    static std::once_flag once;
    std::call_once(once, [] {
        struct sigaction sa {};
        sa.sa_handler = on_sigbus;
        sigemptyset(&sa.sa_mask);
        ::sigaction(SIGBUS, &sa, nullptr);
    });
}

// A read-only private mapping of a whole file; empty when the file cannot be mapped (the caller
// then reads it the ordinary way).
class MappedFile {
  public:
    explicit MappedFile(const std::string& path) {
        const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
        if (fd < 0) throw InputError::unreadable(path, std::strerror(errno));
        struct stat st {};
        if (::fstat(fd, &st) == 0 && S_ISREG(st.st_mode) && st.st_size > 0) {
            size_ = static_cast<std::size_t>(st.st_size);
            void* p = ::mmap(nullptr, size_, PROT_READ, MAP_PRIVATE, fd, 0);
            if (p != MAP_FAILED) {
                data_ = static_cast<const char*>(p);
                ::madvise(p, size_, MADV_SEQUENTIAL);
            }
        }
        ::close(fd);  // the mapping keeps the file
    }
    ~MappedFile() {
        if (data_ != nullptr) ::munmap(const_cast<char*>(data_), size_);
    }
    MappedFile(const MappedFile&) = delete;
    MappedFile& operator=(const MappedFile&) = delete;

    [[nodiscard]] bool mapped() const { return data_ != nullptr; }
    [[nodiscard]] std::string_view bytes() const { return {data_, size_}; }

    // Drops the whole pages inside [begin, end) from this process's resident memory; they stay
    // in the page cache and a later read maps them again (a clean read-only mapping of a file:
    // nothing is lost). Keeps the file's pages from being resident beside the pixels copied
    // out of them (the .vol is as large as its pixels).
    void release(std::size_t begin, std::size_t end) const {
        static const auto page = static_cast<std::size_t>(::sysconf(_SC_PAGESIZE));
        const std::size_t b = (begin + page - 1) / page * page;
        const std::size_t e = std::min(end, size_) / page * page;
        if (data_ == nullptr || e <= b) return;
        ::madvise(const_cast<char*>(data_) + b, e - b, MADV_DONTNEED);
    }

  private:
    const char* data_ = nullptr;
    std::size_t size_ = 0;
};

// An input stream over the bytes of a mapped file (no copy), seekable as read_vol needs; the
// pages behind the read position are released every kReleaseBytes.
class MemoryBuf : public std::streambuf {
  public:
    explicit MemoryBuf(const MappedFile& m) : file_(m) {
        const std::string_view b = m.bytes();
        char* p = const_cast<char*>(b.data());  // never written: a get area only
        setg(p, p, p + b.size());
    }

  protected:
    std::streamsize xsgetn(char* s, std::streamsize n) override {
        const std::streamsize got = std::streambuf::xsgetn(s, n);
        const auto pos = static_cast<std::size_t>(gptr() - eback());
        if (pos >= released_ + kReleaseBytes) {
            file_.release(released_, pos);
            released_ = pos;
        }
        return got;
    }

    pos_type seekoff(off_type off, std::ios_base::seekdir dir, std::ios_base::openmode) override {
        const off_type base = dir == std::ios_base::beg   ? 0
                              : dir == std::ios_base::cur ? gptr() - eback()
                                                          : egptr() - eback();
        return seekpos(pos_type(base + off), std::ios_base::in);
    }
    pos_type seekpos(pos_type pos, std::ios_base::openmode) override {
        const off_type p = pos;
        if (p < 0 || p > egptr() - eback()) return pos_type(off_type(-1));
        setg(eback(), eback() + p, egptr());
        return pos;
    }

  private:
    static constexpr std::size_t kReleaseBytes = std::size_t{8} << 20U;
    const MappedFile& file_;
    std::size_t released_ = 0;  // pages before this offset were released (a read maps them again)
};

// Marks the mapped file as the one a SIGBUS would come from, for as long as it is read.
class SigbusScope {
  public:
    explicit SigbusScope(const std::string& path) {
        install_sigbus_handler();
        const std::size_t n = std::min(path.size(), sizeof g_mapped_path - 1);
        std::memcpy(g_mapped_path, path.data(), n);
        g_mapped_path[n] = '\0';
        g_mapped_active.store(true);
    }
    ~SigbusScope() { g_mapped_active.store(false); }
    SigbusScope(const SigbusScope&) = delete;
    SigbusScope& operator=(const SigbusScope&) = delete;
};

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

HashedScan read_scan_hashed(const std::string& path, const ReadOptions& options) {
    if (detect_format(path) == FileFormat::kVol) {
        const MappedFile m(path);
        if (m.mapped()) {
            const SigbusScope guard(path);
            HashedScan out;
            // Hashed in chunks, each released once hashed: the file's pages are never all
            // resident together with the pixels read from them (peak memory of an ONH eye).
            const std::string_view bytes = m.bytes();
            constexpr std::size_t kChunk = std::size_t{8} << 20U;
            Sha256 hash;
            for (std::size_t at = 0; at < bytes.size(); at += kChunk) {
                const std::size_t n = std::min(kChunk, bytes.size() - at);
                hash.update(bytes.data() + at, n);
                m.release(at, at + n);
            }
            out.sha256 = hash.hex();
            MemoryBuf buf(m);
            std::istream in(&buf);
            out.scan = read_vol(in, m.bytes().size(), path, options);
            out.scan.source_path = path;
            return out;
        }
    }
    // Not a .vol, or the file system cannot map it: read and hash it the ordinary way.
    HashedScan out;
    out.scan = read_scan(path, options);
    out.sha256 = sha256_file(path);
    return out;
}

}  // namespace octshape::io
