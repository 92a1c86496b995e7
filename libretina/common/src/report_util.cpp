#include "octshape/retina/report_util.h"

#include <cmath>

namespace octshape::retina {

nlohmann::ordered_json json_number(double v) {
    return std::isfinite(v) ? nlohmann::ordered_json(v) : nlohmann::ordered_json(nullptr);
}

}  // namespace octshape::retina
