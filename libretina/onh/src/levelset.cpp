// Level-set ILM of an ONH volume (thesis §8.1.1, SPEC §5.2). Method, equations (LS-1 …) and
// defaults: docs/algorithms/levelset.md.

#include "octshape/retina/levelset.h"

#include <vtkCellArray.h>
#include <vtkCellArrayIterator.h>
#include <vtkFloatArray.h>
#include <vtkFlyingEdges3D.h>
#include <vtkImageData.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkSmartPointer.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <ctime>
#include <cmath>
#include <cstdint>
#include <numeric>
#include <stdexcept>
#include <unordered_map>
#include <cstring>

#include "octshape/error.h"

namespace octshape::retina {
namespace {

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

constexpr std::int8_t kNotInBand = 127;
constexpr std::int8_t kCandidate = 126;  // rebuild(): listed as a candidate for layer 0

// The depth windows: column c = b * na + a holds rows [lo[c], lo[c] + len[c]) stored
// contiguously from offset[c].
struct Windows {
    int nb = 0, na = 0, nz = 0;
    std::vector<int> lo, len;
    std::vector<std::int64_t> offset;
    std::int64_t size = 0;

    [[nodiscard]] int column(int b, int a) const { return b * na + a; }
    [[nodiscard]] int hi(int c) const { return lo[static_cast<std::size_t>(c)] + len[static_cast<std::size_t>(c)]; }
};

// The level-set state and the machinery of one run.
class Evolver {
public:
    Evolver(const Windows& w, std::vector<float>& phi, const std::vector<float>& image,
            const LevelSetParams& p, double hx, double hy, double hz)
        : w_(w), phi_(phi), image_(image), p_(p), h_{hx, hy, hz} {
        cols_.resize(w.lo.size());
        for (std::size_t c = 0; c < cols_.size(); ++c) {
            cols_[c] = {w.offset[c] - w.lo[c], w.lo[c], w.lo[c] + w.len[c]};
        }
        layer_.assign(static_cast<std::size_t>(w.size), kNotInBand);
        flips_.assign(static_cast<std::size_t>(w.size), 0);
        // Tiles about tile_mm square: the activity of a front is judged over the same physical
        // area at any sampling.
        tile_a_ = std::max(1, static_cast<int>(std::lround(p.tile_mm / hx)));
        tile_b_ = std::max(1, static_cast<int>(std::lround(p.tile_mm / hy)));
        tiles_x_ = (w.na + tile_a_ - 1) / tile_a_;
        tiles_y_ = (w.nb + tile_b_ - 1) / tile_b_;
        tile_last_change_.assign(static_cast<std::size_t>(tiles_x_ * tiles_y_), 0);
        column_tile_.resize(static_cast<std::size_t>(w.nb) * static_cast<std::size_t>(w.na));
        for (int b = 0; b < w.nb; ++b) {
            for (int a = 0; a < w.na; ++a) {
                column_tile_[static_cast<std::size_t>(w.column(b, a))] =
                    (b / tile_b_) * tiles_x_ + a / tile_a_;
            }
        }
        tile_active_.assign(tile_last_change_.size(), 1);
        far_ = static_cast<float>((p.band_layers + 1) * std::max({hx, hy, hz}));
        const double inv_h = 1.0 / hx + 1.0 / hy + 1.0 / hz;
        const double inv_h2 = 1.0 / (hx * hx) + 1.0 / (hy * hy) + 1.0 / (hz * hz);
        dt_ = p.cfl / (inv_h + 2.0 * p.mu_mm * inv_h2);
        patience_ = p.patience;
        // Region sums for c_vitreous and c_tissue (Eq. LS-2), kept exact under sign changes.
        for (std::int64_t v = 0; v < w.size; ++v) {
            const auto i = static_cast<std::size_t>(v);
            if (phi_[i] > 0.0F) {
                sum_out_ += image_[i];
                ++n_out_;
            } else {
                sum_in_ += image_[i];
                ++n_in_;
            }
        }
    }

    [[nodiscard]] double dt() const { return dt_; }
    [[nodiscard]] int patience() const { return patience_; }
    [[nodiscard]] double c_vitreous() const { return n_out_ > 0 ? sum_out_ / n_out_ : 0.0; }
    [[nodiscard]] double c_tissue() const { return n_in_ > 0 ? sum_in_ / n_in_ : 0.0; }
    [[nodiscard]] bool reached_edge() const { return reached_edge_; }
    [[nodiscard]] std::int64_t band_size() const { return static_cast<std::int64_t>(band_.size()); }

    // Marks tiles active when they or a neighbour changed sign within `patience` iterations.
    // Returns the number of active tiles.
    int update_activity(int iteration) {
        int active = 0;
        for (int ty = 0; ty < tiles_y_; ++ty) {
            for (int tx = 0; tx < tiles_x_; ++tx) {
                int last = -1000000;
                for (int dy = -1; dy <= 1; ++dy) {
                    for (int dx = -1; dx <= 1; ++dx) {
                        const int y = ty + dy;
                        const int x = tx + dx;
                        if (y < 0 || y >= tiles_y_ || x < 0 || x >= tiles_x_) continue;
                        last = std::max(last, tile_last_change_[static_cast<std::size_t>(y * tiles_x_ + x)]);
                    }
                }
                const bool on = iteration - last <= patience_;
                tile_active_[static_cast<std::size_t>(ty * tiles_x_ + tx)] = on ? 1 : 0;
                active += on ? 1 : 0;
            }
        }
        return active;
    }

