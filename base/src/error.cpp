#include "octshape/error.h"

#include <utility>

namespace octshape {
namespace {

std::string format_input_message(const std::string& path, const std::string& reason,
                                 std::optional<std::uint64_t> offset) {
    std::string msg = path + ": " + reason;
    if (offset) msg += " (at byte " + std::to_string(*offset) + ")";
    return msg;
}

}  // namespace

InputError::InputError(Kind kind, std::string path, std::string reason,
                       std::optional<std::uint64_t> offset)
    : Error(format_input_message(path, reason, offset)),
      kind_(kind),
      path_(std::move(path)),
      reason_(std::move(reason)),
      offset_(offset) {}

InputError InputError::missing(const std::string& path) {
    return {Kind::kMissing, path, "no such file"};
}
InputError InputError::not_regular(const std::string& path) {
    return {Kind::kNotRegular, path, "not a regular file (a directory or device?)"};
}
InputError InputError::unreadable(const std::string& path, const std::string& why) {
    return {Kind::kUnreadable, path, "cannot read: " + why};
}
InputError InputError::truncated(const std::string& path, const std::string& what,
                                 std::uint64_t offset) {
    return {Kind::kTruncated, path, "file truncated: " + what, offset};
}
InputError InputError::corrupt(const std::string& path, const std::string& what,
                               std::optional<std::uint64_t> offset) {
    return {Kind::kCorrupt, path, "corrupt: " + what, offset};
}
InputError InputError::unsupported(const std::string& path, const std::string& what,
                                   std::optional<std::uint64_t> offset) {
    return {Kind::kUnsupported, path, "unsupported: " + what, offset};
}

ExitCode InputError::exit_code() const {
    switch (kind_) {
        case Kind::kMissing:
        case Kind::kNotRegular:
        case Kind::kUnreadable:
            return ExitCode::kNoInput;
        case Kind::kTruncated:
        case Kind::kCorrupt:
        case Kind::kUnsupported:
            return ExitCode::kDataError;
    }
    return ExitCode::kDataError;
}

OutputError::OutputError(std::string path, const std::string& reason)
    : Error(path + ": cannot write: " + reason), path_(std::move(path)) {}

InternalError::InternalError(const std::string& what) : Error(what) {}
InternalError::InternalError(const char* what) : Error(what) {}

}  // namespace octshape
