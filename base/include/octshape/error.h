#pragma once
// Error types of octshape and the exit codes they map to.
//
// Libraries throw; they never exit and never log-and-throw. `app/main.cpp` catches by type and
// returns `exit_code()`. Exit codes follow BSD sysexits where one fits (documented in README.md
// and `octshape --help`).

#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>

namespace octshape {

// Documented process exit codes. Keep README.md "Exit codes" in step with this list.
enum class ExitCode : int {
    kOk = 0,
    kPartial = 1,          // a batch finished but some inputs failed (each one recorded)
    kUsage = 64,           // EX_USAGE: bad command line or option value
    kDataError = 65,       // EX_DATAERR: input corrupt, truncated, hostile or unsupported
    kNoInput = 66,         // EX_NOINPUT: input missing, not a regular file, or unreadable
    kAnalysisFailed = 69,  // the input was read but this analysis cannot be done on it
    kInternal = 70,        // EX_SOFTWARE: a bug in octshape (please report)
    kCantCreate = 73,      // EX_CANTCREAT: an output cannot be written
};

// Base of every error octshape throws on purpose.
class Error : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
    [[nodiscard]] virtual ExitCode exit_code() const { return ExitCode::kInternal; }
};

// A problem with an input file: names the file, what is wrong and, where known, the byte offset.
// what() is the one-line message shown to the user: "PATH: REASON (at byte N)".
class InputError : public Error {
public:
    enum class Kind {
        kMissing,      // does not exist
        kNotRegular,   // a directory, device, ...
        kUnreadable,   // permission or I/O error
        kTruncated,    // ends before a structure the header promises
        kCorrupt,      // contradictory or impossible values
        kUnsupported,  // a valid file of a kind/version octshape does not read
    };

    InputError(Kind kind, std::string path, std::string reason,
               std::optional<std::uint64_t> offset = std::nullopt);

    static InputError missing(const std::string& path);
    static InputError not_regular(const std::string& path);
    static InputError unreadable(const std::string& path, const std::string& why);
    static InputError truncated(const std::string& path, const std::string& what,
                                std::uint64_t offset);
    static InputError corrupt(const std::string& path, const std::string& what,
                              std::optional<std::uint64_t> offset = std::nullopt);
    static InputError unsupported(const std::string& path, const std::string& what,
                                  std::optional<std::uint64_t> offset = std::nullopt);

    [[nodiscard]] Kind kind() const { return kind_; }
    [[nodiscard]] const std::string& path() const { return path_; }
    [[nodiscard]] const std::string& reason() const { return reason_; }
    [[nodiscard]] std::optional<std::uint64_t> offset() const { return offset_; }
    [[nodiscard]] ExitCode exit_code() const override;

private:
    Kind kind_;
    std::string path_;
    std::string reason_;
    std::optional<std::uint64_t> offset_;
};

// An output file or directory cannot be created or written.
class OutputError : public Error {
public:
    OutputError(std::string path, const std::string& reason);
    [[nodiscard]] const std::string& path() const { return path_; }
    [[nodiscard]] ExitCode exit_code() const override { return ExitCode::kCantCreate; }

private:
    std::string path_;
};

// The input was read, but the requested analysis cannot be carried out on it (wrong scan
// pattern, segmentation missing where it is needed, ...).
class AnalysisError : public Error {
public:
    using Error::Error;
    [[nodiscard]] ExitCode exit_code() const override { return ExitCode::kAnalysisFailed; }
};

// Values handed to a library function are impossible (a non-finite coordinate, a face index out
// of range, a mesh without faces): the data, not the code, is wrong. The library does not know
// which file the data came from; a caller that does rethrows it as InputError naming the file.
class DataError : public Error {
public:
    using Error::Error;
    [[nodiscard]] ExitCode exit_code() const override { return ExitCode::kDataError; }
};

// A bad option value or combination that the command-line parser could not catch itself, and a
// library's parameter struct with a field out of its range (the message names the field).
class UsageError : public Error {
public:
    using Error::Error;
    [[nodiscard]] ExitCode exit_code() const override { return ExitCode::kUsage; }
};

// A broken invariant of octshape itself, or a library octshape relies on failing for a reason no
// input can cause (libcrypto or zlib without memory): exit 70, "please report". Each throw site
// says in one line beside it why no input can reach it.
class InternalError : public Error {
public:
    // Out of line: a cold path, kept from the caller's inlining.
    explicit InternalError(const std::string& what);
    explicit InternalError(const char* what);
    [[nodiscard]] ExitCode exit_code() const override { return ExitCode::kInternal; }
};

}  // namespace octshape
