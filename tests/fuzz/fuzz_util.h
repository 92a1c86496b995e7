#pragma once
// What the fuzz targets share: a failed check traps (libFuzzer reports it with the input), and
// two floats are the same value bit for bit (NaN = missing equals NaN).

#include <bit>
#include <cmath>
#include <cstdint>

namespace octshape::fuzz {

inline void check(bool ok) {
    if (!ok) __builtin_trap();
}

inline bool same(float a, float b) {
    return (std::isnan(a) && std::isnan(b)) ||
           std::bit_cast<std::uint32_t>(a) == std::bit_cast<std::uint32_t>(b);
}

}  // namespace octshape::fuzz
