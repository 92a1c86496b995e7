#pragma once
// Atomic output: a result file either appears complete or not at all.
//
// The content is written to a temporary file in the destination's directory, flushed and
// fsync'ed, then renamed over the destination (rename within one file system is atomic on
// POSIX). If writing fails or the writer throws, the temporary file is removed and the
// destination is left untouched.

#include <functional>
#include <iosfwd>
#include <string>
#include <string_view>

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

// Convenience for text already in memory.
void write_text_atomically(const std::string& path,
                           std::string_view text,
                           const AtomicWriteOptions& options = {});

}  // namespace octshape::io
