#pragma once
// Which code made an output, and when (docs/outputs.md, "Provenance"; the rule for raising the
// version: docs/versioning.md).
//
// - `software_json()`: version, source revision (and whether the tree was modified), build type.
// - `Provenance`: that, plus the UTC time the run started and the seconds of each stage; every
//   JSON written by a command carries it under "provenance". Times never enter a table or a
//   fingerprint, so re-running an analysis gives the same tables byte for byte.
// - `fingerprint(parameters)`: 16 hex digits of SHA-256 of the software identity and the
//   canonical text of every effective parameter (code defaults included). Two results with the
//   same fingerprint were computed by the same code with the same settings.

#include <chrono>
#include <nlohmann/json.hpp>
#include <string>

namespace octshape::app {

// {"version", "revision", "modified", "build_type"}.
[[nodiscard]] nlohmann::ordered_json software_json();
// The `octshape --version` text (one line).
[[nodiscard]] std::string version_text();
// "2026-12-02T00:59:03Z".
[[nodiscard]] std::string utc_now_iso();
// SHA-256 over the software identity and `parameters_text`, first 16 hex digits.
[[nodiscard]] std::string fingerprint(const std::string& parameters_text);

// The software identity, the run's start time and the seconds of each stage, in order.
class Provenance {
public:
    Provenance();
    // Ends the current stage (started at construction or at the previous mark) as `stage`.
    void mark(const std::string& stage);
    [[nodiscard]] nlohmann::ordered_json json() const;

private:
    std::string utc_;
    std::chrono::steady_clock::time_point last_;
    nlohmann::ordered_json seconds_ = nlohmann::ordered_json::object();
};

}  // namespace octshape::app
