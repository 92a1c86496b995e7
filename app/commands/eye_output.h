#pragma once
// What every per-eye command (macula, onh) writes around its own results: the JSON preamble
// (command, provenance, input SHA-256, scan summary without identifiers), the leading CSV
// columns, and the atomic publication of the JSON and CSV files (or the JSON on stdout).

#include <nlohmann/json.hpp>
#include <string>
#include <utility>
#include <vector>

#include "octshape/error.h"

#include "octshape/io/scan.h"

namespace octshape::app {

// {"command", "provenance": {} (filled by the caller at the end: commands/provenance.h), "input": {"sha256"}, "scan": summary without identifiers and without
// the file's path}. `record_paths` (`--record-paths`, identifying): "input" and "scan" also
// hold the input's path.
[[nodiscard]] nlohmann::ordered_json eye_json_preamble(const std::string& command,
                                                       const std::string& file,
                                                       const std::string& sha256,
                                                       const io::Scan& scan,
                                                       bool record_paths);

// The provenance options of a per-eye result (commands/provenance.h): every effective parameter
// (`options_text`, the fingerprint's text, as options_from_text reads it), and whether QC
// pictures were drawn and paths recorded (choices of output that change no number).
[[nodiscard]] nlohmann::ordered_json eye_provenance_options(const std::string& options_text,
                                                            const std::string& qc_dir,
                                                            bool record_paths);

// Leading CSV columns of every per-eye row: eye_key, sha256, eye, scan_pattern, num_bscans;
// with `record_paths` the input's path comes first in a column `file`.
[[nodiscard]] std::vector<std::string> eye_csv_header(bool record_paths);
[[nodiscard]] std::vector<std::string> eye_csv_values(const std::string& file,
                                                      const std::string& sha256,
                                                      const io::Scan& scan,
                                                      bool record_paths);

// The stem of the QC pictures and meshes of a single-eye command: the -o file's stem, else
// the --csv file's, else "eye"; never the input's name (which may be the patient's).
[[nodiscard]] std::string output_stem(const std::string& json_out, const std::string& csv_out);

// Checks every output location of a single-eye command before the analysis starts (io::
// check_output_location / check_output_directory; empty = not asked for): throws OutputError,
// or UsageError when -o and --csv both go to stdout ("-").
void check_eye_outputs(const std::string& json_out, const std::string& csv_out,
                       const std::string& qc_dir, const std::string& mesh_dir);

// Writes the CSV (header line + one row) and then the JSON, each atomically ("-": stdout); with
// neither path given, prints the JSON on stdout. Throws OutputError.
void publish_eye_outputs(const std::string& json_out,
                         const std::string& csv_out,
                         const nlohmann::ordered_json& j,
                         const std::vector<std::string>& csv_header,
                         const std::vector<std::string>& csv_values);

// "FILE: MESSAGE", unless the message already starts with the file's name.
[[nodiscard]] std::string naming_file(const std::string& file, const std::string& message);

// Runs `f`; an AnalysisError or DataError out of it (the analyses do not know the file) is
// rethrown as the same kind with the file's name in front, so that every message names it.
template <class F>
decltype(auto) with_file_named(const std::string& file, F&& f) {
    try {
        return std::forward<F>(f)();
    } catch (const AnalysisError& e) {
        throw AnalysisError(naming_file(file, e.what()));
    } catch (const DataError& e) {
        throw DataError(naming_file(file, e.what()));
    }
}

}  // namespace octshape::app
