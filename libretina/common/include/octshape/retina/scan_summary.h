#pragma once
// What an export holds, as JSON: the `info` command prints it, and every per-eye result embeds
// it (without identifiers) so a number can be traced to the scan it came from.

#include <nlohmann/json.hpp>

#include "octshape/io/scan.h"

namespace octshape::retina {

struct SummaryOptions {
    // Identifiers, date of birth and exam/visit dates are private: off unless the user asks.
    bool identifiers = false;
};

// Keys carry units (`_mm`, `_deg`, `_percent`). Missing values are JSON null, never numbers.
[[nodiscard]] nlohmann::json scan_summary(const io::Scan& scan,
                                          const SummaryOptions& options = {});

}  // namespace octshape::retina
