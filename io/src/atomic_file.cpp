#include "octshape/io/atomic_file.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>
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

thread_local OutputJournal* g_journal = nullptr;

// Where a write to `path` lands.
struct Target {
    enum class Kind { kStdout, kFile, kSpecial } kind = Kind::kFile;
    fs::path path;  // kFile: the file to replace or create (a link's final target); kSpecial: the node
};

Target resolve_target(const std::string& path) {
    if (path == "-") return {Target::Kind::kStdout, {}};
    fs::path p(path);
    for (int hops = 0;; ++hops) {
        std::error_code ec;
        const fs::file_status st = fs::symlink_status(p, ec);
        if (ec || !fs::exists(st)) return {Target::Kind::kFile, p};  // a new file
        if (fs::is_symlink(st)) {
            if (hops >= 40) throw OutputError(path, "too many levels of symbolic links");
            const fs::path t = fs::read_symlink(p, ec);
            if (ec) throw OutputError(path, "cannot read the symbolic link: " + ec.message());
            p = t.is_absolute() ? t : p.parent_path() / t;
            continue;
        }
        if (fs::is_directory(st)) throw OutputError(path, "is a directory");
        if (fs::is_regular_file(st)) return {Target::Kind::kFile, p};
        return {Target::Kind::kSpecial, p};  // character/block device, FIFO, socket
    }
}

void write_all(int fd, std::string_view data, const std::string& dest) {
    while (!data.empty()) {
        const ssize_t n = ::write(fd, data.data(), data.size());
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0) throw OutputError(dest, std::string("write failed: ") + std::strerror(errno));
        data.remove_prefix(static_cast<std::size_t>(n));
    }
}

// Writes complete content into stdout or a device/FIFO (opened for writing, never created,
// truncated or replaced).
void write_into(const Target& t, std::string_view data, const std::string& dest) {
    if (t.kind == Target::Kind::kStdout) {
        std::cout.flush();
        write_all(STDOUT_FILENO, data, dest);
        return;
    }
    const int fd = ::open(t.path.c_str(), O_WRONLY | O_CLOEXEC | O_NOCTTY);
    if (fd < 0) throw OutputError(dest, std::string("cannot open: ") + std::strerror(errno));
    try {
        write_all(fd, data, dest);
    } catch (...) {
        ::close(fd);
        throw;
    }
    if (::close(fd) != 0) throw OutputError(dest, std::string("close failed: ") + std::strerror(errno));
}

std::string read_whole(const fs::path& p, const std::string& dest) {
    std::ifstream in(p, std::ios::binary);
    std::ostringstream ss;
    ss << in.rdbuf();
    if (!in && !in.eof()) throw OutputError(dest, "cannot read back the written file");
    return ss.str();
}

}  // namespace

OutputJournal::OutputJournal() : outer_(g_journal) { g_journal = this; }

OutputJournal::~OutputJournal() {
    g_journal = outer_;
    if (committed_) {
        if (outer_ != nullptr) {
            for (auto& f : files_) outer_->published(f);
        }
        return;
    }
    for (const auto& f : files_) {
        std::error_code ec;
        fs::remove(f, ec);
    }
}

void check_output_location(const std::string& path) {
    const Target t = resolve_target(path);
    if (t.kind == Target::Kind::kStdout) return;
    if (t.kind == Target::Kind::kSpecial) {
        if (::access(t.path.c_str(), W_OK) != 0) {
            throw OutputError(path, std::string("not writable: ") + std::strerror(errno));
        }
        return;
    }
    if (t.path.filename().empty()) throw OutputError(path, "not a file name");
    fs::path dir = t.path.parent_path();
    if (dir.empty()) dir = ".";
    std::error_code ec;
    if (!fs::is_directory(dir, ec)) throw OutputError(path, "directory does not exist");
    // A new or replaced file is a rename in its directory.
    if (::access(dir.c_str(), W_OK | X_OK) != 0) {
        throw OutputError(path, std::string("directory not writable: ") + std::strerror(errno));
    }
}

void check_output_directory(const std::string& dir) {
    std::error_code ec;
    // fs::absolute throws (a standard exception, exit 70) when the working folder is gone.
    fs::path p = fs::absolute(fs::path(dir), ec).lexically_normal();
    if (ec) throw OutputError(dir, "cannot resolve the path: " + ec.message());
    if (fs::exists(p, ec) && !fs::is_directory(p, ec)) throw OutputError(dir, "not a directory");
    while (!fs::exists(p, ec) && p.has_parent_path() && p.parent_path() != p) p = p.parent_path();
    if (!fs::is_directory(p, ec)) throw OutputError(dir, "no existing folder to create it in");
    if (::access(p.c_str(), W_OK | X_OK) != 0) {
        throw OutputError(dir, std::string("not writable: ") + std::strerror(errno));
    }
}

void write_path_atomically(const std::string& path,
                           const std::function<void(const std::string& tmp)>& write,
                           const AtomicWriteOptions& options) {
    const Target target = resolve_target(path);
    if (target.kind != Target::Kind::kFile) {
        // The writer needs a file: a private temporary one, then its bytes in one go.
        std::error_code tec;  // a TMPDIR that is not a folder: an OutputError, not exit 70
        const fs::path tmp_dir = fs::temp_directory_path(tec);
        if (tec) throw OutputError(path, "no folder for temporary files: " + tec.message());
        std::random_device rd;
        const fs::path tmp = tmp_dir / (".octshape-out.tmp-" + std::to_string(::getpid()) + "-" +
                                        std::to_string(rd()) +
                                        fs::path(path).extension().string());
        TempGuard guard(tmp);
        write(tmp.string());
        write_into(target, read_whole(tmp, path), path);
        return;
    }
    const fs::path dest = target.path;  // a symbolic link's final target: the link stays
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
    if (g_journal != nullptr) g_journal->published(dest.string());
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
    const Target target = resolve_target(path);
    if (target.kind != Target::Kind::kFile) {
        // Complete in memory first: a writer that throws leaves the stream or device untouched.
        std::ostringstream buf(std::ios::binary);
        write(buf);
        if (!buf) throw OutputError(path, "write failed");
        write_into(target, buf.str(), path);
        return;
    }
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
