#include "octshape/io/scan.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>

namespace octshape::io {
namespace {

constexpr std::array<std::string_view, kNumKnownLayers> kLayerNames = {
    "ILM", "BM", "RNFL", "GCL", "IPL", "INL", "OPL", "ONL", "ELM",
    "IOS", "OPT", "CHO", "VIT", "ANT", "PR1", "PR2", "RPE"};

bool iequals(std::string_view a, std::string_view b) {
    return a.size() == b.size() &&
           std::equal(a.begin(), a.end(), b.begin(), [](char x, char y) {
               return std::toupper(static_cast<unsigned char>(x)) ==
                      std::toupper(static_cast<unsigned char>(y));
           });
}

// Proleptic Gregorian date from days since 1970-01-01 (H. Hinnant's civil_from_days).
void civil_from_days(long long z, int& y, unsigned& m, unsigned& d) {
    z += 719468;
    const long long era = (z >= 0 ? z : z - 146096) / 146097;
    const auto doe = static_cast<unsigned>(z - era * 146097);
    const unsigned yoe = (doe - doe / 1460 + doe / 36524 - doe / 146096) / 365;
    const unsigned doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    const unsigned mp = (5 * doy + 2) / 153;
    d = doy - (153 * mp + 2) / 5 + 1;
    m = mp < 10 ? mp + 3 : mp - 9;
    y = static_cast<int>(static_cast<long long>(yoe) + era * 400 + (m <= 2 ? 1 : 0));
}

}  // namespace

// Days since 1970-01-01 of a proleptic Gregorian date (H. Hinnant's days_from_civil).
long long days_from_civil(long long y, unsigned m, unsigned d) {
    y -= m <= 2 ? 1 : 0;
    const long long era = (y >= 0 ? y : y - 399) / 400;
    const auto yoe = static_cast<unsigned>(y - era * 400);
    const unsigned doy = (153 * (m > 2 ? m - 3 : m + 9) + 2) / 5 + d - 1;
    const unsigned doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    return era * 146097 + static_cast<long long>(doe) - 719468;
}

std::string layer_name(int index) {
    if (index >= 0 && index < kNumKnownLayers) return std::string(kLayerNames[index]);
    return "LINE" + std::to_string(index);
}

std::optional<int> layer_from_name(std::string_view name) {
    for (int k = 0; k < kNumKnownLayers; ++k) {
        if (iequals(name, kLayerNames[k])) return k;
    }
    if (iequals(name, "EZ")) return static_cast<int>(Layer::kPR1);
    if (iequals(name, "IZ")) return static_cast<int>(Layer::kPR2);
    return std::nullopt;
}

std::string_view to_string(Laterality l) {
    switch (l) {
        case Laterality::kOD: return "OD";
        case Laterality::kOS: return "OS";
        case Laterality::kUnknown: break;
    }
    return "unknown";
}

std::string_view to_string(ScanPattern p) {
    switch (p) {
        case ScanPattern::kLine: return "line";
        case ScanPattern::kCircle: return "circle";
        case ScanPattern::kVolume: return "volume";
        case ScanPattern::kFastVolume: return "fast volume";
        case ScanPattern::kRadial: return "radial";
        case ScanPattern::kRadialCircles: return "radial + circles";
        case ScanPattern::kUnknown: break;
    }
    return "unknown";
}

std::string_view to_string(SourceFormat f) {
    switch (f) {
        case SourceFormat::kVol: return "Heidelberg .vol";
        case SourceFormat::kHeyexXml: return "Heidelberg XML";
        case SourceFormat::kIowaSurfaces: return "Iowa surfaces XML";
        case SourceFormat::kTopcon: return "Topcon .fda/.fds";
    }
    return "unknown";
}

ScanPattern scan_pattern_from_code(std::int32_t code) {
    if (code < 0 || code > 6) return ScanPattern::kUnknown;
    return static_cast<ScanPattern>(code);
}

int Scan::num_lines() const {
    if (bscans.empty()) return 0;
    int n = bscans.front().num_seg();
    for (const BScan& b : bscans) n = std::min(n, b.num_seg());
    return n;
}

double Scan::valid_fraction(int k) const {
    std::size_t total = 0;
    std::size_t valid = 0;
    for (const BScan& b : bscans) {
        if (!b.has_line(k)) {
            total += static_cast<std::size_t>(meta.size_x);
            continue;
        }
        total += b.seg[static_cast<std::size_t>(k)].size();
        for (float v : b.seg[static_cast<std::size_t>(k)]) valid += is_valid(v) ? 1U : 0U;
    }
    return total == 0 ? 0.0 : static_cast<double>(valid) / static_cast<double>(total);
}

float Scan::depth_px(int k, int b, int a) const {
    if (b < 0 || b >= num_bscans()) return std::numeric_limits<float>::quiet_NaN();
    const BScan& bs = bscans[static_cast<std::size_t>(b)];
    if (!bs.has_line(k)) return std::numeric_limits<float>::quiet_NaN();
    const auto& line = bs.seg[static_cast<std::size_t>(k)];
    if (a < 0 || static_cast<std::size_t>(a) >= line.size()) {
        return std::numeric_limits<float>::quiet_NaN();
    }
    return line[static_cast<std::size_t>(a)];
}

std::string Scan::line_name(int k) const {
    if (k >= 0 && static_cast<std::size_t>(k) < line_names.size()) {
        return line_names[static_cast<std::size_t>(k)];
    }
    return layer_name(k);
}

std::optional<int> Scan::find_line(std::string_view name) const {
    for (std::size_t k = 0; k < line_names.size(); ++k) {
        if (iequals(name, line_names[k])) return static_cast<int>(k);
    }
    if (!line_names.empty()) return std::nullopt;  // the Heidelberg indices do not apply
    return layer_from_name(name);
}

std::string filetime_to_iso(std::uint64_t filetime) {
    // FILETIME counts 100 ns ticks since 1601-01-01; 11644473600 s separate it from 1970.
    const long long secs = static_cast<long long>(filetime / 10000000ULL) - 11644473600LL;
    long long days = secs / 86400;
    long long rem = secs % 86400;
    if (rem < 0) {
        rem += 86400;
        days -= 1;
    }
    int y = 0;
    unsigned m = 0;
    unsigned d = 0;
    civil_from_days(days, y, m, d);
    char buf[40];
    std::snprintf(buf, sizeof buf, "%04d-%02u-%02uT%02lld:%02lld:%02lldZ", y, m, d, rem / 3600,
                  (rem / 60) % 60, rem % 60);
    return buf;
}

std::string ole_date_to_iso_date(double ole_days) {
    if (!std::isfinite(ole_days) || std::fabs(ole_days) > 3.0e6) return "invalid";
    // OLE automation dates count days since 1899-12-30; 25569 days separate it from 1970.
    const auto days = static_cast<long long>(std::floor(ole_days)) - 25569LL;
    int y = 0;
    unsigned m = 0;
    unsigned d = 0;
    civil_from_days(days, y, m, d);
    char buf[24];
    std::snprintf(buf, sizeof buf, "%04d-%02u-%02u", y, m, d);
    return buf;
}

}  // namespace octshape::io

