#include "commands/provenance.h"

#include <ctime>

#include "build_info.h"
#include "octshape/io/sha256.h"
#include "octshape/version.h"

namespace octshape::app {

nlohmann::ordered_json software_json() {
    const BuildInfo& b = build_info();
    return {{"version", kVersion},
            {"revision", b.revision},
            {"modified", b.modified},
            {"build_type", b.build_type}};
}

std::string version_text() {
    const BuildInfo& b = build_info();
    std::string s = std::string("octshape ") + kVersion + " (revision " + b.revision;
    if (std::string(b.modified) == "yes") s += ", modified";
    if (std::string(b.modified) == "unknown") s += ", modified: unknown";
    s += "; " + std::string(b.describe) + "; build " + b.build_type + ")";
    return s;
}

std::string utc_now_iso() {
    const std::time_t t = std::time(nullptr);
    std::tm tm{};
    ::gmtime_r(&t, &tm);
    char buf[32];
    std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
    return buf;
}

std::string fingerprint(const std::string& parameters_text) {
    const BuildInfo& b = build_info();
    const std::string identity = std::string("octshape ") + kVersion + "\nrevision " + b.revision +
                                 "\nmodified " + b.modified + "\nbuild " + b.build_type + "\n";
    return io::sha256_hex(identity + parameters_text).substr(0, 16);
}

Provenance::Provenance() : utc_(utc_now_iso()), last_(std::chrono::steady_clock::now()) {}

void Provenance::mark(const std::string& stage) {
    const auto now = std::chrono::steady_clock::now();
    // Milliseconds are enough for a stage time and keep the JSON short.
    const double s = std::chrono::duration<double>(now - last_).count();
    seconds_[stage] = static_cast<double>(static_cast<long long>(s * 1000.0 + 0.5)) / 1000.0;
    last_ = now;
}

nlohmann::ordered_json Provenance::json() const {
    nlohmann::ordered_json j = software_json();
    j["utc"] = utc_;
    j["seconds"] = seconds_;
    return j;
}

}  // namespace octshape::app