    // Rebuilds the band in the active tiles and their neighbours and re-initialises φ there
    // to the (anisotropic) signed distance to the interface.
    void rebuild() {
        region_prev_.swap(region_);
        // Region: active tiles dilated by one tile (so distances at an active tile's edge
        // see the interface beyond it).
        region_.assign(tile_active_.size(), 0);
        for (int ty = 0; ty < tiles_y_; ++ty) {
            for (int tx = 0; tx < tiles_x_; ++tx) {
                if (!tile_active_[static_cast<std::size_t>(ty * tiles_x_ + tx)]) continue;
                for (int dy = -1; dy <= 1; ++dy) {
                    for (int dx = -1; dx <= 1; ++dx) {
                        const int y = ty + dy;
                        const int x = tx + dx;
                        if (y < 0 || y >= tiles_y_ || x < 0 || x >= tiles_x_) continue;
                        region_[static_cast<std::size_t>(y * tiles_x_ + x)] = 1;
                    }
                }
            }
        }
        // Candidates for the interface. In tiles that were in the previous region: the old
        // layer 0, and the voxels that changed sign since (step() lists them) with their
        // 6-neighbours — a voxel none of whose 6-neighbourhood changed sign keeps the neighbours'
        // signs it had, so it is on the interface now only if it was then. In tiles new to the
        // region: every window voxel. Each candidate once (marked kCandidate in layer_).
        candidates_.clear();
        auto add = [&](const Voxel& vx) {
            auto& l = layer_[static_cast<std::size_t>(vx.index)];
            if (l == kCandidate) return;
            l = kCandidate;
            candidates_.push_back(vx);
        };
        for (const Voxel& vx : band_) {
            auto& l = layer_[static_cast<std::size_t>(vx.index)];
            const bool old_interface = l == 0;
            l = kNotInBand;
            if (old_interface && in_region(vx.b, vx.a)) add(vx);
        }
        for (const Voxel& vx : flipped_) {
            if (in_region(vx.b, vx.a)) add(vx);
            for_each_neighbour(vx, add);
        }
        flipped_.clear();
        band_.clear();
        for (int b = 0; b < w_.nb; ++b) {
            for (int a = 0; a < w_.na; ++a) {
                const auto t = static_cast<std::size_t>(tile_of(b, a));
                if (!region_[t] || (region_prev_.size() == region_.size() && region_prev_[t])) continue;
                const int c = w_.column(b, a);
                const Column& col = cols_[static_cast<std::size_t>(c)];
                for (int d = col.lo; d < col.hi; ++d) add(make_voxel(col.base + d, b, a, d));
            }
        }
        // Layer 0: voxels with a 6-neighbour of the other sign; distance by linear
        // interpolation of the crossings (Eq. LS-5).
        std::vector<float> values;
        {
            for (const Voxel& cand : candidates_) {
                const int b = cand.b;
                const int a = cand.a;
                const int c = w_.column(b, a);
                const Column& col = cols_[static_cast<std::size_t>(c)];
                const int lo = col.lo;
                const int hi = col.hi;
                const std::int64_t base = col.base;
                {
                    const int d = cand.depth;
                    const float f0 = phi_[static_cast<std::size_t>(base + d)];
                    const bool s0 = f0 > 0.0F;
                    double inv2 = 0.0;
                    bool interface = false;
                    for (int axis = 0; axis < 3; ++axis) {
                        double t_min = 1e300;
                        for (int dir = -1; dir <= 1; dir += 2) {
                            int nb = b, na = a, nd = d;
                            if (axis == 0) na += dir;
                            if (axis == 1) nb += dir;
                            if (axis == 2) nd += dir;
                            if (na < 0 || na >= w_.na || nb < 0 || nb >= w_.nb) continue;
                            const float f1 = value(nb, na, nd);
                            if ((f1 > 0.0F) == s0) continue;
                            interface = true;
                            const double denom = static_cast<double>(f0) - f1;
                            const double t = denom != 0.0 ? h_[axis] * f0 / denom : 0.0;
                            t_min = std::min(t_min, std::abs(t));
                        }
                        if (t_min < 1e300) {
                            if (t_min <= 0.0) {
                                inv2 = 1e300;
                            } else {
                                inv2 += 1.0 / (t_min * t_min);
                            }
                        }
                    }
                    if (!interface) {
                        layer_[static_cast<std::size_t>(base + d)] = kNotInBand;
                        continue;
                    }
                    if (d == lo || d == hi - 1) reached_edge_ = true;
                    const double dist = inv2 >= 1e300 ? 0.0 : 1.0 / std::sqrt(inv2);
                    const auto idx = base + d;
                    band_.push_back(make_voxel(idx, b, a, d));
                    values.push_back(static_cast<float>(s0 ? dist : -dist));
                    layer_[static_cast<std::size_t>(idx)] = 0;
                }
            }
        }
        for (std::size_t k = 0; k < band_.size(); ++k) {
            phi_[static_cast<std::size_t>(band_[k].index)] = values[k];
        }
        // Layers 1..W: breadth-first through 6-neighbours, each voxel solving the first-order
        // eikonal equation |∇φ| = 1 from its neighbours in lower layers (Eq. LS-6).
        std::size_t layer_begin = 0;
        for (int k = 1; k <= p_.band_layers; ++k) {
            const std::size_t layer_end = band_.size();
            for (std::size_t i = layer_begin; i < layer_end; ++i) {
                // A copy: push_back may move band_.
                for_each_neighbour(Voxel(band_[i]), [&](const Voxel& nv) {
                    auto& l = layer_[nv.index];
                    if (l != kNotInBand) return;
                    l = static_cast<std::int8_t>(k);
                    band_.push_back(nv);
                });
            }
            for (std::size_t i = layer_end; i < band_.size(); ++i) {
                const Voxel vx = band_[i];
                phi_[static_cast<std::size_t>(vx.index)] = eikonal(vx, k);
            }
            layer_begin = layer_end;
        }
        if (p_.region_means == LevelSetParams::RegionMeans::kBand) band_means();
    }

