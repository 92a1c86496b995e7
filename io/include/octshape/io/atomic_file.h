#pragma once
// Atomic output: a result file either appears complete or not at all.
//
// The content is written to a temporary file in the destination's directory, flushed and
// fsync'ed, then renamed over the destination (rename within one file system is atomic on
// POSIX). If writing fails or the writer throws, the temporary file is removed and the
// destination is left untouched.
//
// Output paths as Unix users use them (docs/outputs.md, "Output paths"):
// - "-" is standard output;
// - a device node, FIFO or socket is written into (opened for writing), never replaced;
// - a symbolic link is written through: its final target is replaced atomically, the link
//   stays;
// - anything else (an existing regular file or a new name) is replaced atomically as above.
// For the targets that are not regular files the content is first made complete (in memory or
// in a temporary file), then written in one go.

#include <functional>
#include <iosfwd>
#include <string>
#include <string_view>
#include <vector>

namespace octshape::io {

struct AtomicWriteOptions {
    // true: fsync the file before the rename and the directory after it, so the result also
    // survives a power loss. false: the file is still complete-or-absent for any *process*
    // crash (SIGKILL included: the kernel keeps the written pages), but an OS crash may lose it
    // or leave it empty; for callers that validate what they read back and sync once at the end
    // (`octshape cohort`, docs/cohort.md).
    bool durable = true;
};

// Calls `write(out)` on a temporary stream and publishes the result at `path`.
// Throws OutputError (path + reason) if the directory is not writable, the disk is full, etc.
// Exceptions thrown by `write` propagate unchanged after the temporary file is removed.
void write_file_atomically(const std::string& path,
                           const std::function<void(std::ostream&)>& write,
                           const AtomicWriteOptions& options = {});

// The same for writers that need a file name rather than a stream (VTK's writers): `write(tmp)`
// must create the file `tmp`, which is then fsync'ed and renamed to `path`.
void write_path_atomically(const std::string& path,
                           const std::function<void(const std::string& tmp)>& write,
                           const AtomicWriteOptions& options = {});

// Throws OutputError when `path` cannot be written as above (a directory; no such directory;
// a directory or device not writable by this user): commands call it for every output
// before the analysis starts, so a run never fails at its end for a bad output location.
void check_output_location(const std::string& path);
// The same for an output folder (created if missing): it, or its nearest existing ancestor,
// must be a writable directory.
void check_output_directory(const std::string& dir);

// While one is alive (on this thread), every regular file published by the functions here is
// recorded; destroyed without commit() (a failed run: an exception unwinds the command), it
// removes them, so a failed run leaves none of its outputs behind. Writes into devices, FIFOs
// and stdout cannot be taken back and are not recorded.
class OutputJournal {
public:
    OutputJournal();
    ~OutputJournal();
    OutputJournal(const OutputJournal&) = delete;
    OutputJournal& operator=(const OutputJournal&) = delete;
    void commit() { committed_ = true; }
    void published(const std::string& path) { files_.push_back(path); }

private:
    OutputJournal* outer_ = nullptr;
    bool committed_ = false;
    std::vector<std::string> files_;
};

// Convenience for text already in memory.
void write_text_atomically(const std::string& path,
                           std::string_view text,
                           const AtomicWriteOptions& options = {});

}  // namespace octshape::io
