// The level-set ILM of a radial scan (docs/algorithms/onh.md "Radial scans"): a 2-D
// Chan–Vese level set in every B-scan's own plane (the volume's stages of levelset_stages.h on
// a one-B-scan "volume"), the signed distance to each B-scan's zero-level curve, interpolated
// between neighbouring half-lines linearly in angle at constant distance from the crossing (as
// radial_height_field interpolates heights) onto a Cartesian grid over the scanned circle, and
// the volume's marching cubes, clean-up and RoFi on that grid. Each line keeps its own curve
// (the interpolation weight is 0 on it), and an overhang in the lines' planes is carried into
// the surface between them: nothing here is a height field. Where a B-scan's front leaked
// into the tissue, the shadowed tissue it took under the ILM is cut from the vitreous (a vessel's
// shadow) or, where its top crossing lies deep below the device ILM (a cleft), those A-scans take
// the device ILM (docs/algorithms/levelset.md "Leaks").

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "levelset_stages.h"
#include "octshape/error.h"
#include "octshape/retina/report_util.h"
#include "onh_stages.h"

namespace octshape::retina::onh_detail {
namespace {

namespace ls = levelset_detail;

// The signed distance to a B-scan's curve is exact up to this distance and saturates beyond
// (mm). The interpolated surface between two lines is the zero of (1 - w) d_0 + w d_1, exact
// (for locally straight curves: the point dividing the normal gap in the ratio w) wherever both
// lines' curves lie within the cap of that point, i.e. where the two lines' curves at the same
// distance from the crossing are less than the cap apart. 0.1 mm (26 px of depth, 9 A-scans) is
// several times what neighbouring lines differ by on a disc 7.5 deg apart (docs: measured
// 6-48 lines); the cost is linear in it (each segment rasterises its cap neighbourhood).
// Measured: 0.05, 0.1 and 0.2 mm give the same parameters to 0.01 % and 0.01 um at 24 lines
// (crossing centred and 300 um off); at 6 lines 0.05 mm moves the MRW by 0.05 um.
constexpr double kDistanceCapMm = 0.1;

// One B-scan's 2-D level set and its signed distance field.
struct BscanLevelSet {
    int na = 0;
    int r0 = 0;  // dense rows [r0, r0 + rows) (absolute pixel rows)
    int rows = 0;
    std::vector<float> dist;  // rows × na (row-major): signed distance (mm), + vitreous, capped
    std::vector<int> lo, hi;  // the depth window of each A-scan, rows [lo, hi)
    std::vector<std::uint8_t> valid;  // per A-scan: device ILM and pixel data present
    std::vector<PlaneSegment> curve;  // the zero level, (s, z) mm
    int iterations = 0;
    bool converged = false;
    bool reached_edge = false;
    int missing_ilm_columns = 0;
    int leak_ascans = 0;  // A-scans that fell back to the device ILM (a leak)
    int shadow_ascans = 0;  // A-scans whose shadowed tissue was cut from the vitreous (a leak)
    // Rows by which the B-scan's lines lie deeper than its pixels (io::BScan::line_offset_px):
    // dist and curve are in the pixels' frame, at_line_frame and the reported curve in the lines'.
    double line_offset_px = 0.0;