    // One explicit step (Eq. LS-3, LS-4) on the band voxels of active tiles, layers < W.
    // Returns the number of voxels that changed sign; `updated` counts the voxels updated.
    std::int64_t step(int iteration, std::int64_t& updated) {
        const double cv = c_vitreous();
        const double ct = c_tissue();
        const double contrast = std::max((ct - cv) * (ct - cv), 1e-12);
        active_.clear();
        next_.clear();
        for (const Voxel& vx : band_) {
            if (layer_[static_cast<std::size_t>(vx.index)] >= p_.band_layers) continue;
            const int b = vx.b;
            const int a = vx.a;
            if (!tile_active_[static_cast<std::size_t>(tile_of(b, a))]) continue;
            active_.push_back(vx);
            next_.push_back(evolve(vx, b, a, cv, ct, contrast));
        }
        std::int64_t changes = 0;
        for (std::size_t k = 0; k < active_.size(); ++k) {
            const auto i = static_cast<std::size_t>(active_[k].index);
            const bool before = phi_[i] > 0.0F;
            const bool after = next_[k] > 0.0F;
            phi_[i] = next_[k];
            if (before == after) continue;
            ++changes;
            flipped_.push_back(active_[k]);
            const double v = image_[i];
            const double sign = after ? 1.0 : -1.0;  // +1: tissue -> vitreous
            sum_out_ += sign * v;
            n_out_ += after ? 1 : -1;
            sum_in_ -= sign * v;
            n_in_ -= after ? 1 : -1;
            if (!tile_sums_.empty()) {
                TileSums& ts = tile_sums_[static_cast<std::size_t>(tile_of(active_[k].b, active_[k].a))];
                ts.out += sign * v;
                ts.n_out += after ? 1 : -1;
                ts.in -= sign * v;
                ts.n_in -= after ? 1 : -1;
            }
            // A voxel that already changed sign twice oscillates about its equilibrium (the
            // explicit step and the re-initialisation nudge it back and forth): its flips no
            // longer keep the tile active. A moving front changes each voxel's sign once.
            auto& flips = flips_[i];
            if (flips < 2) {
                ++flips;
                tile_last_change_[static_cast<std::size_t>(tile_of(active_[k].b, active_[k].a))] = iteration;
            }
        }
        updated = static_cast<std::int64_t>(active_.size());
        return changes;
    }

private:
    // Region means over the band (LevelSetParams::RegionMeans::kBand), kept per tile: each
    // tile's sums restart from its band voxels on either side of the interface whenever the
    // tile's band is rebuilt (distances exact after the rebuild); a frozen tile keeps the sums
    // of its last band. So the means are always over the whole interface, and do not drift as
    // the active part shrinks. step() keeps them exact under sign changes (band voxels only).
    struct TileSums {
        double out = 0.0, in = 0.0;
        std::int64_t n_out = 0, n_in = 0;
    };
    void band_means() {
        if (tile_sums_.empty()) tile_sums_.assign(region_.size(), TileSums{});
        for (std::size_t t = 0; t < region_.size(); ++t) {
            if (region_[t]) tile_sums_[t] = TileSums{};
        }
        for (const Voxel& vx : band_) {
            const auto i = static_cast<std::size_t>(vx.index);
            TileSums& ts = tile_sums_[static_cast<std::size_t>(tile_of(vx.b, vx.a))];
            if (phi_[i] > 0.0F) {
                ts.out += image_[i];
                ++ts.n_out;
            } else {
                ts.in += image_[i];
                ++ts.n_in;
            }
        }
        TileSums all;
        for (const TileSums& ts : tile_sums_) {
            all.out += ts.out;
            all.in += ts.in;
            all.n_out += ts.n_out;
            all.n_in += ts.n_in;
        }
        if (all.n_out == 0 || all.n_in == 0) return;
        sum_out_ = all.out;
        n_out_ = all.n_out;
        sum_in_ = all.in;
        n_in_ = all.n_in;
    }

    // A band voxel: 12 bytes, B-scan and A-scan kept so that no division is needed.
    struct Voxel {
        std::uint32_t index;  // into the window storage (size checked < 2^32)
        std::uint16_t b;
        std::uint16_t a;
        std::int32_t depth;
    };

    [[nodiscard]] static Voxel make_voxel(std::int64_t index, int b, int a, int d) {
        return {static_cast<std::uint32_t>(index), static_cast<std::uint16_t>(b), static_cast<std::uint16_t>(a), d};
    }
    [[nodiscard]] int tile_of(int b, int a) const {
        return column_tile_[static_cast<std::size_t>(w_.column(b, a))];
    }
    [[nodiscard]] bool in_region(int b, int a) const {
        return region_[static_cast<std::size_t>(tile_of(b, a))] != 0;
    }
    // Calls f(neighbour) for each of the 6 face neighbours of vx that lie in an evolving tile
    // and inside their column's window.
    template <class F>
    void for_each_neighbour(const Voxel& vx, F&& f) const {
        for (int axis = 0; axis < 3; ++axis) {
            for (int dir = -1; dir <= 1; dir += 2) {
                int nb = vx.b, na = vx.a, nd = vx.depth;
                if (axis == 0) na += dir;
                if (axis == 1) nb += dir;
                if (axis == 2) nd += dir;
                if (na < 0 || na >= w_.na || nb < 0 || nb >= w_.nb) continue;
                if (!in_region(nb, na)) continue;
                const Column& col = cols_[static_cast<std::size_t>(w_.column(nb, na))];
                if (nd < col.lo || nd >= col.hi) continue;
                f(make_voxel(col.base + nd, nb, na, nd));
            }
        }
    }
    // φ at (b, a, d) inside the volume's columns; rows outside a window are vitreous above and
    // tissue below (±far).
    [[nodiscard]] float value(int b, int a, int d) const {
        const Column& col = cols_[static_cast<std::size_t>(w_.column(b, a))];
        if (d < col.lo) return far_;
        if (d >= col.hi) return -far_;
        return phi_[static_cast<std::size_t>(col.base + d)];
    }