namespace octshape::io {

namespace {

// out[i] = in(i - shift) by linear interpolation, indices clamped to [0, n - 1] (edges repeated).
template <typename Get, typename Put>
void shift_samples(int n, double shift, Get&& get, Put&& put) {
    const double last = static_cast<double>(n - 1);
    for (int i = 0; i < n; ++i) {
        const double src = std::clamp(static_cast<double>(i) - shift, 0.0, last);
        const auto i0 = static_cast<int>(std::floor(src));
        const int i1 = std::min(i0 + 1, n - 1);
        const double f = src - i0;
        put(i, (1.0 - f) * get(i0) + f * get(i1));
    }
}

}  // namespace

void shift_bscan(BScan& bscan, int size_x, int size_z, double dz_px, double dx_px) {
    if (size_x <= 0 || size_z <= 0 || !std::isfinite(dz_px) || !std::isfinite(dx_px)) return;
    const auto nx = static_cast<std::size_t>(size_x);
    const auto nz = static_cast<std::size_t>(size_z);
    if (bscan.pixels.size() == nx * nz) {
        std::vector<float> tmp(bscan.pixels.size());
        if (dz_px != 0.0) {
            // One source position per output row (the shift is the same for every A-scan):
            // whole rows blended, in memory order.
            const double last = static_cast<double>(size_z - 1);
            for (int z = 0; z < size_z; ++z) {
                const double src = std::clamp(static_cast<double>(z) - dz_px, 0.0, last);
                const auto z0 = static_cast<std::size_t>(std::floor(src));
                const std::size_t z1 = std::min(z0 + 1, nz - 1);
                const auto f = static_cast<float>(src - static_cast<double>(z0));
                const float* r0 = bscan.pixels.data() + z0 * nx;
                const float* r1 = bscan.pixels.data() + z1 * nx;
                float* out = tmp.data() + static_cast<std::size_t>(z) * nx;
                for (std::size_t a = 0; a < nx; ++a) out[a] = (1.0F - f) * r0[a] + f * r1[a];
            }
            bscan.pixels.swap(tmp);
        }
        if (dx_px != 0.0) {
            for (std::size_t z = 0; z < nz; ++z) {
                const float* row = bscan.pixels.data() + z * nx;
                shift_samples(
                    size_x, dx_px, [&](int a) { return double{row[a]}; },
                    [&](int a, double v) { tmp[z * nx + static_cast<std::size_t>(a)] = static_cast<float>(v); });
            }
            bscan.pixels.swap(tmp);
        }
    }
    for (auto& line : bscan.seg) {
        if (dx_px != 0.0 && line.size() == nx) {
            // Linear between two present values. Next to a missing one, the nearer sample
            // decides whether the value is present (so the edge of a gap, e.g. the BMO, moves
            // with the content, not always outward), and its value is the line extrapolated
            // from that side (the slope of its two present samples; the sample itself when
            // it has no present neighbour): the line's slope at a gap's edge survives a shift
            // and its inverse.
            const std::vector<float> in = line;
            const double last = static_cast<double>(size_x - 1);
            const auto present = [&](std::ptrdiff_t i) {
                return i >= 0 && i < static_cast<std::ptrdiff_t>(nx) && std::isfinite(in[static_cast<std::size_t>(i)]);
            };
            for (std::size_t a = 0; a < nx; ++a) {
                const double src = std::clamp(static_cast<double>(a) - dx_px, 0.0, last);
                const auto a0 = static_cast<std::size_t>(std::floor(src));
                const std::size_t a1 = std::min(a0 + 1, nx - 1);
                const double f = src - static_cast<double>(a0);
                const float v0 = in[a0];
                const float v1 = in[a1];
                if (std::isfinite(v0) && std::isfinite(v1)) {
                    line[a] = static_cast<float>((1.0 - f) * v0 + f * v1);
                } else if (f < 0.5) {
                    const auto i0 = static_cast<std::ptrdiff_t>(a0);
                    line[a] = std::isfinite(v0) && present(i0 - 1)
                                  ? static_cast<float>(v0 + f * (v0 - in[a0 - 1]))
                                  : v0;
                } else {
                    const auto i1 = static_cast<std::ptrdiff_t>(a1);
                    line[a] = std::isfinite(v1) && present(i1 + 1)
                                  ? static_cast<float>(v1 - (1.0 - f) * (in[a1 + 1] - v1))
                                  : v1;
                }
            }
        }
        for (float& v : line) v = static_cast<float>(v + dz_px);  // NaN stays NaN
    }
}

}  // namespace octshape::io
