#include "octshape/retina/report_util.h"

#include <cmath>
#include <sstream>

namespace octshape::retina {

nlohmann::ordered_json json_number(double v) {
    return std::isfinite(v) ? nlohmann::ordered_json(v) : nlohmann::ordered_json(nullptr);
}

std::string csv_number(double v) {
    if (!std::isfinite(v)) return "NA";
    std::ostringstream s;
    s.precision(10);
    s << v;
    return s.str();
}

std::string csv_field(const std::string& s) {
    if (s.find_first_of(",\"\n\r") == std::string::npos) return s;
    std::string out = "\"";
    for (const char ch : s) {
        if (ch == '"') out += '"';
        out += ch;
    }
    return out + "\"";
}

std::string csv_line(const std::vector<std::string>& fields) {
    std::string s;
    for (std::size_t i = 0; i < fields.size(); ++i) {
        if (i > 0) s += ',';
        s += csv_field(fields[i]);
    }
    return s + '\n';
}

}  // namespace octshape::retina
