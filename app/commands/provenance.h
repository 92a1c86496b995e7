#pragma once
// Which code made an output, from what and how (docs/outputs.md, "Provenance"; the rule for
// raising the version: docs/versioning.md). One block, built here, in every output: the mesh
// commands' JSON and meshes, the per-eye JSON (macula, onh, cohort records), `info --json`,
// the cohort's tables (OUT/provenance.json) and `stats`.
//
// - `Provenance`: the block {"version", "revision", "modified", "build_type", "command",
//   "inputs": [{"sha256"} (+ "path" with --record-paths)], "options": every effective option
//   (code defaults included), "utc" (when the run started), "seconds" (per stage)}. Files that
//   must be reproducible byte for byte (meshes, tables) carry `json_untimed()`: the same block
//   without "utc" and "seconds". Times never enter a table or a fingerprint, so re-running an
//   analysis gives the same tables byte for byte.
// - `fingerprint(parameters)`: 16 hex digits of SHA-256 of the software identity and the
//   canonical text of every effective parameter (code defaults included). Two results with the
//   same fingerprint were computed by the same code with the same settings.

#include <chrono>
#include <nlohmann/json.hpp>
#include <string>

namespace octshape::app {

// {"version", "revision", "modified", "build_type"}: the first keys of every provenance block.
[[nodiscard]] nlohmann::ordered_json software_json();
// The `octshape --version` text (one line).
[[nodiscard]] std::string version_text();
// "2026-12-02T00:59:03Z".
[[nodiscard]] std::string utc_now_iso();
// SHA-256 over the software identity and `parameters_text`, first 16 hex digits.
[[nodiscard]] std::string fingerprint(const std::string& parameters_text);
// The canonical option text "name k1=v1 k2=v2 ..." (the fingerprint's parameter text) as a
// JSON object {k1: v1, ...}: a value that is a JSON number becomes that number, true/false a
// boolean, any other a string; "group(k=v ... k=v)" becomes {"group": {k: v, ...}}; a word without
// '=' (the analysis's name) is left out.
[[nodiscard]] nlohmann::ordered_json options_from_text(const std::string& text);

// The provenance block of one run (above): the software identity, the command, its inputs by
// SHA-256, its effective options, the run's start time and the seconds of each stage, in order.
class Provenance {
public:
    explicit Provenance(std::string command = "");
    void set_command(std::string command) { command_ = std::move(command); }
    // One input, by the SHA-256 of its bytes; its path only when `path` is given (with
    // --record-paths: identifying). `extra` keys (e.g. {"role": "reference"}) are appended.
    void add_input(const std::string& sha256, const std::string& path = "",
                   const nlohmann::ordered_json& extra = nlohmann::ordered_json::object());
    // Every effective option, code defaults included (an object).
    void set_options(nlohmann::ordered_json options) { options_ = std::move(options); }
    // Ends the current stage (started at construction or at the previous mark) as `stage`.
    void mark(const std::string& stage);
    [[nodiscard]] nlohmann::ordered_json json() const;
    // The same without "utc" and "seconds".
    [[nodiscard]] nlohmann::ordered_json json_untimed() const;

private:
    std::string command_;
    nlohmann::ordered_json inputs_ = nlohmann::ordered_json::array();
    nlohmann::ordered_json options_ = nlohmann::ordered_json::object();
    std::string utc_;
    std::chrono::steady_clock::time_point last_;
    nlohmann::ordered_json seconds_ = nlohmann::ordered_json::object();
};

// In `block` (a Provenance::json()), takes `earlier`'s start time and puts its stages before the
// block's own (a scan read by one unit and analysed by another).
void prepend_stages(nlohmann::ordered_json& block, const Provenance& earlier);

}  // namespace octshape::app
