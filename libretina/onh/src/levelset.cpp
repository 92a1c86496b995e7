// Level-set ILM of an ONH volume (thesis §8.1.1): the driver over the stages of
// levelset_stages.h and the stages that read the scan. Method, equations (LS-1 …) and
// defaults: docs/algorithms/levelset.md.

#include "octshape/retina/levelset.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <ctime>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "levelset_stages.h"
#include "octshape/error.h"

namespace octshape::retina {
namespace levelset_detail {
namespace {

// Running min and max over a box of half-widths (ra, rb) columns.
void box_min_max(const std::vector<float>& in, int nb, int na, int ra, int rb,
                 std::vector<float>& mn, std::vector<float>& mx) {
    std::vector<float> tmn(in.size()), tmx(in.size());
    for (int b = 0; b < nb; ++b) {
        for (int a = 0; a < na; ++a) {
            float lo = 1e30F, hi = -1e30F;
            for (int k = std::max(0, a - ra); k <= std::min(na - 1, a + ra); ++k) {
                const float v = in[static_cast<std::size_t>(b * na + k)];
                lo = std::min(lo, v);
                hi = std::max(hi, v);
            }
            tmn[static_cast<std::size_t>(b * na + a)] = lo;
            tmx[static_cast<std::size_t>(b * na + a)] = hi;
        }
    }
    // Filled by assign (not resize): GCC 12 at -O3 sees a null-pointer path in the inlined
    // default-construction of resize (a -Wnull-dereference false positive).
    mn.assign(in.size(), 0.0F);
    mx.assign(in.size(), 0.0F);
    for (int b = 0; b < nb; ++b) {
        for (int a = 0; a < na; ++a) {
            float lo = 1e30F, hi = -1e30F;
            for (int k = std::max(0, b - rb); k <= std::min(nb - 1, b + rb); ++k) {
                lo = std::min(lo, tmn[static_cast<std::size_t>(k * na + a)]);
                hi = std::max(hi, tmx[static_cast<std::size_t>(k * na + a)]);
            }
            mn[static_cast<std::size_t>(b * na + a)] = lo;
            mx[static_cast<std::size_t>(b * na + a)] = hi;
        }
    }
}


}  // namespace

bool fill_missing(std::vector<float>& ilm, int nb, int na) {
    std::vector<std::uint8_t> row_ok(static_cast<std::size_t>(nb), 0);
    for (int b = 0; b < nb; ++b) {
        float* r = ilm.data() + static_cast<std::ptrdiff_t>(b) * na;
        int prev = -1;
        for (int a = 0; a < na; ++a) {
            if (std::isnan(r[a])) continue;
            if (prev < 0) {
                for (int k = 0; k < a; ++k) r[k] = r[a];
            } else {
                for (int k = prev + 1; k < a; ++k) {
                    const float t = static_cast<float>(k - prev) / static_cast<float>(a - prev);
                    r[k] = r[prev] + t * (r[a] - r[prev]);
                }
            }
            prev = a;
        }
        if (prev < 0) continue;
        for (int k = prev + 1; k < na; ++k) r[k] = r[prev];
        row_ok[static_cast<std::size_t>(b)] = 1;
    }
    int any = -1;
    for (int b = 0; b < nb; ++b) {
        if (row_ok[static_cast<std::size_t>(b)]) any = b;
    }
    if (any < 0) return false;
    for (int b = 0; b < nb; ++b) {
        if (row_ok[static_cast<std::size_t>(b)]) continue;
        int best = -1;
        for (int k = 0; k < nb; ++k) {
            if (row_ok[static_cast<std::size_t>(k)] && (best < 0 || std::abs(k - b) < std::abs(best - b))) best = k;
        }
        std::copy_n(ilm.data() + static_cast<std::ptrdiff_t>(best) * na, na,
                    ilm.data() + static_cast<std::ptrdiff_t>(b) * na);
    }
    return true;
}


void require_image(const io::Scan& scan, int b0, int nb, const std::string& where) {
    const auto npx = static_cast<std::size_t>(scan.meta.size_x) *
                     static_cast<std::size_t>(scan.meta.size_z);
    for (int b = b0; b < b0 + nb; ++b) {
        if (scan.bscans[static_cast<std::size_t>(b)].pixels.size() != npx) {
            throw AnalysisError("level-set ILM: no pixels in " +
                                (nb == 1 ? where : "B-scan " + std::to_string(b)));
        }
    }
    // An image: some contrast among the pixels that hold data (the evolution reads max(v, 0)).
    // Without it (all zero, all "no data", NaN or 1e30) the surface would stay where the device
    // line started it and be reported as a segmentation of pixels that show nothing.
    float lo = std::numeric_limits<float>::infinity();
    float hi = -std::numeric_limits<float>::infinity();
    for (int b = b0; b < b0 + nb; ++b) {
        for (const float v : scan.bscans[static_cast<std::size_t>(b)].pixels) {
            if (std::isnan(v) || !(v < io::kInvalidThreshold)) continue;
            const float u = std::max(v, 0.0F);
            lo = std::min(lo, u);
            hi = std::max(hi, u);
        }
    }
    if (!(hi > lo)) {
        throw AnalysisError(
            std::isfinite(lo)
                ? "level-set ILM: no image in " + where + " (every pixel with data is " +
                      std::to_string(lo) + "); --ilm device uses the device's ILM line instead"
                : "level-set ILM: no pixel in " + where +
                      " holds data (all missing, NaN or invalid); --ilm device uses the "
                      "device's ILM line instead");
    }
}

DeviceIlm device_ilm_rows(const io::Scan& scan, int b0, int nb, const Spacing& h) {
    DeviceIlm out;
    out.nb = nb;
    out.na = scan.meta.size_x;
    out.nz = scan.meta.size_z;
    out.h = h;
    const int na = out.na, nz = out.nz;
    // Device ILM (pixels), missing values filled for the initialisation and clipped later.
    const auto ncol = static_cast<std::size_t>(nb) * static_cast<std::size_t>(na);
    out.ilm.resize(ncol);
    out.valid.assign(ncol, 1);
    for (int b = 0; b < nb; ++b) {
        // In the pixels' frame: the level set reads the pixels, and its start, depth windows and
        // leak fallback must agree with them; its result is moved into the lines' frame after
        // the mesh (io::BScan::line_offset_px).
        const double offset = scan.bscans[static_cast<std::size_t>(b0 + b)].line_offset_px;
        for (int a = 0; a < na; ++a) {
            float v = scan.depth_px(static_cast<int>(io::Layer::kILM), b0 + b, a);
            if (offset != 0.0) v = static_cast<float>(v - offset);
            const auto c = static_cast<std::size_t>(b * na + a);
            if (io::is_valid(v) && v >= -1.0F && v <= static_cast<float>(nz)) {
                out.ilm[c] = v;
            } else {
                out.ilm[c] = std::numeric_limits<float>::quiet_NaN();
                out.valid[c] = 0;
                ++out.missing_columns;
            }
        }
    }
    return out;
}

DeviceIlm device_ilm(const io::Scan& scan) {
    const auto& meta = scan.meta;
    const int nb = scan.num_bscans(), na = meta.size_x, nz = meta.size_z;
    if (nb < 2 || na < 2 || nz < 4 || !(meta.distance_mm > 0.0) || !(meta.scale_x_mm > 0.0) ||
        !(meta.scale_z_mm > 0.0)) {
        throw AnalysisError(
            "level-set ILM needs a volume scan (>= 2 B-scans with a B-scan distance)");
    }
    if (!scan.pixels_loaded) throw AnalysisError("level-set ILM needs the B-scan pixels");
    require_image(scan, 0, nb, "the B-scans");
    DeviceIlm out =
        device_ilm_rows(scan, 0, nb, {meta.scale_x_mm, meta.distance_mm, meta.scale_z_mm});
    if (!fill_missing(out.ilm, nb, na)) throw AnalysisError("level-set ILM: the scan has no device ILM");
    return out;
}

Windows depth_windows(const DeviceIlm& ilm, const LevelSetParams& params) {
    const int nb = ilm.nb, na = ilm.na, nz = ilm.nz;
    const auto ncol = static_cast<std::size_t>(nb) * static_cast<std::size_t>(na);
    Windows w;
    w.nb = nb;
    w.na = na;
    std::vector<float> mn, mx;
    const int ra = static_cast<int>(std::floor(params.lateral_radius_mm / ilm.h.hx));
    const int rb = static_cast<int>(std::floor(params.lateral_radius_mm / ilm.h.hy));
    box_min_max(ilm.ilm, nb, na, ra, rb, mn, mx);
    const double m = params.margin_mm / ilm.h.hz;
    w.lo.resize(ncol);
    w.len.resize(ncol);
    w.offset.resize(ncol + 1);
    std::int64_t off = 0;
    for (std::size_t c = 0; c < ncol; ++c) {
        const int lo = std::clamp(static_cast<int>(std::floor(mn[c] - m)), 0, nz - 1);
        const int hi = std::clamp(static_cast<int>(std::ceil(mx[c] + m)) + 1, lo + 1, nz);
        w.lo[c] = lo;
        w.len[c] = hi - lo;
        w.offset[c] = off;
        off += hi - lo;
    }
    w.offset[ncol] = off;
    w.size = off;
    if (w.size >= (std::int64_t{1} << 32) || nb > 65535 || na > 65535) {
        throw AnalysisError("level-set ILM: the volume is too large (window voxels, B-scans or A-scans)");
    }
    return w;
}

void binomial_pass(std::vector<float>& buf, std::vector<float>& tmp, int rows, int na,
                   double sigma_x_px) {
    auto at = [](int i, int n) { return std::clamp(i, 0, n - 1); };
    if (sigma_x_px >= 1.0) {
        for (int r = 0; r < rows; ++r) {
            const float* in = buf.data() + static_cast<std::ptrdiff_t>(r) * na;
            float* out = tmp.data() + static_cast<std::ptrdiff_t>(r) * na;
            for (int a = 0; a < na; ++a) {
                out[a] = (in[at(a - 2, na)] + in[at(a + 2, na)] +
                          4.0F * (in[at(a - 1, na)] + in[at(a + 1, na)]) + 6.0F * in[a]) *
                         (1.0F / 16.0F);
            }
        }
    } else {
        // [q, 1 - 2q, q] twice, q = sigma^2 / 4: variance 4q = sigma^2 (q = 1/4 is the
        // binomial above).
        const float q = static_cast<float>(std::max(0.0, sigma_x_px) * std::max(0.0, sigma_x_px) / 4.0);
        const float k2 = q * q, k1 = 2.0F * q * (1.0F - 2.0F * q), k0 = 1.0F - 2.0F * (k1 + k2);
        for (int r = 0; r < rows; ++r) {
            const float* in = buf.data() + static_cast<std::ptrdiff_t>(r) * na;
            float* out = tmp.data() + static_cast<std::ptrdiff_t>(r) * na;
            for (int a = 0; a < na; ++a) {
                out[a] = k2 * (in[at(a - 2, na)] + in[at(a + 2, na)]) +
                         k1 * (in[at(a - 1, na)] + in[at(a + 1, na)]) + k0 * in[a];
            }
        }
    }
    for (int r = 0; r < rows; ++r) {
        const float* m2 = tmp.data() + static_cast<std::ptrdiff_t>(at(r - 2, rows)) * na;
        const float* m1 = tmp.data() + static_cast<std::ptrdiff_t>(at(r - 1, rows)) * na;
        const float* c0 = tmp.data() + static_cast<std::ptrdiff_t>(r) * na;
        const float* p1 = tmp.data() + static_cast<std::ptrdiff_t>(at(r + 1, rows)) * na;
        const float* p2 = tmp.data() + static_cast<std::ptrdiff_t>(at(r + 2, rows)) * na;
        float* out = buf.data() + static_cast<std::ptrdiff_t>(r) * na;
        for (int a = 0; a < na; ++a) {
            out[a] = (m2[a] + p2[a] + 4.0F * (m1[a] + p1[a]) + 6.0F * c0[a]) * (1.0F / 16.0F);
        }
    }
}

std::vector<float> despeckle(const io::Scan& scan, const Windows& w, int despeckle_passes,
                             double max_sigma_x_mm, DeviceIlm& ilm, int b0) {
    const int nb = w.nb, na = w.na, nz = ilm.nz;
    std::vector<float> image(static_cast<std::size_t>(w.size));
    const int pad = 2 * despeckle_passes;
    const double sigma_x_px = std::min(1.0, max_sigma_x_mm / ilm.h.hx);
    std::vector<float> buf, tmp;
    for (int b = 0; b < nb; ++b) {
        int r0 = nz, r1 = 0;
        for (int a = 0; a < na; ++a) {
            const auto c = static_cast<std::size_t>(b * na + a);
            r0 = std::min(r0, w.lo[c]);
            r1 = std::max(r1, w.lo[c] + w.len[c]);
        }
        r0 = std::max(0, r0 - pad);
        r1 = std::min(nz, r1 + pad);
        const int rows = r1 - r0;
        buf.resize(static_cast<std::size_t>(rows) * static_cast<std::size_t>(na));
        tmp.resize(buf.size());
        const auto& px = scan.bscans[static_cast<std::size_t>(b0 + b)].pixels;
        for (int r = 0; r < rows; ++r) {
            const float* in = px.data() + static_cast<std::ptrdiff_t>(r0 + r) * na;
            float* out = buf.data() + static_cast<std::ptrdiff_t>(r) * na;
            for (int a = 0; a < na; ++a) {
                float v = in[a];
                if (!(v < io::kInvalidThreshold) || std::isnan(v)) {
                    ilm.valid[static_cast<std::size_t>(b * na + a)] = 0;
                    v = 0.0F;
                }
                out[a] = std::sqrt(std::sqrt(std::max(v, 0.0F)));
            }
        }
        for (int k = 0; k < despeckle_passes; ++k) binomial_pass(buf, tmp, rows, na, sigma_x_px);
        for (int a = 0; a < na; ++a) {
            const auto c = static_cast<std::size_t>(b * na + a);
            float* dst = image.data() + w.offset[c];
            for (int d = w.lo[c]; d < w.lo[c] + w.len[c]; ++d) {
                dst[d - w.lo[c]] = buf[static_cast<std::size_t>((d - r0) * na + a)];
            }
        }
    }
    return image;
}

std::vector<float> initial_phi(const Windows& w, const DeviceIlm& ilm) {
    std::vector<float> phi(static_cast<std::size_t>(w.size));
    for (std::size_t c = 0; c < w.lo.size(); ++c) {
        for (int r = 0; r < w.len[c]; ++r) {
            phi[static_cast<std::size_t>(w.offset[c] + r)] =
                static_cast<float>((ilm.ilm[c] - (w.lo[c] + r)) * ilm.h.hz);
        }
    }
    return phi;
}

std::vector<std::uint8_t> leak_runs(const std::vector<double>& top,
                                     const float* device,
                                     const std::uint8_t* valid,
                                     int na,
                                     double leak_rows) {
    // The median drops a device-line spike of up to 4 A-scans into the vitreous (there the level
    // set is right) and keeps a monotone wall and a step; a run of 3 leaves out a lip's tip,
    // thinner than a pixel where it ends, which may open one or two A-scans to its cavity.
    constexpr int kHalfWindow = 4;
    constexpr int kMinRun = 3;
    constexpr int kMargin = 2;
    std::vector<std::uint8_t> deep(static_cast<std::size_t>(na), 0);
    std::vector<float> win;
    for (int a = 0; a < na; ++a) {
        if (!valid[a]) continue;
        win.clear();
        for (int b = std::max(0, a - kHalfWindow); b <= std::min(na - 1, a + kHalfWindow); ++b) {
            if (valid[b]) win.push_back(device[b]);
        }
        std::nth_element(win.begin(), win.begin() + static_cast<std::ptrdiff_t>(win.size() / 2),
                         win.end());
        deep[static_cast<std::size_t>(a)] =
            top[static_cast<std::size_t>(a)] > win[win.size() / 2] + leak_rows ? 1 : 0;
    }
    std::vector<std::uint8_t> leak(static_cast<std::size_t>(na), 0);
    for (int a = 0; a < na;) {
        if (!deep[static_cast<std::size_t>(a)]) {
            ++a;
            continue;
        }
        int e = a;
        while (e < na && deep[static_cast<std::size_t>(e)]) ++e;
        if (e - a >= kMinRun) {
            for (int b = std::max(0, a - kMargin); b < std::min(na, e + kMargin); ++b) {
                leak[static_cast<std::size_t>(b)] = 1;
            }
        }
        a = e;
    }
    return leak;
}

namespace {

// One B-scan's rows [r0, r0 + rows) x na A-scans, row-major.
struct Slice {
    int r0 = 0, rows = 0, na = 0;
    [[nodiscard]] std::size_t at(int d, int a) const {
        return static_cast<std::size_t>(d - r0) * static_cast<std::size_t>(na) +
               static_cast<std::size_t>(a);
    }
};

// Marks 2 every voxel of `m` (1 = candidate) 4-connected to a 3 x 3 block of candidates.
void keep_thick_groups(std::vector<std::uint8_t>& m, const Slice& sl) {
    const int rows = sl.rows, na = sl.na;
    std::vector<int> stack;
    for (int r = 1; r + 1 < rows; ++r) {
        for (int a = 1; a + 1 < na; ++a) {
            bool block = true;
            for (int dr = -1; dr <= 1 && block; ++dr) {
                for (int da = -1; da <= 1 && block; ++da) {
                    block = m[static_cast<std::size_t>((r + dr) * na + a + da)] != 0;
                }
            }
            const int i0 = r * na + a;
            if (!block || m[static_cast<std::size_t>(i0)] != 1) continue;
            m[static_cast<std::size_t>(i0)] = 2;
            stack.push_back(i0);
            while (!stack.empty()) {
                const int i = stack.back();
                stack.pop_back();
                const int ri = i / na, ai = i % na;
                for (const auto& [rr, aa] : {std::pair{ri - 1, ai}, std::pair{ri + 1, ai},
                                             std::pair{ri, ai - 1}, std::pair{ri, ai + 1}}) {
                    if (rr < 0 || rr >= rows || aa < 0 || aa >= na) continue;
                    const int j = rr * na + aa;
                    if (m[static_cast<std::size_t>(j)] != 1) continue;
                    m[static_cast<std::size_t>(j)] = 2;
                    stack.push_back(j);
                }
            }
        }
    }
}

// B-scan b's cut (cut_shadowed_tissue); returns its number of columns.
std::int64_t cut_bscan(const Windows& w, std::vector<float>& phi, const std::vector<float>& image,
                       const DeviceIlm& ilm, double c_tissue, double hidden_rows, int b) {
    const int na = w.na;
    Slice sl;
    sl.na = na;
    int r1 = 0;
    sl.r0 = std::numeric_limits<int>::max();
    std::vector<float> open;
    for (int a = 0; a < na; ++a) {
        const auto c = static_cast<std::size_t>(w.column(b, a));
        sl.r0 = std::min(sl.r0, w.lo[c]);
        r1 = std::max(r1, w.lo[c] + w.len[c]);
        if (!ilm.valid[c]) continue;
        for (int d = w.lo[c]; d < w.lo[c] + w.len[c] && d <= ilm.ilm[c] - 3.0F; ++d) {
            const auto i = static_cast<std::size_t>(w.offset[c] + (d - w.lo[c]));
            if (phi[i] > 0.0F) open.push_back(image[i]);
        }
    }
    if (open.empty()) return 0;
    sl.rows = r1 - sl.r0;
    const auto mid = open.begin() + static_cast<std::ptrdiff_t>(open.size() / 2);
    std::nth_element(open.begin(), mid, open.end());
    const double v = *mid;
    if (!(c_tissue > v)) return 0;
    const double step = (c_tissue - v) / 4.0;
    const double thr = v + step;
    // Hidden vitreous brighter than the threshold, then its thick groups.
    std::vector<std::uint8_t> m(static_cast<std::size_t>(sl.rows) * static_cast<std::size_t>(na), 0);
    for (int a = 0; a < na; ++a) {
        const auto c = static_cast<std::size_t>(w.column(b, a));
        if (!ilm.valid[c]) continue;
        for (int d = w.lo[c]; d < w.lo[c] + w.len[c]; ++d) {
            const auto i = static_cast<std::size_t>(w.offset[c] + (d - w.lo[c]));
            if (phi[i] > 0.0F && d >= ilm.ilm[c] + hidden_rows && image[i] > thr) m[sl.at(d, a)] = 1;
        }
    }
    keep_thick_groups(m, sl);
    auto cut = [&](int d, int a) {
        return d >= sl.r0 && d < sl.r0 + sl.rows && a >= 0 && a < na && m[sl.at(d, a)] == 2;
    };
    std::int64_t columns = 0;
    for (int a = 0; a < na; ++a) {
        const auto c = static_cast<std::size_t>(w.column(b, a));
        if (!ilm.valid[c]) continue;
        bool any = false;
        for (int d = w.lo[c]; d < w.lo[c] + w.len[c]; ++d) {
            const auto i = static_cast<std::size_t>(w.offset[c] + (d - w.lo[c]));
            const bool in = cut(d, a);
            any = any || in;
            if (!in && !(phi[i] > 0.0F && (cut(d - 1, a) || cut(d + 1, a) || cut(d, a - 1) ||
                                           cut(d, a + 1)))) {
                continue;
            }
            phi[i] = std::min(phi[i], static_cast<float>(ilm.h.hz * (thr - image[i]) / step));
        }
        columns += any ? 1 : 0;
    }
    return columns;
}

}  // namespace

std::int64_t cut_shadowed_tissue(const Windows& w, std::vector<float>& phi,
                                 const std::vector<float>& image, const DeviceIlm& ilm,
                                 double c_tissue, double leak_depth_mm, std::vector<int>& bscans) {
    std::int64_t columns = 0;
    for (int b = 0; b < w.nb; ++b) {
        const std::int64_t n = cut_bscan(w, phi, image, ilm, c_tissue, leak_depth_mm / ilm.h.hz, b);
        if (n > 0) bscans.push_back(b);
        columns += n;
    }
    return columns;
}

std::int64_t fall_back_leaks(const Windows& w, std::vector<float>& phi, const DeviceIlm& ilm,
                             double leak_depth_mm, std::vector<int>& bscans) {
    const int na = w.na;
    const double hz = ilm.h.hz;
    std::int64_t columns = 0;
    std::vector<double> top(static_cast<std::size_t>(na));
    for (int b = 0; b < w.nb; ++b) {
        for (int a = 0; a < na; ++a) {
            const auto c = static_cast<std::size_t>(w.column(b, a));
            int t = w.lo[c] + w.len[c];  // below the window: tissue
            for (int d = 0; d < w.len[c]; ++d) {
                if (phi[static_cast<std::size_t>(w.offset[c] + d)] <= 0.0F) {
                    t = w.lo[c] + d;
                    break;
                }
            }
            top[static_cast<std::size_t>(a)] = t;
        }
        const std::size_t row = static_cast<std::size_t>(b) * static_cast<std::size_t>(na);
        const std::vector<std::uint8_t> leak =
            leak_runs(top, ilm.ilm.data() + row, ilm.valid.data() + row, na, leak_depth_mm / hz);
        bool any = false;
        for (int a = 0; a < na; ++a) {
            if (!leak[static_cast<std::size_t>(a)]) continue;
            any = true;
            ++columns;
            const auto c = static_cast<std::size_t>(w.column(b, a));
            for (int d = 0; d < w.len[c]; ++d) {
                phi[static_cast<std::size_t>(w.offset[c] + d)] =
                    static_cast<float>((ilm.ilm[row + static_cast<std::size_t>(a)] - (w.lo[c] + d)) * hz);
            }
        }
        if (any) bscans.push_back(b);
    }
    return columns;
}

}  // namespace levelset_detail

mesh::RofiParams levelset_default_rofi() {
    mesh::RofiParams r;
    r.sigma_s = 1.0;
    r.lambda_i = 0.0;
    r.iterations = 10;
    // Bit-identical to the shared weights; 12 bytes less per slot of Ω (~30 slots per face on
    // the level-set mesh): RoFi's arrays set the eye's peak memory (docs: "Memory").
    r.pair_weights = mesh::PairWeights::kPerRow;
    return r;
}

void LevelSetParams::validate() const {
    auto bad = [](const std::string& field, const std::string& why) {
        throw UsageError("level-set parameter " + field + ": " + why);
    };
    if (!(lateral_radius_mm > 0.0)) bad("lateral_radius_mm", "must be > 0");
    if (!(margin_mm > 0.0)) bad("margin_mm", "must be > 0");
    if (despeckle_passes < 0) bad("despeckle_passes", "must be >= 0");
    if (!(despeckle_max_sigma_x_mm >= 0.0) || !std::isfinite(despeckle_max_sigma_x_mm)) {
        bad("despeckle_max_sigma_x_mm", "must be finite and >= 0");
    }
    if (!(mu_mm >= 0.0) || !std::isfinite(mu_mm)) bad("mu_mm", "must be finite and >= 0");
    if (!(lambda_vitreous > 0.0)) bad("lambda_vitreous", "must be > 0");
    if (!(lambda_tissue > 0.0)) bad("lambda_tissue", "must be > 0");
    if (band_layers < 2 || band_layers > 100) bad("band_layers", "must be in [2, 100]");
    if (reinit_interval < 1 || reinit_interval > band_layers) {
        bad("reinit_interval", "must be in [1, band_layers]");
    }
    if (!(cfl > 0.0 && cfl <= 1.0)) bad("cfl", "must be in (0, 1]");
    if (max_iterations < 1) bad("max_iterations", "must be >= 1");
    if (!(tile_mm > 0.0) || !std::isfinite(tile_mm)) bad("tile_mm", "must be finite and > 0");
    if (patience < 1) bad("patience", "must be >= 1");
    if (slab_bscans < 2) bad("slab_bscans", "must be >= 2");
    if (!(leak_depth_mm > 0.0) || !std::isfinite(leak_depth_mm)) {
        bad("leak_depth_mm", "must be finite and > 0");
    }
    try {
        rofi.validate();
    } catch (const UsageError& e) {
        bad("rofi", e.what());
    }
}

namespace {

using namespace levelset_detail;
using Clock = std::chrono::steady_clock;

// Wall and process-CPU stopwatch for the stage timings.
class Stopwatch {
public:
    Stopwatch() : wall_(Clock::now()), cpu_(std::clock()) {}
    [[nodiscard]] LevelSetResult::StageTime elapsed() const {
        return {std::chrono::duration<double>(Clock::now() - wall_).count(),
                static_cast<double>(std::clock() - cpu_) / CLOCKS_PER_SEC};
    }

private:
    Clock::time_point wall_;
    std::clock_t cpu_;
};

// What the stages that read the pixels hand to the rest: after prepare() the scan's pixels
// are no longer needed.
struct Prepared {
    LevelSetResult res;
    DeviceIlm ilm;
    Windows windows;
    std::vector<float> image;  // despeckled intensities on the windows
    std::vector<float> phi;    // φ0 on the windows
    std::vector<double> line_offset_px;  // per B-scan (io::BScan::line_offset_px)
    Stopwatch clock;           // started with the preparation
};

Prepared prepare(const io::Scan& scan, const LevelSetParams& params) {
    params.validate();
    Prepared p;
    p.ilm = device_ilm(scan);
    p.res.missing_ilm_columns = p.ilm.missing_columns;
    p.windows = depth_windows(p.ilm, params);
    p.res.window_voxels = p.windows.size;
    p.image = despeckle(scan, p.windows, params.despeckle_passes, params.despeckle_max_sigma_x_mm, p.ilm);
    for (std::size_t c = 0; c < p.ilm.valid.size(); ++c) {
        const int na = p.ilm.na;
        if (!p.ilm.valid[c] && io::is_valid(scan.depth_px(0, static_cast<int>(c) / na, static_cast<int>(c) % na))) {
            ++p.res.invalid_pixel_columns;
        }
    }
    p.phi = initial_phi(p.windows, p.ilm);
    for (const io::BScan& bs : scan.bscans) p.line_offset_px.push_back(bs.line_offset_px);
    return p;
}

// "B-scan 3" or "B-scans 3, 7".
std::string bscan_names(const std::vector<int>& bscans) {
    std::string list;
    for (const int b : bscans) list += (list.empty() ? "" : ", ") + std::to_string(b);
    return std::string(bscans.size() > 1 ? "B-scans " : "B-scan ") + list;
}

// evolve → surface → clean-up → smoothing; frees each array as soon as the next stage has it.
LevelSetResult finish(Prepared p, const LevelSetParams& params) {
    LevelSetResult res = std::move(p.res);
    res.prepare = p.clock.elapsed();

    Stopwatch t0;
    evolve(p.windows, p.phi, p.image, params, p.ilm.h, res, params.open_vitreous_mean ? p.ilm.ilm.data() : nullptr);
    if (params.leak_fallback) {
        std::vector<int> bscans;
        const std::int64_t n = fall_back_leaks(p.windows, p.phi, p.ilm, params.leak_depth_mm, bscans);
        if (n > 0) {
            res.warnings.push_back(std::string(kLeakFlag) + " in " + std::to_string(n) +
                                   " columns of " + bscan_names(bscans) +
                                   ": they fell back to the device ILM");
        }
    }
    // After the fallback (the radial level set cuts first, levelset.md "Leaks"): a volume has no
    // region step, and a cut above a dark cleft would leave the cleft below it as a bubble of
    // vitreous inside the tissue (measured: worst 3-D MRW point 6 -> 25 um on the cupped volume
    // with shadows and the cleft) where the fallback takes the device ILM.
    if (params.leak_fallback) {
        std::vector<int> cut;
        const std::int64_t n = cut_shadowed_tissue(p.windows, p.phi, p.image, p.ilm, res.c_tissue,
                                                   params.leak_depth_mm, cut);
        if (n > 0) {
            res.warnings.push_back(std::string(kLeakFlag) + " in " + std::to_string(n) +
                                   " columns of " + bscan_names(cut) +
                                   ": shadowed tissue cut from the vitreous");
        }
    }
    p.image = std::vector<float>();  // released before the mesh stages
    res.evolve = t0.elapsed();

    t0 = Stopwatch();
    Surface s = surface(p.windows, p.phi, p.ilm.h, params.slab_bscans);
    p.phi = std::vector<float>();
    to_line_frame(s, p.line_offset_px, p.ilm.h);
    res.raw_vertices = s.V.rows();
    res.raw_faces = s.F.rows();
    res.marching_cubes = t0.elapsed();

    t0 = Stopwatch();
    const CleanUp c = clean_up(s, p.ilm.valid, p.ilm.nb, p.ilm.na, p.ilm.h);
    res.clipped_faces = c.clipped_faces;
    res.components = c.components;
    res.component_clip = t0.elapsed();

    t0 = Stopwatch();
    smooth(std::move(s), params, res);
    res.rofi = t0.elapsed();
    return res;
}

}  // namespace

LevelSetResult levelset_ilm(const io::Scan& scan, const LevelSetParams& params) {
    return finish(prepare(scan, params), params);
}

LevelSetResult levelset_ilm_releasing_pixels(io::Scan& scan, const LevelSetParams& params) {
    Prepared p = prepare(scan, params);
    for (auto& bs : scan.bscans) bs.pixels = std::vector<float>();
    scan.pixels_loaded = false;
    return finish(std::move(p), params);
}

}  // namespace octshape::retina
