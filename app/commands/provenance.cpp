#include "commands/provenance.h"

#include <ctime>
#include <sstream>

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
    // `git describe` adds something only after a tag (e.g. "v0.2.0-3-g1234"): without one it
    // is the revision again, said once.
    const std::string describe = b.describe;
    if (describe != b.revision && describe != "unknown") s += "; " + describe;
    s += "; build " + std::string(b.build_type) + ")";
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

nlohmann::ordered_json options_from_text(const std::string& text) {
    nlohmann::ordered_json o = nlohmann::ordered_json::object();
    std::istringstream in(text);
    std::string token;
    std::string group;  // inside "group(k1=v1 ... kn=vn)"
    while (in >> token) {
        const auto eq = token.find('=');
        if (eq == std::string::npos) continue;
        std::string key = token.substr(0, eq);
        std::string value = token.substr(eq + 1);
        if (const auto open = key.find('('); open != std::string::npos) {
            group = key.substr(0, open);
            key = key.substr(open + 1);
        }
        const bool closes = !group.empty() && value.ends_with(")");
        if (closes) value.pop_back();
        // Numbers and the switches (true/false) as JSON numbers and booleans, the rest as text.
        const auto parsed = nlohmann::ordered_json::parse(value, nullptr, false);
        nlohmann::ordered_json& into = group.empty() ? o : o[group];
        into[key] =
            parsed.is_number() || parsed.is_boolean() ? parsed : nlohmann::ordered_json(value);
        if (closes) group.clear();
    }
    return o;
}

Provenance::Provenance(std::string command)
    : command_(std::move(command)), utc_(utc_now_iso()), last_(std::chrono::steady_clock::now()) {}

void Provenance::add_input(const std::string& sha256, const std::string& path,
                           const nlohmann::ordered_json& extra) {
    nlohmann::ordered_json e = {{"sha256", sha256}};
    if (!path.empty()) e["path"] = path;
    for (const auto& [k, v] : extra.items()) e[k] = v;
    inputs_.push_back(std::move(e));
}

void Provenance::mark(const std::string& stage) {
    const auto now = std::chrono::steady_clock::now();
    // Milliseconds are enough for a stage time and keep the JSON short.
    const double s = std::chrono::duration<double>(now - last_).count();
    seconds_[stage] = static_cast<double>(static_cast<long long>(s * 1000.0 + 0.5)) / 1000.0;
    last_ = now;
}

void prepend_stages(nlohmann::ordered_json& block, const Provenance& earlier) {
    const nlohmann::ordered_json e = earlier.json();
    nlohmann::ordered_json seconds = e["seconds"];
    for (const auto& [k, v] : block["seconds"].items()) seconds[k] = v;
    block["utc"] = e["utc"];
    block["seconds"] = std::move(seconds);
}

nlohmann::ordered_json Provenance::json_untimed() const {
    nlohmann::ordered_json j = software_json();
    j["command"] = command_;
    j["inputs"] = inputs_;
    j["options"] = options_;
    return j;
}

nlohmann::ordered_json Provenance::json() const {
    nlohmann::ordered_json j = json_untimed();
    j["utc"] = utc_;
    j["seconds"] = seconds_;
    return j;
}

}  // namespace octshape::app