    [[nodiscard]] double at(int d, int a) const {
        if (d < r0) return kDistanceCapMm;
        if (d >= r0 + rows) return -kDistanceCapMm;
        return dist[static_cast<std::size_t>(d - r0) * static_cast<std::size_t>(na) +
                    static_cast<std::size_t>(a)];
    }
    // The signed distance at row d of the lines' frame: the pixels' row d - line_offset_px,
    // linear between rows (as marching cubes interpolates), so the zero level moves by exactly
    // the offset.
    [[nodiscard]] double at_line_frame(int d, int a) const {
        if (line_offset_px == 0.0) return at(d, a);
        const double x = d - line_offset_px;
        const int d0 = static_cast<int>(std::floor(x));
        const double f = x - d0;
        return (1.0 - f) * at(d0, a) + f * at(d0 + 1, a);
    }
};

// Flood fill over 4-neighbours of the cells with mark == from, starting at row `row`: they
// become `to`.
void flood(std::vector<std::uint8_t>& mark,
           int rows,
           int na,
           int row,
           std::uint8_t from,
           std::uint8_t to) {
    std::vector<int> stack;
    for (int a = 0; a < na; ++a) {
        const int i = row * na + a;
        if (mark[static_cast<std::size_t>(i)] == from) {
            mark[static_cast<std::size_t>(i)] = to;
            stack.push_back(i);
        }
    }
    while (!stack.empty()) {
        const int i = stack.back();
        stack.pop_back();
        const int r = i / na, a = i % na;
        const std::array<std::pair<int, int>, 4> nbs{
            {{r - 1, a}, {r + 1, a}, {r, a - 1}, {r, a + 1}}};
        for (const auto& [rr, aa] : nbs) {
            if (rr < 0 || rr >= rows || aa < 0 || aa >= na) continue;
            const int j = rr * na + aa;
            if (mark[static_cast<std::size_t>(j)] != from) continue;
            mark[static_cast<std::size_t>(j)] = to;
            stack.push_back(j);
        }
    }
}

// The B-scan's 2-D evolution; fills `out`'s windows, valid columns, diagnostics and dense rows
// (one row of vitreous above and of tissue below every window) and returns phi on them
// (rows x na, row-major; +-hz outside the windows). `device` receives the device ILM (px,
// missing values filled).
std::vector<double> evolve_bscan(const io::Scan& scan,
                                 const RadialOnhGrid& grid,
                                 int k,
                                 const LevelSetParams& params,
                                 BscanLevelSet& out,
                                 std::vector<float>& device) {
    ls::require_image(scan, k, 1, "radial B-scan " + std::to_string(k));
    const int na = scan.meta.size_x;
    const double ds = grid.geo.lines[static_cast<std::size_t>(k)].length_mm / (na - 1);
    const double hz = scan.meta.scale_z_mm;
    // The y-spacing is no direction of a single B-scan: infinite, so that the depth windows'
    // lateral box stays in the plane (and the evolution ignores it, levelset_evolve.cpp).
    ls::DeviceIlm ilm =
        ls::device_ilm_rows(scan, k, 1, {ds, std::numeric_limits<double>::infinity(), hz});
    if (!ls::fill_missing(ilm.ilm, 1, na)) {
        throw AnalysisError("level-set ILM: radial B-scan " + std::to_string(k) +
                            " has no device ILM to start from");
    }
    out.na = na;
    out.missing_ilm_columns = ilm.missing_columns;
    const ls::Windows w = ls::depth_windows(ilm, params);
    std::vector<float> image = ls::despeckle(scan, w, params.despeckle_passes, params.despeckle_max_sigma_x_mm, ilm, k);
    std::vector<float> phi = ls::initial_phi(w, ilm);
    LevelSetResult res;
    ls::evolve(w, phi, image, params, ilm.h, res, params.open_vitreous_mean ? ilm.ilm.data() : nullptr);
    if (params.leak_fallback) {
        std::vector<int> cut_bscans;
        out.shadow_ascans = static_cast<int>(ls::cut_shadowed_tissue(
            w, phi, image, ilm, res.c_tissue, params.leak_depth_mm, cut_bscans));
    }
    out.iterations = res.iterations;
    out.converged = res.converged;
    out.reached_edge = res.front_reached_window_edge;
    out.valid = ilm.valid;
    device = ilm.ilm;
    out.lo.resize(static_cast<std::size_t>(na));
    out.hi.resize(static_cast<std::size_t>(na));
    int top = std::numeric_limits<int>::max(), bottom = 0;
    for (int a = 0; a < na; ++a) {
        const auto c = static_cast<std::size_t>(a);
        out.lo[c] = w.lo[c];
        out.hi[c] = w.lo[c] + w.len[c];
        top = std::min(top, out.lo[c]);
        bottom = std::max(bottom, out.hi[c]);
    }
    out.r0 = top - 1;
    out.rows = bottom + 1 - out.r0;
    std::vector<double> dense(static_cast<std::size_t>(out.rows) * static_cast<std::size_t>(na));
    for (int r = 0; r < out.rows; ++r) {
        const int d = out.r0 + r;
        for (int a = 0; a < na; ++a) {
            const auto c = static_cast<std::size_t>(a);
            double f = -hz;
            if (d < out.lo[c]) {
                f = hz;
            } else if (d < out.hi[c]) {
                f = phi[static_cast<std::size_t>(w.offset[c] + (d - out.lo[c]))];
            }
            dense[static_cast<std::size_t>(r) * static_cast<std::size_t>(na) + c] = f;
        }
    }
    return dense;
}

// The vitreous (1) and the tissue (0) of a dense phi: the vitreous is what connects to the top
// row through phi > 0, the tissue what connects to the bottom row through the rest: specks of
// either inside the other (speckle) are absorbed, and the zero level is the one interface
// between them (the volume keeps the largest component of its mesh for the same reason).
std::vector<std::uint8_t> vitreous_region(const std::vector<double>& phi, int rows, int na) {
    std::vector<std::uint8_t> mark(phi.size(), 0);
    for (std::size_t i = 0; i < phi.size(); ++i) mark[i] = phi[i] > 0.0 ? 1 : 0;
    flood(mark, rows, na, 0, 1, 2);           // 2: the vitreous
    for (auto& v : mark) v = v == 2 ? 2 : 0;  // vitreous specks inside the tissue: tissue
    flood(mark, rows, na, rows - 1, 0, 3);    // 3: the tissue (specks inside the vitreous are not)
    for (auto& v : mark) v = v != 3 ? 1 : 0;
    return mark;
}

// Leaks (docs/algorithms/levelset.md "Leaks"). Where the level set is right, its top crossing
// (the first tissue row from the top) is the device ILM's, up to the level set's own offset
// (1-3 um) — also over an overhang, whose cavity lies below the lip that both see first. A
// front that ran into the tissue (a dark cleft, a vessel's shadow) leaves its top crossing deep
// below the device ILM: ls::leak_runs on the B-scan's top crossings.
std::vector<std::uint8_t> leak_columns(const BscanLevelSet& l,
                                       const std::vector<std::uint8_t>& vit,
                                       const std::vector<float>& device,
                                       double leak_rows) {
    const int na = l.na;
    std::vector<double> top(static_cast<std::size_t>(na), l.r0 + l.rows);
    for (int a = 0; a < na; ++a) {
        for (int r = 0; r < l.rows; ++r) {
            if (!vit[static_cast<std::size_t>(r) * static_cast<std::size_t>(na) +
                     static_cast<std::size_t>(a)]) {
                top[static_cast<std::size_t>(a)] = l.r0 + r;
                break;
            }
        }
    }
    return ls::leak_runs(top, device.data(), l.valid.data(), na, leak_rows);
}

// The zero level of `val` by marching squares (linear interpolation on the cell edges, as
// marching cubes), over the cells between two valid A-scans, into l.curve.
void marching_squares(BscanLevelSet& l, const std::vector<double>& val, double ds, double hz) {
    const int na = l.na;
    auto z_of = [&](double r) { return -(l.r0 + r) * hz; };
    for (int r = 0; r + 1 < l.rows; ++r) {
        for (int a = 0; a + 1 < na; ++a) {
            if (!l.valid[static_cast<std::size_t>(a)] || !l.valid[static_cast<std::size_t>(a) + 1]) {
                continue;
            }
            // Corners counter-clockwise in (a, r): 0 = (a, r), 1 = (a+1, r), 2 = (a+1, r+1),
            // 3 = (a, r+1); edge e joins corners e and e+1.
            const std::array<std::pair<int, int>, 4> cn{
                {{a, r}, {a + 1, r}, {a + 1, r + 1}, {a, r + 1}}};
            std::array<double, 4> f{};
            for (std::size_t c = 0; c < 4; ++c) {
                f[c] = val[static_cast<std::size_t>(cn[c].second) * static_cast<std::size_t>(na) +
                           static_cast<std::size_t>(cn[c].first)];
            }
            std::array<std::array<double, 2>, 4> pt{};
            std::array<bool, 4> cut{};
            int ncut = 0;
            for (std::size_t i0 = 0; i0 < 4; ++i0) {
                const std::size_t i1 = (i0 + 1) % 4;
                if ((f[i0] > 0.0) == (f[i1] > 0.0)) continue;
                const double t = f[i0] / (f[i0] - f[i1]);
                pt[i0] = {(cn[i0].first + t * (cn[i1].first - cn[i0].first)) * ds,
                          z_of(cn[i0].second + t * (cn[i1].second - cn[i0].second))};
                cut[i0] = true;
                ++ncut;
            }
            auto add = [&](int e0, int e1) {
                const auto& p = pt[static_cast<std::size_t>(e0)];
                const auto& q = pt[static_cast<std::size_t>(e1)];
                l.curve.push_back({p[0], p[1], q[0], q[1]});
            };
            if (ncut == 2) {
                int e0 = -1, e1 = -1;
                for (int e = 0; e < 4; ++e) {
                    if (!cut[static_cast<std::size_t>(e)]) continue;
                    (e0 < 0 ? e0 : e1) = e;
                }
                add(e0, e1);
            } else if (ncut == 4) {
                // Saddle: the centre's sign (mean of the corners) decides which diagonal pair
                // of corners is joined; the segments cut off the other two corners.
                const bool centre = (f[0] + f[1] + f[2] + f[3]) > 0.0;
                if ((f[0] > 0.0) == centre) {
                    add(0, 1);  // around corner 1
                    add(2, 3);  // around corner 3
                } else {
                    add(3, 0);  // around corner 0
                    add(1, 2);  // around corner 2
                }
            }
        }
    }
}

// Signed distance to l.curve within the cap (+ in the vitreous `vit`): each segment updates the
// pixels of its cap neighbourhood (exact point-to-segment distance), into l.dist.
void signed_distance(BscanLevelSet& l, const std::vector<std::uint8_t>& vit, double ds, double hz) {
    const int na = l.na, rows = l.rows;
    const std::size_t ncell = vit.size();
    std::vector<float> m(ncell, static_cast<float>(kDistanceCapMm));
    const double cap = kDistanceCapMm;
    for (const PlaneSegment& g : l.curve) {
        const double smin = std::min(g.s0, g.s1) - cap, smax = std::max(g.s0, g.s1) + cap;
        const double dmin = -std::max(g.z0, g.z1) - cap, dmax = -std::min(g.z0, g.z1) + cap;
        const int a0 = std::max(0, static_cast<int>(std::ceil(smin / ds)));
        const int a1 = std::min(na - 1, static_cast<int>(std::floor(smax / ds)));
        const int q0 = std::max(0, static_cast<int>(std::ceil(dmin / hz)) - l.r0);
        const int q1 = std::min(rows - 1, static_cast<int>(std::floor(dmax / hz)) - l.r0);
        const double es = g.s1 - g.s0, ez = g.z1 - g.z0;
        const double len2 = es * es + ez * ez;
        for (int r = q0; r <= q1; ++r) {
            const double z = -(l.r0 + r) * hz;
            for (int a = a0; a <= a1; ++a) {
                const double s = a * ds;
                const double t =
                    len2 > 0.0 ? std::clamp(((s - g.s0) * es + (z - g.z0) * ez) / len2, 0.0, 1.0)
                               : 0.0;
                const double us = g.s0 + t * es - s, uz = g.z0 + t * ez - z;
                const auto d = static_cast<float>(std::sqrt(us * us + uz * uz));
                float& slot = m[static_cast<std::size_t>(r) * static_cast<std::size_t>(na) +
                                static_cast<std::size_t>(a)];
                slot = std::min(slot, d);
            }
        }
    }
    l.dist.resize(ncell);
    for (std::size_t i = 0; i < ncell; ++i) l.dist[i] = vit[i] ? m[i] : -m[i];
}

BscanLevelSet bscan_level_set(const io::Scan& scan,
                              const RadialOnhGrid& grid,
                              int k,
                              const LevelSetParams& params) {
    BscanLevelSet out;
    std::vector<float> device;
    std::vector<double> phi = evolve_bscan(scan, grid, k, params, out, device);
    const int na = out.na, rows = out.rows;
    const double ds = grid.geo.lines[static_cast<std::size_t>(k)].length_mm / (na - 1);
    const double hz = scan.meta.scale_z_mm;
    std::vector<std::uint8_t> vit = vitreous_region(phi, rows, na);
    if (params.leak_fallback) {
        const std::vector<std::uint8_t> leak =
            leak_columns(out, vit, device, params.leak_depth_mm / hz);
        for (int a = 0; a < na; ++a) {
            if (!leak[static_cast<std::size_t>(a)]) continue;
            ++out.leak_ascans;
            // phi0 of the device ILM in this A-scan (its signed vertical distance).
            for (int r = 0; r < rows; ++r) {
                phi[static_cast<std::size_t>(r) * static_cast<std::size_t>(na) +
                    static_cast<std::size_t>(a)] =
                    (static_cast<double>(device[static_cast<std::size_t>(a)]) - (out.r0 + r)) * hz;
            }
        }
        if (out.leak_ascans > 0) vit = vitreous_region(phi, rows, na);
    }
    // The values marching squares reads: phi where its sign agrees with the region, else the
    // region's sign at one pixel of depth; |phi| kept off zero (1e-2 ScaleZ: a curve has no
    // slivers to turn over, unlike the volume's marching cubes, levelset_mesh.cpp).
    const double eps = 1e-2 * hz;
    for (std::size_t i = 0; i < phi.size(); ++i) {
        const bool v = vit[i] != 0;
        double& f = phi[i];
        if ((f > 0.0) != v) f = v ? hz : -hz;
        if (std::abs(f) < eps) f = v ? eps : -eps;
    }
    marching_squares(out, phi, ds, hz);
    signed_distance(out, vit, ds, hz);
    out.line_offset_px = scan.bscans[static_cast<std::size_t>(k)].line_offset_px;
    return out;
}

std::string bscan_list(const std::vector<int>& ks) {
    std::string s;
    for (const int k : ks) s += (s.empty() ? "" : ", ") + std::to_string(k);
    return s;
}

// " B-scan 3" or " B-scans 3, 7".
std::string bscans_named(const std::vector<int>& ks) {
    return std::string(ks.size() > 1 ? "B-scans " : "B-scan ") + bscan_list(ks);
}

// The B-scans' signed distances on the grid's nodes, with the grid's depth windows and the
// nodes whose face the clip keeps.
struct GridPhi {
    ls::Windows w;
    std::vector<float> phi;
    std::vector<std::uint8_t> valid;
};

// The clip keeps a face when the node nearest its centroid is valid; with the valid nodes
// eroded by one (every 8-neighbour scanned and valid) such a centroid lies in cells whose
// corners are all scanned, where the RPE (NaN outside the circle) is defined: no ILM face
// outside the RPE grid, as on the device ILM's mesh of the scanned cells.
std::vector<std::uint8_t> eroded(const std::vector<std::uint8_t>& valid, int n) {
    std::vector<std::uint8_t> out(valid.size(), 0);
    auto at = [n](int b, int a) {
        return static_cast<std::size_t>(b) * static_cast<std::size_t>(n) +
               static_cast<std::size_t>(a);
    };
    for (int b = 1; b + 1 < n; ++b) {
        for (int a = 1; a + 1 < n; ++a) {
            bool ok = true;
            for (int db = -1; db <= 1 && ok; ++db) {
                for (int da = -1; da <= 1 && ok; ++da) ok = valid[at(b + db, a + da)] != 0;
            }
            out[at(b, a)] = ok ? 1 : 0;
        }
    }
    return out;
}

// The signed distances interpolated between neighbouring half-lines (linear in angle at
// constant distance r from the crossing, each linear between A-scans; no interpolation in depth:
// all B-scans share the rows) onto the grid's nodes. Nodes outside the scanned circle take the
// values at its edge (r clamped), so that the surface runs on smoothly to the clip instead of
// ending in a wall.
GridPhi interpolate_between_lines(const std::vector<BscanLevelSet>& bs,
                                  const RadialOnhGrid& grid,
                                  int na) {
    const int n = grid.n;
    const auto nn = static_cast<std::size_t>(n) * static_cast<std::size_t>(n);
    struct Tap {
        int line = 0, a = 0;
        double f = 0.0, w = 0.0;  // A-scan fraction, angular weight
    };
    std::vector<std::array<Tap, 2>> taps(nn);
    GridPhi g;
    g.w.nb = n;
    g.w.na = n;
    g.w.lo.resize(nn);
    g.w.len.resize(nn);
    g.w.offset.resize(nn + 1);
    std::vector<std::uint8_t> valid(nn, 0);
    std::int64_t off = 0;
    for (int b = 0; b < n; ++b) {
        for (int a = 0; a < n; ++a) {
            const std::size_t i = static_cast<std::size_t>(b) * static_cast<std::size_t>(n) +
                                  static_cast<std::size_t>(a);
            const Eigen::Vector2d p =
                Eigen::Vector2d(a * grid.step_mm, b * grid.step_mm) - grid.crossing_mm;
            const double r = std::min(p.norm(), grid.radius_mm);
            const auto [h0, h1, w] = grid.blend_at(p);
            int lo = std::numeric_limits<int>::max(), hi = 0;
            bool ok = grid.scanned[i] != 0;
            for (int t = 0; t < 2; ++t) {
                const int h = t == 0 ? h0 : h1;
                const int line = grid.half_line[static_cast<std::size_t>(h)];
                const double x = std::clamp(grid.half_line_ascan(h, r), 0.0, na - 1.0);
                const int ia = std::min(static_cast<int>(std::floor(x)), na - 2);
                taps[i][static_cast<std::size_t>(t)] = {line, ia, x - ia, t == 0 ? 1.0 - w : w};
                const BscanLevelSet& l = bs[static_cast<std::size_t>(line)];
                for (const int c : {ia, ia + 1}) {
                    lo = std::min(lo, l.lo[static_cast<std::size_t>(c)]);
                    hi = std::max(hi, l.hi[static_cast<std::size_t>(c)]);
                    ok = ok && l.valid[static_cast<std::size_t>(c)] != 0;
                }
            }
            valid[i] = ok ? 1 : 0;
            g.w.lo[i] = lo;
            g.w.len[i] = hi - lo;
            g.w.offset[i] = off;
            off += hi - lo;
        }
    }
    g.w.offset[nn] = off;
    g.w.size = off;
    g.valid = eroded(valid, n);
    g.phi.resize(static_cast<std::size_t>(off));
    for (std::size_t i = 0; i < nn; ++i) {
        const auto& tp = taps[i];
        for (int d = g.w.lo[i]; d < g.w.lo[i] + g.w.len[i]; ++d) {
            double v = 0.0;
            for (const Tap& t : tp) {
                if (t.w == 0.0) continue;
                const BscanLevelSet& l = bs[static_cast<std::size_t>(t.line)];
                const double f0 = l.at_line_frame(d, t.a);
                const double f1 = t.f > 0.0 ? l.at_line_frame(d, t.a + 1) : f0;
                v += t.w * ((1.0 - t.f) * f0 + t.f * f1);
            }
            g.phi[static_cast<std::size_t>(g.w.offset[i] + (d - g.w.lo[i]))] = static_cast<float>(v);
        }
    }
    return g;
}

// The per-B-scan diagnostics as QC flags and notes; moves each B-scan's curve into `out`.
void report_bscans(std::vector<BscanLevelSet>& bs, double hz, IlmSurface& out) {
    const int nl = static_cast<int>(bs.size());
    out.bscan_curves.resize(static_cast<std::size_t>(nl));
    int missing = 0;
    std::vector<int> unconverged, edge, iterations;
    for (int k = 0; k < nl; ++k) {
        BscanLevelSet& l = bs[static_cast<std::size_t>(k)];
        iterations.push_back(l.iterations);
        missing += l.missing_ilm_columns;
        if (!l.converged) unconverged.push_back(k);
        if (l.reached_edge) edge.push_back(k);
        if (l.leak_ascans > 0 || l.shadow_ascans > 0) out.leak_bscans.push_back(k);
        out.leak_fallback_ascans += l.leak_ascans;
        out.leak_cut_ascans += l.shadow_ascans;
        // Into the lines' frame: deeper by the line offset (z = -depth).
        const double dz = -l.line_offset_px * hz;
        if (dz != 0.0) {
            for (PlaneSegment& g : l.curve) {
                g.z0 += dz;
                g.z1 += dz;
            }
        }
        out.bscan_curves[static_cast<std::size_t>(k)] = std::move(l.curve);
    }
    if (!unconverged.empty()) {
        out.qc_flags.push_back("level set did not converge in radial " + bscans_named(unconverged));
    }
    if (!edge.empty()) {
        out.qc_flags.push_back("level-set front reached the edge of its depth window in radial " +
                               bscans_named(edge));
    }
    if (!out.leak_bscans.empty()) {
        std::string what;
        if (out.leak_fallback_ascans > 0) {
            what = std::to_string(out.leak_fallback_ascans) + " A-scans fell back to the device ILM";
        }
        if (out.leak_cut_ascans > 0) {
            what += (what.empty() ? "" : ", ") + std::string("shadowed tissue cut from the vitreous in ") +
                    std::to_string(out.leak_cut_ascans) + " A-scans";
        }
        out.qc_flags.push_back(std::string(ls::kLeakFlag) + " in radial " +
                               bscans_named(out.leak_bscans) + ": " + what);
    }
    out.notes.push_back("level-set iterations per radial B-scan (0, 1, ...): " +
                        bscan_list(iterations));
    if (missing > 0) {
        out.notes.push_back(std::to_string(missing) +
                            " A-scans without a device ILM value were filled for the level "
                            "set's start (and left out of the surface)");
    }
}

// AnalysisError unless the scan can be afforded. Memory bound, before any work: the grid's
// depth windows hold at most n x n x SizeZ voxels (4 bytes each; the per-B-scan level sets are
// smaller). A real radial scan has n <= 257 nodes per side and 496-1024 rows (<= 68 M voxels);
// a file whose depth would need more than 2^28 voxels (1 GiB of distances) is refused rather
// than allocating what its few lines of pixels do not justify.
void require_affordable(const io::Scan& scan, const RadialOnhGrid& grid) {
    if (scan.meta.size_z < 4) throw AnalysisError("level-set ILM: B-scans of fewer than 4 rows");
    constexpr std::int64_t kMaxGridVoxels = std::int64_t{1} << 28;
    const std::int64_t grid_voxels = std::int64_t{grid.n} * grid.n * scan.meta.size_z;
    if (grid_voxels > kMaxGridVoxels) {
        throw AnalysisError("level-set ILM: the radial grid would need " +
                            std::to_string(grid_voxels) + " voxels (" + std::to_string(grid.n) +
                            " x " + std::to_string(grid.n) + " nodes x " +
                            std::to_string(scan.meta.size_z) + " rows), more than " +
                            std::to_string(kMaxGridVoxels) + "; use --ilm device");
    }
}

}  // namespace

IlmSurface radial_levelset_ilm_surface(const io::Scan& scan, const LevelSetParams& params) {
    params.validate();
    if (!scan.pixels_loaded) throw AnalysisError("level-set ILM needs the B-scan pixels");
    const RadialOnhGrid grid = radial_onh_grid(scan);
    require_affordable(scan, grid);
    const int nl = static_cast<int>(grid.geo.lines.size());

    // 1. A 2-D level set per B-scan (its leaks fallen back to the device ILM).
    std::vector<BscanLevelSet> bs;
    bs.reserve(static_cast<std::size_t>(nl));
    for (int k = 0; k < nl; ++k) bs.push_back(bscan_level_set(scan, grid, k, params));

    // 2. Their signed distances interpolated between the lines onto the grid's nodes.
    GridPhi g = interpolate_between_lines(bs, grid, scan.meta.size_x);

    // 3. The volume's mesh stages on the grid: marching cubes, clip to the scanned circle (and
    // the valid A-scans), largest component, normals up, RoFi.
    const ls::Spacing h{grid.step_mm, grid.step_mm, scan.meta.scale_z_mm};
    ls::Surface s = ls::surface(g.w, g.phi, h, params.slab_bscans);
    g.phi = std::vector<float>();
    const std::int64_t raw_faces = s.F.rows();
    const ls::CleanUp c = ls::clean_up(s, g.valid, grid.n, grid.n, h);
    LevelSetResult res;
    ls::smooth(std::move(s), params, res);

    IlmSurface out;
    out.V = std::move(res.V);
    out.F = std::move(res.F);
    out.source = "levelset";
    int it_min = std::numeric_limits<int>::max(), it_max = 0, converged = 0;
    for (const BscanLevelSet& l : bs) {
        it_min = std::min(it_min, l.iterations);
        it_max = std::max(it_max, l.iterations);
        converged += l.converged ? 1 : 0;
    }
    for (const auto& wmsg : res.warnings) out.notes.push_back(wmsg);
    out.notes.push_back(
        "level-set ILM (radial): a 2-D level set per B-scan (" + std::to_string(nl) + " B-scans, " +
        std::to_string(it_min) + "-" + std::to_string(it_max) + " iterations, " +
        std::to_string(converged) +
        " converged), their signed "
        "distances interpolated between the lines (linear in angle about the crossing) on a " +
        fixed_number(grid.step_mm * 1e3, 1) + " um grid; " + std::to_string(raw_faces) +
        " marching-cubes faces, " + std::to_string(out.F.rows()) +
        " after the clip to the scanned circle and the largest of " + std::to_string(c.components) +
        " components, " + std::to_string(res.rofi_iterations) + " RoFi iterations");
    report_bscans(bs, scan.meta.scale_z_mm, out);
    return out;
}

}  // namespace octshape::retina::onh_detail
