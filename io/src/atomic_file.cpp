#include "octshape/io/atomic_file.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>

#include "octshape/error.h"

namespace octshape::io {
namespace {

namespace fs = std::filesystem;

// Removes the temporary file unless released (RAII, so a throwing writer cleans up).
class TempGuard {
public:
    explicit TempGuard(fs::path p) : path_(std::move(p)) {}
    ~TempGuard() {
        if (!path_.empty()) {
            std::error_code ec;
            fs::remove(path_, ec);
        }
    }
    TempGuard(const TempGuard&) = delete;
    TempGuard& operator=(const TempGuard&) = delete;
    void release() { path_.clear(); }

private:
    fs::path path_;
};

void fsync_path(const fs::path& p, const std::string& dest) {
    const int fd = ::open(p.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) throw OutputError(dest, std::strerror(errno));
    const int rc = ::fsync(fd);
    const int err = errno;
    ::close(fd);
    if (rc != 0) throw OutputError(dest, std::strerror(err));
}

}  // namespace

void write_path_atomically(const std::string& path,
                           const std::function<void(const std::string& tmp)>& write,
                           const AtomicWriteOptions& options) {
    const fs::path dest(path);
    if (dest.filename().empty()) throw OutputError(path, "not a file name");
    fs::path dir = dest.parent_path();
    if (dir.empty()) dir = ".";
    std::error_code ec;
    if (!fs::is_directory(dir, ec)) throw OutputError(path, "directory does not exist");
    if (fs::is_directory(dest, ec)) throw OutputError(path, "is a directory");

    // Hidden, unique temporary name in the same directory (same file system => atomic rename);
    // it keeps the destination's extension, which some writers look at.
    std::random_device rd;
    // (Built with append: GCC 12 -O3 emits a false -Wrestrict on chained operator+.)
    std::string tmp_name(".");
    tmp_name.append(dest.stem().string())
        .append(".tmp-")
        .append(std::to_string(::getpid()))
        .append("-")
        .append(std::to_string(rd()))
        .append(dest.extension().string());
    const fs::path tmp = dir / tmp_name;
    TempGuard guard(tmp);
    write(tmp.string());
    if (!fs::is_regular_file(tmp, ec)) throw OutputError(path, "the writer produced no file");
    if (options.durable) fsync_path(tmp, path);
    if (::rename(tmp.c_str(), dest.c_str()) != 0) {
        throw OutputError(path, std::string("rename failed: ") + std::strerror(errno));
    }
    guard.release();
    if (!options.durable) return;
    // Make the rename itself durable.
    const int dfd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (dfd >= 0) {
        ::fsync(dfd);
        ::close(dfd);
    }
}

void write_file_atomically(const std::string& path,
                           const std::function<void(std::ostream&)>& write,
                           const AtomicWriteOptions& options) {
    write_path_atomically(
        path,
        [&](const std::string& tmp) {
            std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
            if (!out) {
                throw OutputError(path, std::string("cannot create: ") + std::strerror(errno));
            }
            write(out);
            out.flush();
            if (!out) throw OutputError(path, "write failed (disk full?)");
            out.close();
            if (out.fail()) throw OutputError(path, "close failed");
        },
        options);
}

void write_text_atomically(const std::string& path,
                           std::string_view text,
                           const AtomicWriteOptions& options) {
    const auto put = [&](std::ostream& out) {
        out.write(text.data(), static_cast<std::streamsize>(text.size()));
    };
    write_file_atomically(path, put, options);
}

}  // namespace octshape::io