    [[nodiscard]] float eikonal(const Voxel& vx, int k) const {
        const int b = vx.b;
        const int a = vx.a;
        const float self = phi_[static_cast<std::size_t>(vx.index)];
        std::array<std::pair<double, double>, 3> cand{};  // (|φ| of the best neighbour, h)
        int n = 0;
        for (int axis = 0; axis < 3; ++axis) {
            double best = 1e300;
            for (int dir = -1; dir <= 1; dir += 2) {
                int nb = b, na = a, nd = vx.depth;
                if (axis == 0) na += dir;
                if (axis == 1) nb += dir;
                if (axis == 2) nd += dir;
                if (na < 0 || na >= w_.na || nb < 0 || nb >= w_.nb) continue;
                const Column& col = cols_[static_cast<std::size_t>(w_.column(nb, na))];
                if (nd < col.lo || nd >= col.hi) continue;
                const std::int64_t idx = col.base + nd;
                const auto l = layer_[static_cast<std::size_t>(idx)];
                if (l >= k) continue;  // not yet assigned in this rebuild (or outside the band)
                best = std::min(best, static_cast<double>(std::abs(phi_[static_cast<std::size_t>(idx)])));
            }
            if (best < 1e300) cand[static_cast<std::size_t>(n++)] = {best, h_[axis]};
        }
        if (n == 0) return self;
        // Insertion sort of at most three candidates by |φ|.
        for (int i = 1; i < n; ++i) {
            for (int j = i; j > 0 && cand[static_cast<std::size_t>(j)].first <
                                         cand[static_cast<std::size_t>(j - 1)].first;
                 --j) {
                std::swap(cand[static_cast<std::size_t>(j)], cand[static_cast<std::size_t>(j - 1)]);
            }
        }
        // Sorted upwind solution of Σ ((d − a_i) / h_i)² = 1 over the neighbours below d.
        double d = cand[0].first + cand[0].second;
        double sa = 0.0, sb = 0.0, sc = 0.0;
        for (int m = 0; m < n; ++m) {
            const auto [am, hm] = cand[static_cast<std::size_t>(m)];
            if (m > 0 && d <= am) break;
            const double w = 1.0 / (hm * hm);
            sa += w;
            sb += am * w;
            sc += am * am * w;
            const double disc = sb * sb - sa * (sc - 1.0);
            if (disc < 0.0) break;
            d = (sb + std::sqrt(disc)) / sa;
        }
        return static_cast<float>(self > 0.0F ? d : -d);
    }

    // Eq. LS-3: φ_new = φ + dt (μ κ|∇φ| − F |∇φ|_upwind), F from Eq. LS-4.
    [[nodiscard]] float evolve(const Voxel& vx, int b, int a, double cv, double ct,
                               double contrast) const {
        // P[db][da][dd] for db, da, dd in {-1, 0, 1} (index + 1); columns clamped at the scan
        // edges (zero normal derivative). The differences below read 19 of the 27 points: three
        // rows of the centre column and of its 4 edge neighbours, the centre row only of the 4
        // corner columns (f_xy); the 8 corners of the block stay 0 and are never read.
        const float* ph = phi_.data();
        const int d0 = vx.depth;
        auto at = [&](const Column& col, int d) {
            return d < col.lo ? far_ : (d >= col.hi ? -far_ : ph[col.base + d]);
        };
        float P[3][3][3] = {};
        const int bm = std::max(b - 1, 0), bp = std::min(b + 1, w_.nb - 1);
        const int am = std::max(a - 1, 0), ap = std::min(a + 1, w_.na - 1);
        const Column* rm = cols_.data() + static_cast<std::ptrdiff_t>(bm) * w_.na;
        const Column* r0 = cols_.data() + static_cast<std::ptrdiff_t>(b) * w_.na;
        const Column* rp = cols_.data() + static_cast<std::ptrdiff_t>(bp) * w_.na;
        for (int dd = 0; dd < 3; ++dd) {
            const int d = d0 + dd - 1;
            P[1][1][dd] = at(r0[a], d);
            P[1][0][dd] = at(r0[am], d);
            P[1][2][dd] = at(r0[ap], d);
            P[0][1][dd] = at(rm[a], d);
            P[2][1][dd] = at(rp[a], d);
        }
        P[0][0][1] = at(rm[am], d0);
        P[0][2][1] = at(rm[ap], d0);
        P[2][0][1] = at(rp[am], d0);
        P[2][2][1] = at(rp[ap], d0);
        const double hx = h_[0], hy = h_[1], hz = h_[2];
        const double f0 = P[1][1][1];
        const double dxm = (f0 - P[1][0][1]) / hx, dxp = (P[1][2][1] - f0) / hx;
        const double dym = (f0 - P[0][1][1]) / hy, dyp = (P[2][1][1] - f0) / hy;
        const double dzm = (f0 - P[1][1][0]) / hz, dzp = (P[1][1][2] - f0) / hz;
        // Curvature term κ|∇φ| with central differences at the physical spacing (Eq. LS-3).
        const double fx = 0.5 * (dxm + dxp), fy = 0.5 * (dym + dyp), fz = 0.5 * (dzm + dzp);
        const double fxx = (dxp - dxm) / hx, fyy = (dyp - dym) / hy, fzz = (dzp - dzm) / hz;
        const double fxy = (P[2][2][1] - P[2][0][1] - P[0][2][1] + P[0][0][1]) / (4.0 * hx * hy);
        const double fxz = (P[1][2][2] - P[1][2][0] - P[1][0][2] + P[1][0][0]) / (4.0 * hx * hz);
        const double fyz = (P[2][1][2] - P[2][1][0] - P[0][1][2] + P[0][1][0]) / (4.0 * hy * hz);
        const double g2 = fx * fx + fy * fy + fz * fz;
        double curv = 0.0;
        if (g2 > 1e-8) {
            curv = (fx * fx * (fyy + fzz) + fy * fy * (fxx + fzz) + fz * fz * (fxx + fyy) -
                    2.0 * (fx * fy * fxy + fx * fz * fxz + fy * fz * fyz)) /
                   g2;
        }
        // Region force (Eq. LS-4), normalised by the contrast and saturated at ±1.
        const double I = image_[static_cast<std::size_t>(vx.index)];
        double F = (p_.lambda_vitreous * (I - cv) * (I - cv) - p_.lambda_tissue * (I - ct) * (I - ct)) /
                   contrast;
        F = std::clamp(F, -1.0, 1.0);
        // Osher–Sethian upwind gradient for the advection −F|∇φ|.
        auto sq = [](double v) { return v * v; };
        double grad = 0.0;
        if (F > 0.0) {
            grad = std::sqrt(sq(std::max(dxm, 0.0)) + sq(std::min(dxp, 0.0)) + sq(std::max(dym, 0.0)) +
                             sq(std::min(dyp, 0.0)) + sq(std::max(dzm, 0.0)) + sq(std::min(dzp, 0.0)));
        } else {
            grad = std::sqrt(sq(std::min(dxm, 0.0)) + sq(std::max(dxp, 0.0)) + sq(std::min(dym, 0.0)) +
                             sq(std::max(dyp, 0.0)) + sq(std::min(dzm, 0.0)) + sq(std::max(dzp, 0.0)));
        }
        // Local pseudo-time step (docs: "Time step"): the explicit limits of the advection
        // (Σ |n_i| / h_i) and of the curvature term, which diffuses only tangentially
        // (2 μ Σ (1 − n_i²) / h_i²), for this voxel's normal n. The equilibrium — all that is
        // wanted — is that of the global step; a flat ILM (n ≈ z) moves ~2.5× faster per
        // iteration than with the worst-case step over all normals.
        double dt = dt_;
        if (g2 > 1e-8) {
            const double nx2 = fx * fx / g2, ny2 = fy * fy / g2, nz2 = fz * fz / g2;
            const double adv = std::sqrt(nx2) / hx + std::sqrt(ny2) / hy + std::sqrt(nz2) / hz;
            const double dif = 2.0 * p_.mu_mm *
                               ((1.0 - nx2) / (hx * hx) + (1.0 - ny2) / (hy * hy) + (1.0 - nz2) / (hz * hz));
            dt = p_.cfl / (adv + dif);
        }
        return static_cast<float>(f0 + dt * (p_.mu_mm * curv - F * grad));
    }

