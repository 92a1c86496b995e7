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

// Calls `write(out)` on a temporary stream and publishes the result at `path`.
// Throws OutputError (path + reason) if the directory is not writable, the disk is full, etc.
// Exceptions thrown by `write` propagate unchanged after the temporary file is removed.
void write_file_atomically(const std::string& path,
                           const std::function<void(std::ostream&)>& write);

// The same for writers that need a file name rather than a stream (VTK's writers): `write(tmp)`
// must create the file `tmp`, which is then fsync'ed and renamed to `path`.
void write_path_atomically(const std::string& path,
                           const std::function<void(const std::string& tmp)>& write);

// Convenience for text already in memory.
void write_text_atomically(const std::string& path, std::string_view text);

}  // namespace octshape::io
