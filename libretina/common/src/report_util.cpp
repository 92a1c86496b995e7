#include "octshape/retina/report_util.h"

#include <cmath>
#include <cstdio>

namespace octshape::retina {

nlohmann::ordered_json json_number(double v) {
    return std::isfinite(v) ? nlohmann::ordered_json(v) : nlohmann::ordered_json(nullptr);
}

std::string fixed_number(double v, int digits) {
    char b[64];
    std::snprintf(b, sizeof b, "%.*f", digits, v);
    return b;
}

void put_shifts(nlohmann::ordered_json& j, const std::vector<double>& shift_um,
                const std::vector<bool>& estimated) {
    nlohmann::ordered_json shifts = nlohmann::ordered_json::array();
    nlohmann::ordered_json est = nlohmann::ordered_json::array();
    for (std::size_t b = 0; b < shift_um.size(); ++b) {
        shifts.push_back(shift_um[b]);
        est.push_back(b < estimated.size() && estimated[b]);
    }
    j["shift_um"] = std::move(shifts);
    j["estimated"] = std::move(est);
}

}  // namespace octshape::retina