    // A column's window: rows [lo, hi), row d stored at base + d (base = offset − lo); one
    // record so that a neighbour costs one cache line, not three arrays.
    struct Column {
        std::int64_t base = 0;
        int lo = 0;
        int hi = 0;
    };

    const Windows& w_;
    std::vector<Column> cols_;
    std::vector<float>& phi_;
    const std::vector<float>& image_;
    const LevelSetParams& p_;
    std::array<double, 3> h_;  // spacing along a (x), b (y), d (depth), mm
    std::vector<std::int8_t> layer_;
    std::vector<std::uint8_t> flips_;  // sign changes per voxel, saturating at 2
    std::vector<Voxel> band_;
    std::vector<Voxel> active_;
    std::vector<float> next_;
    int tile_a_ = 1, tile_b_ = 1;  // A-scans and B-scans per tile
    int tiles_x_ = 0, tiles_y_ = 0;
    std::vector<int> tile_last_change_;
    std::vector<int> column_tile_;  // tile of each column (no division per voxel)
    std::vector<std::uint8_t> tile_active_;
    std::vector<std::uint8_t> region_;
    std::vector<std::uint8_t> region_prev_;
    std::vector<Voxel> candidates_;
    std::vector<Voxel> flipped_;  // voxels that changed sign since the last rebuild
    std::vector<TileSums> tile_sums_;  // band means per tile (kBand only; empty otherwise)
    float far_ = 1.0F;
    double dt_ = 0.0;
    int patience_ = 1;
    double sum_in_ = 0.0, sum_out_ = 0.0;
    std::int64_t n_in_ = 0, n_out_ = 0;
    bool reached_edge_ = false;
};

// Fills missing device ILM values: linear interpolation along each B-scan, then the nearest
// B-scan with values for B-scans that have none. Returns false if no value exists at all.
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
    mn.resize(in.size());
    mx.resize(in.size());
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

// One [1 4 6 4 1]/16 pass along x (rows of length na) and along depth over rows [0, rows).
void binomial_pass(std::vector<float>& buf, std::vector<float>& tmp, int rows, int na) {
    auto at = [](int i, int n) { return std::clamp(i, 0, n - 1); };
    for (int r = 0; r < rows; ++r) {
        const float* in = buf.data() + static_cast<std::ptrdiff_t>(r) * na;
        float* out = tmp.data() + static_cast<std::ptrdiff_t>(r) * na;
        for (int a = 0; a < na; ++a) {
            out[a] = (in[at(a - 2, na)] + in[at(a + 2, na)] + 4.0F * (in[at(a - 1, na)] + in[at(a + 1, na)]) +
                      6.0F * in[a]) *
                     (1.0F / 16.0F);
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

// Union–find over vertices.
int find_root(std::vector<int>& parent, int i) {
    while (parent[static_cast<std::size_t>(i)] != i) {
        parent[static_cast<std::size_t>(i)] = parent[static_cast<std::size_t>(parent[static_cast<std::size_t>(i)])];
        i = parent[static_cast<std::size_t>(i)];
    }
    return i;
}

// Keeps the faces flagged in `keep` and the vertices they use.
void compact(mesh::Vertices& V, mesh::Faces& F, const std::vector<std::uint8_t>& keep) {
    std::vector<int> map(static_cast<std::size_t>(V.rows()), -1);
    int nf = 0;
    int nv = 0;
    for (Eigen::Index f = 0; f < F.rows(); ++f) {
        if (!keep[static_cast<std::size_t>(f)]) continue;
        for (int k = 0; k < 3; ++k) {
            int& m = map[static_cast<std::size_t>(F(f, k))];
            if (m < 0) m = nv++;
        }
        ++nf;
    }
    mesh::Vertices V2(nv, 3);
    for (Eigen::Index i = 0; i < V.rows(); ++i) {
        const int m = map[static_cast<std::size_t>(i)];
        if (m >= 0) V2.row(m) = V.row(i);
    }
    mesh::Faces F2(nf, 3);
    int k2 = 0;
    for (Eigen::Index f = 0; f < F.rows(); ++f) {
        if (!keep[static_cast<std::size_t>(f)]) continue;
        for (int k = 0; k < 3; ++k) F2(k2, k) = map[static_cast<std::size_t>(F(f, k))];
        ++k2;
    }
    V = std::move(V2);
    F = std::move(F2);
}

}  // namespace

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
    try {
        rofi.validate();
    } catch (const UsageError& e) {
        bad("rofi", e.what());
    }
}

namespace {

LevelSetResult run_levelset(const io::Scan& scan, const LevelSetParams& params, io::Scan* release) {
    params.validate();
    const auto& meta = scan.meta;
    const int nb = scan.num_bscans();
    const int na = meta.size_x;
    const int nz = meta.size_z;
    if (nb < 2 || na < 2 || nz < 4 || !(meta.distance_mm > 0.0) || !(meta.scale_x_mm > 0.0) ||
        !(meta.scale_z_mm > 0.0)) {
        throw AnalysisError("level-set ILM needs a volume scan (>= 2 B-scans with a B-scan distance)");
    }
    if (!scan.pixels_loaded) throw AnalysisError("level-set ILM needs the B-scan pixels");
    const auto npx = static_cast<std::size_t>(na) * static_cast<std::size_t>(nz);
    for (const auto& bs : scan.bscans) {
        if (bs.pixels.size() != npx) throw AnalysisError("level-set ILM: a B-scan has no pixels");
    }
    const double hx = meta.scale_x_mm, hy = meta.distance_mm, hz = meta.scale_z_mm;
    LevelSetResult res;
    Stopwatch t0;

    // Device ILM (pixels), missing values filled for the initialisation and clipped later.
    const auto ncol = static_cast<std::size_t>(nb) * static_cast<std::size_t>(na);
    std::vector<float> ilm(ncol);
    std::vector<std::uint8_t> valid(ncol, 1);
    for (int b = 0; b < nb; ++b) {
        for (int a = 0; a < na; ++a) {
            const float v = scan.depth_px(static_cast<int>(io::Layer::kILM), b, a);
            const auto c = static_cast<std::size_t>(b * na + a);
            if (io::is_valid(v) && v >= -1.0F && v <= static_cast<float>(nz)) {
                ilm[c] = v;
            } else {
                ilm[c] = std::numeric_limits<float>::quiet_NaN();
                valid[c] = 0;
                ++res.missing_ilm_columns;
            }
        }
    }
    if (!fill_missing(ilm, nb, na)) throw AnalysisError("level-set ILM: the scan has no device ILM");

    // Depth windows (docs: "Depth window").
    Windows w;
    w.nb = nb;
    w.na = na;
    w.nz = nz;
    {
        std::vector<float> mn, mx;
        const int ra = static_cast<int>(std::floor(params.lateral_radius_mm / hx));
        const int rb = static_cast<int>(std::floor(params.lateral_radius_mm / hy));
        box_min_max(ilm, nb, na, ra, rb, mn, mx);
        const double m = params.margin_mm / hz;
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
    }
    res.window_voxels = w.size;
    if (w.size >= (std::int64_t{1} << 32) || nb > 65535 || na > 65535) {
        throw AnalysisError("level-set ILM: the volume is too large (window voxels, B-scans or A-scans)");
    }

    // Display transform v^0.25 and per-B-scan despeckling, stored on the windows.
    std::vector<float> image(static_cast<std::size_t>(w.size));
    {
        const int pad = 2 * params.despeckle_passes;
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
            const auto& px = scan.bscans[static_cast<std::size_t>(b)].pixels;
            for (int r = 0; r < rows; ++r) {
                const float* in = px.data() + static_cast<std::ptrdiff_t>(r0 + r) * na;
                float* out = buf.data() + static_cast<std::ptrdiff_t>(r) * na;
                for (int a = 0; a < na; ++a) {
                    float v = in[a];
                    if (!(v < io::kInvalidThreshold) || std::isnan(v)) {
                        valid[static_cast<std::size_t>(b * na + a)] = 0;
                        v = 0.0F;
                    }
                    out[a] = std::sqrt(std::sqrt(std::max(v, 0.0F)));
                }
            }
            for (int k = 0; k < params.despeckle_passes; ++k) binomial_pass(buf, tmp, rows, na);
            for (int a = 0; a < na; ++a) {
                const auto c = static_cast<std::size_t>(b * na + a);
                float* dst = image.data() + w.offset[c];
                for (int d = w.lo[c]; d < w.lo[c] + w.len[c]; ++d) {
                    dst[d - w.lo[c]] = buf[static_cast<std::size_t>((d - r0) * na + a)];
                }
            }
        }
    }
    for (std::size_t c = 0; c < ncol; ++c) {
        if (!valid[c] && io::is_valid(scan.depth_px(0, static_cast<int>(c) / na, static_cast<int>(c) % na))) {
            ++res.invalid_pixel_columns;
        }
    }

    // φ0: signed vertical distance to the device ILM (positive above), made a distance
    // function on the band by the first rebuild (Eq. LS-5, LS-6).
    std::vector<float> phi(static_cast<std::size_t>(w.size));
    for (std::size_t c = 0; c < ncol; ++c) {
        for (int r = 0; r < w.len[c]; ++r) {
            phi[static_cast<std::size_t>(w.offset[c] + r)] = static_cast<float>((ilm[c] - (w.lo[c] + r)) * hz);
        }
    }
    if (release != nullptr) {
        for (auto& bs : release->bscans) bs.pixels = std::vector<float>();
        release->pixels_loaded = false;
    }
    res.prepare = t0.elapsed();

    // Evolution.
    t0 = Stopwatch();
    {
        Evolver ev(w, phi, image, params, hx, hy, hz);
        res.time_step = ev.dt();
        res.patience = ev.patience();
        ev.update_activity(0);
        ev.rebuild();
        res.band_voxels = ev.band_size();
        int it = 0;
        while (it < params.max_iterations) {
            const int nact = ev.update_activity(it + 1);
            if (nact == 0) {
                res.converged = true;
                break;
            }
            ++it;
            if (it % params.reinit_interval == 0) ev.rebuild();
            std::int64_t updated = 0;
            const std::int64_t changes = ev.step(it, updated);
            res.voxel_updates += updated;
            res.last_updated_voxels = updated;
            res.last_sign_changes = changes;
        }
        if (!res.converged && ev.update_activity(it + 1) == 0) res.converged = true;
        res.iterations = it;
        res.last_sign_change_fraction =
            res.last_updated_voxels > 0
                ? static_cast<double>(res.last_sign_changes) / static_cast<double>(res.last_updated_voxels)
                : 0.0;
        res.c_vitreous = ev.c_vitreous();
        res.c_tissue = ev.c_tissue();
        res.front_reached_window_edge = ev.reached_edge();
        if (!res.converged) {
            res.warnings.push_back("level set did not converge in " + std::to_string(it) + " iterations");
        }
        if (res.front_reached_window_edge) {
            res.warnings.push_back("level-set front reached the top or bottom of a depth window");
        }
    }
    image = std::vector<float>();  // release before the mesh stages
    res.evolve = t0.elapsed();

    // Marching cubes (vtkFlyingEdges3D) on slabs of B-scans sharing their last B-scan.
    t0 = Stopwatch();
    std::vector<Eigen::Vector3d> points;
    std::vector<std::array<int, 3>> tris;
    {
        // Rows outside a window: ±ScaleZ (vitreous above, tissue below), a distance-like value
        // for the depth edge that joins them to the window.
        const auto far = static_cast<float>(hz);
        // |φ| below 1e-2 ScaleZ (39 nm) is set to ±1e-2 ScaleZ (φ ≤ 0 counts as tissue): every
        // surface point then lies at least ~1e-2 ScaleZ inside its grid edge, far above the float
        // rounding of the output points (~5e-7 mm), so no two points coincide and the merge of
        // the slabs' shared planes by exact coordinates is unambiguous (manifold output).
        const auto eps = static_cast<float>(1e-2 * hz);
        std::unordered_map<std::uint64_t, int> shared_prev, shared_next;
        std::vector<float> dense;
        // One depth range for all slabs, so that a point on a shared B-scan plane is computed
        // from the same inputs (edge, end values, origin) in both slabs and comes out
        // bit-identical: the merge below is exact, never by tolerance.
        int k0 = nz, k1 = 0;
        for (std::size_t c = 0; c < ncol; ++c) {
            k0 = std::min(k0, w.lo[c]);
            k1 = std::max(k1, w.lo[c] + w.len[c]);
        }
        k0 -= 1;  // one row of vitreous above and of tissue below every window
        const int nk = k1 - k0 + 1;
        int b0 = 0;
        while (true) {
            const int b1 = std::min(nb - 1, b0 + params.slab_bscans - 1);
            const int ns = b1 - b0 + 1;
            dense.assign(static_cast<std::size_t>(na) * static_cast<std::size_t>(ns) * static_cast<std::size_t>(nk), 0.0F);
            for (int bb = 0; bb < ns; ++bb) {
                for (int a = 0; a < na; ++a) {
                    const auto c = static_cast<std::size_t>((b0 + bb) * na + a);
                    const int lo = w.lo[c], hi = lo + w.len[c];
                    for (int k = 0; k < nk; ++k) {
                        const int d = k0 + k;
                        float v = d < lo ? far : (d >= hi ? -far : phi[static_cast<std::size_t>(w.offset[c] + (d - lo))]);
                        if (std::abs(v) < eps) v = v > 0.0F ? eps : -eps;
                        dense[(static_cast<std::size_t>(k) * static_cast<std::size_t>(ns) + static_cast<std::size_t>(bb)) *
                                  static_cast<std::size_t>(na) +
                              static_cast<std::size_t>(a)] = v;
                    }
                }
            }
            vtkNew<vtkFloatArray> arr;
            arr->SetNumberOfComponents(1);
            arr->SetArray(dense.data(), static_cast<vtkIdType>(dense.size()), 1);
            vtkNew<vtkImageData> img;
            img->SetDimensions(na, ns, nk);
            img->SetSpacing(hx, hy, hz);
            img->SetOrigin(0.0, b0 * hy, k0 * hz);
            img->GetPointData()->SetScalars(arr);
            vtkNew<vtkFlyingEdges3D> fe;
            fe->SetInputData(img);
            fe->SetValue(0, 0.0);
            fe->ComputeNormalsOff();
            fe->ComputeGradientsOff();
            fe->ComputeScalarsOff();
            fe->InterpolateAttributesOff();
            fe->Update();
            vtkPolyData* out = fe->GetOutput();
            const vtkIdType np = out->GetNumberOfPoints();
            std::vector<int> map(static_cast<std::size_t>(np));
            shared_next.clear();
            for (vtkIdType i = 0; i < np; ++i) {
                double q[3];
                out->GetPoint(i, q);
                // Points on the first / last B-scan plane of the slab are shared with the
                // neighbouring slab: keyed by the exact (float) bits of x and depth.
                const double j = q[1] / hy;
                const bool on_first = b0 > 0 && std::abs(j - b0) < 1e-3;
                const bool on_last = std::abs(j - b1) < 1e-3;
                std::uint64_t key = 0;
                if (on_first || on_last) {
                    const float fx = static_cast<float>(q[0]);
                    const float fz = static_cast<float>(q[2]);
                    std::uint32_t ux = 0, uz = 0;
                    std::memcpy(&ux, &fx, sizeof ux);
                    std::memcpy(&uz, &fz, sizeof uz);
                    key = (static_cast<std::uint64_t>(ux) << 32U) | uz;
                }
                int index = -1;
                if (on_first) {
                    auto it = shared_prev.find(key);
                    if (it != shared_prev.end()) index = it->second;
                }
                if (index < 0) {
                    index = static_cast<int>(points.size());
                    points.emplace_back(q[0], q[1], -q[2]);
                }
                if (on_last) shared_next.emplace(key, index);
                map[static_cast<std::size_t>(i)] = index;
            }
            auto iter = vtk::TakeSmartPointer(out->GetPolys()->NewIterator());
            for (iter->GoToFirstCell(); !iter->IsDoneWithTraversal(); iter->GoToNextCell()) {
                vtkIdType n = 0;
                const vtkIdType* ids = nullptr;
                iter->GetCurrentCell(n, ids);
                if (n != 3) continue;
                const std::array<int, 3> t = {map[static_cast<std::size_t>(ids[0])], map[static_cast<std::size_t>(ids[1])],
                                              map[static_cast<std::size_t>(ids[2])]};
                if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) continue;
                tris.push_back(t);
            }
            shared_prev.swap(shared_next);
            if (b1 == nb - 1) break;
            b0 = b1;
        }
    }
    phi = std::vector<float>();
    res.raw_vertices = static_cast<std::int64_t>(points.size());
    res.raw_faces = static_cast<std::int64_t>(tris.size());
    res.marching_cubes = t0.elapsed();
    if (tris.empty()) throw AnalysisError("level-set ILM: marching cubes found no surface");

    // Clip to the valid scan area, keep the largest connected component, orient upwards.
    t0 = Stopwatch();
    mesh::Vertices V(static_cast<Eigen::Index>(points.size()), 3);
    for (std::size_t i = 0; i < points.size(); ++i) V.row(static_cast<Eigen::Index>(i)) = points[i].transpose();
    points = std::vector<Eigen::Vector3d>();
    mesh::Faces F(static_cast<Eigen::Index>(tris.size()), 3);
    for (std::size_t f = 0; f < tris.size(); ++f) {
        F.row(static_cast<Eigen::Index>(f)) << tris[f][0], tris[f][1], tris[f][2];
    }
    tris = std::vector<std::array<int, 3>>();
    {
        std::vector<std::uint8_t> keep(static_cast<std::size_t>(F.rows()), 1);
        for (Eigen::Index f = 0; f < F.rows(); ++f) {
            const Eigen::Vector3d c = (V.row(F(f, 0)) + V.row(F(f, 1)) + V.row(F(f, 2))).transpose() / 3.0;
            const int a = std::clamp(static_cast<int>(std::lround(c.x() / hx)), 0, na - 1);
            const int b = std::clamp(static_cast<int>(std::lround(c.y() / hy)), 0, nb - 1);
            if (!valid[static_cast<std::size_t>(b * na + a)]) {
                keep[static_cast<std::size_t>(f)] = 0;
                ++res.clipped_faces;
            }
        }
        if (res.clipped_faces > 0) compact(V, F, keep);
        if (F.rows() == 0) throw AnalysisError("level-set ILM: no surface inside the valid scan area");
        std::vector<int> parent(static_cast<std::size_t>(V.rows()));
        std::iota(parent.begin(), parent.end(), 0);
        for (Eigen::Index f = 0; f < F.rows(); ++f) {
            for (int k = 1; k < 3; ++k) {
                const int r0 = find_root(parent, F(f, 0));
                const int r1 = find_root(parent, F(f, k));
                if (r0 != r1) parent[static_cast<std::size_t>(r1)] = r0;
            }
        }
        std::vector<std::int64_t> count(static_cast<std::size_t>(V.rows()), 0);
        for (Eigen::Index f = 0; f < F.rows(); ++f) ++count[static_cast<std::size_t>(find_root(parent, F(f, 0)))];
        int best = 0;
        res.components = 0;
        for (std::size_t i = 0; i < count.size(); ++i) {
            if (count[i] > 0) ++res.components;
            if (count[i] > count[static_cast<std::size_t>(best)]) best = static_cast<int>(i);
        }
        if (res.components > 1) {
            for (Eigen::Index f = 0; f < F.rows(); ++f) {
                keep[static_cast<std::size_t>(f)] = find_root(parent, F(f, 0)) == best ? 1 : 0;
            }
            keep.resize(static_cast<std::size_t>(F.rows()));
            compact(V, F, keep);
        }
        // Orientation: the ILM faces the vitreous, so the area-weighted normal points up.
        double up = 0.0;
        for (Eigen::Index f = 0; f < F.rows(); ++f) {
            const Eigen::Vector3d e1 = (V.row(F(f, 1)) - V.row(F(f, 0))).transpose();
            const Eigen::Vector3d e2 = (V.row(F(f, 2)) - V.row(F(f, 0))).transpose();
            up += e1.cross(e2).z();
        }
        if (up < 0.0) F.col(1).swap(F.col(2));
    }
    res.component_clip = t0.elapsed();

    // RoFi (§5.1) with the level-set defaults.
    t0 = Stopwatch();
    res.V_raw = V;
    if (params.smooth && params.rofi.iterations > 0) {
        try {
            mesh::DenoiseResult d = mesh::rofi_denoise(V, F, params.rofi);
            res.V = std::move(d.V);
            res.rofi_iterations = d.iterations;
            for (auto& wmsg : d.warnings) res.warnings.push_back("RoFi: " + wmsg);
        } catch (const DataError& e) {
            throw AnalysisError(std::string("level-set ILM: RoFi failed: ") + e.what());
        }
    } else {
        res.V = V;
    }
    res.F = std::move(F);
    res.rofi = t0.elapsed();
    return res;
}

}  // namespace

LevelSetResult levelset_ilm(const io::Scan& scan, const LevelSetParams& params) {
    return run_levelset(scan, params, nullptr);
}

LevelSetResult levelset_ilm_releasing_pixels(io::Scan& scan, const LevelSetParams& params) {
    return run_levelset(scan, params, &scan);
}

}  // namespace octshape::retina
