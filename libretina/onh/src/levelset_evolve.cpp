// The narrow-band evolution of the level-set ILM (stage "evolve" of levelset_stages.h):
// Eq. LS-2 … LS-7 of docs/algorithms/levelset.md.

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "levelset_stages.h"

namespace octshape::retina::levelset_detail {
namespace {

constexpr std::int8_t kNotInBand = 127;
constexpr std::int8_t kCandidate = 126;  // rebuild(): listed as a candidate for layer 0

// The level-set state and the machinery of one run.
class Evolver {
public:
    Evolver(const Windows& w, std::vector<float>& phi, const std::vector<float>& image,
            const LevelSetParams& p, const Spacing& h, const float* device_ilm)
        : w_(w), phi_(phi), image_(image), p_(p), h_{h.hx, h.hy, h.hz} {
        // One B-scan (a radial scan's 2-D level set): the clamped neighbours make every
        // y-difference zero, so the curvature and the upwind gradient are the 2-D ones; the
        // y-spacing must then also leave the time steps (it is no direction of this image).
        if (w.nb == 1) h_[1] = std::numeric_limits<double>::infinity();
        const double hx = h_[0], hy = h_[1], hz = h_[2];
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
        far_ = static_cast<float>((p.band_layers + 1) * std::max({hx, w.nb == 1 ? hx : hy, hz}));
        // Band means: only band voxels with |φ| up to (W + 1) in-plane spacings (x or depth,
        // the larger; 34 µm at 384 A-scans), the farthest a band voxel of one B-scan's own
        // (2-D) band can lie. Layer 0 holds every voxel with a 6-neighbour of the other sign, so
        // where the surface is steep along the B-scans (30-90 µm apart) it spans slope x spacing
        // in depth: clear vitreous and dim deep tissue far from the edge, which pulled the
        // decision level towards the vitreous, the more the coarser the B-scans
        // (docs/algorithms/onh.md "The level set's cup-volume deficit"). A radial scan's 2-D
        // level set keeps every band voxel (bit for bit as before).
        means_reach_ = static_cast<float>((p.band_layers + 1) * std::max(hx, hz));
        const double inv_h = 1.0 / hx + 1.0 / hy + 1.0 / hz;
        const double inv_h2 = 1.0 / (hx * hx) + 1.0 / (hy * hy) + 1.0 / (hz * hz);
        dt_ = p.cfl / (inv_h + 2.0 * p.mu_mm * inv_h2);
        // The open vitreous (docs/algorithms/levelset.md "Leaks", "Vitreous mean"): rows more
        // than leak_depth_mm below the device ILM do not count towards c_vitreous.
        open_end_.assign(cols_.size(), std::numeric_limits<int>::max());
        if (device_ilm != nullptr) {
            const double rows = p.leak_depth_mm / hz;
            for (std::size_t c = 0; c < cols_.size(); ++c) {
                const double r = std::floor(static_cast<double>(device_ilm[c]) + rows) + 1.0;
                if (std::isfinite(r)) open_end_[c] = static_cast<int>(std::clamp(r, -1.0, 1e9));
            }
        }
        // Region sums for c_vitreous and c_tissue (Eq. LS-2), kept exact under sign changes.
        for (std::size_t c = 0; c < cols_.size(); ++c) {
            const Column& col = cols_[c];
            for (int d = col.lo; d < col.hi; ++d) {
                const auto i = static_cast<std::size_t>(col.base + d);
                if (phi_[i] > 0.0F) {
                    if (d >= open_end_[c]) continue;
                    sum_out_ += image_[i];
                    ++n_out_;
                } else {
                    sum_in_ += image_[i];
                    ++n_in_;
                }
            }
        }
    }

    [[nodiscard]] double dt() const { return dt_; }
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
                const bool on = iteration - last <= p_.patience;
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
                    std::array<double, 3> t_axis{1e300, 1e300, 1e300};
                    for_each_scan_neighbour(b, a, d, [&](int axis, int nb, int na, int nd) {
                        const float f1 = value(nb, na, nd);
                        if ((f1 > 0.0F) == s0) return;
                        interface = true;
                        const double denom = static_cast<double>(f0) - f1;
                        const double t = denom != 0.0 ? h_[axis] * f0 / denom : 0.0;
                        auto& t_min = t_axis[static_cast<std::size_t>(axis)];
                        t_min = std::min(t_min, std::abs(t));
                    });
                    for (const double t_min : t_axis) {
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
        if (refining_) local_levels();
    }

    // Starts the refinement under lips (docs/algorithms/levelset.md "Overhang volumes"): each
    // column's top crossing (the first tissue row) is fixed from φ at the end of the main run.
    // A column holds a cavity under a lip when it has vitreous more than leak_depth_mm below its
    // top crossing; the voxels that deep in such columns and in those within band_layers
    // A-scans and one B-scan of them are "hidden" (the cavity's ceiling and floor, and the
    // hidden wall beyond the cavity's tip). A steep cup wall is not: no column under it holds
    // vitreous below tissue. The tiles holding a hidden interface voxel are woken (the caller
    // rebuilds the band over them). Returns the number of hidden interface voxels (0: nothing
    // lies under a lip, the run is over and φ is unchanged).
    std::int64_t begin_refinement(int iteration) {
        hidden_rows_ = p_.leak_depth_mm / h_[2];
        top_.assign(cols_.size(), 0);
        std::vector<std::uint8_t> cavity(cols_.size(), 0);
        bool any = false;
        for (std::size_t c = 0; c < cols_.size(); ++c) {
            const Column& col = cols_[c];
            int top = col.hi;
            for (int d = col.lo; d < col.hi; ++d) {
                const bool vitreous = phi_[static_cast<std::size_t>(col.base + d)] > 0.0F;
                if (top == col.hi) {
                    if (!vitreous) top = d;
                } else if (vitreous && static_cast<double>(d - top) > hidden_rows_) {
                    cavity[c] = 1;
                    any = true;
                    break;
                }
            }
            top_[c] = top;
        }
        if (!any) return 0;
        lipped_.assign(cols_.size(), 0);
        const int r = p_.band_layers;
        const int rb = w_.nb > 1 ? 1 : 0;
        for (int b = 0; b < w_.nb; ++b) {
            for (int a = 0; a < w_.na; ++a) {
                if (!cavity[static_cast<std::size_t>(w_.column(b, a))]) continue;
                for (int nb = std::max(0, b - rb); nb <= std::min(w_.nb - 1, b + rb); ++nb) {
                    for (int na = std::max(0, a - r); na <= std::min(w_.na - 1, a + r); ++na) {
                        lipped_[static_cast<std::size_t>(w_.column(nb, na))] = 1;
                    }
                }
            }
        }
        std::int64_t hidden = 0;
        std::vector<std::uint8_t> woken(tile_last_change_.size(), 0);
        for (int b = 0; b < w_.nb; ++b) {
            for (int a = 0; a < w_.na; ++a) {
                const Column& col = cols_[static_cast<std::size_t>(w_.column(b, a))];
                for (int d = col.lo; d < col.hi; ++d) {
                    if (!is_hidden(b, a, d)) continue;
                    const bool s0 = phi_[static_cast<std::size_t>(col.base + d)] > 0.0F;
                    bool interface = false;
                    for_each_scan_neighbour(b, a, d, [&](int, int nb, int na, int nd) {
                        if ((value(nb, na, nd) > 0.0F) != s0) interface = true;
                    });
                    if (!interface) continue;
                    ++hidden;
                    woken[static_cast<std::size_t>(tile_of(b, a))] = 1;
                }
            }
        }
        if (hidden == 0) return 0;
        for (std::size_t t = 0; t < woken.size(); ++t) {
            if (woken[t]) tile_last_change_[t] = iteration;
        }
        refining_ = true;
        return hidden;
    }
    [[nodiscard]] double mean_local_level() const { return level_n_ > 0 ? level_sum_ / level_n_ : 0.0; }
    [[nodiscard]] std::int64_t local_level_voxels() const { return level_n_; }

    // One explicit step (Eq. LS-3, LS-4) on the band voxels of active tiles, layers < W.
    // Returns the number of voxels that changed sign; `updated` counts the voxels updated.
    std::int64_t step(int iteration, std::int64_t& updated) {
        const double cv = c_vitreous();
        const double ct = c_tissue();
        const double contrast = std::max((ct - cv) * (ct - cv), 1e-12);
        active_.clear();
        next_.clear();
        for (std::size_t k = 0; k < band_.size(); ++k) {
            const Voxel& vx = band_[k];
            if (layer_[static_cast<std::size_t>(vx.index)] >= p_.band_layers) continue;
            const int b = vx.b;
            const int a = vx.a;
            if (!tile_active_[static_cast<std::size_t>(tile_of(b, a))]) continue;
            active_.push_back(vx);
            // Under a lip (refinement): the same speed, about this voxel's own decision level.
            const float level = k < level_.size() ? level_[k] : std::numeric_limits<float>::quiet_NaN();
            if (std::isnan(level)) {
                next_.push_back(evolve(vx, b, a, cv, ct, contrast));
            } else {
                const double half = 0.5 * (ct - cv);
                next_.push_back(evolve(vx, b, a, level - half, level + half, contrast));
            }
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
            const bool open = is_open(active_[k]);
            // Band means: only a voxel the sums hold moves from one sum to the other, and
            // vitreous counts only where it is open.
            if (tile_sums_.empty() || counted_[i] != 0) {
                if (open) {
                    sum_out_ += sign * v;
                    n_out_ += after ? 1 : -1;
                }
                sum_in_ -= sign * v;
                n_in_ -= after ? 1 : -1;
            }
            if (!tile_sums_.empty() && counted_[i] != 0) {
                TileSums& ts = tile_sums_[static_cast<std::size_t>(tile_of(active_[k].b, active_[k].a))];
                if (open) {
                    ts.out += sign * v;
                    ts.n_out += after ? 1 : -1;
                }
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
    // A voxel under a lip (refinement): more than leak_depth_mm below its column's top
    // crossing, in a column that holds or lies beside a cavity under a lip.
    [[nodiscard]] bool is_hidden(int b, int a, int d) const {
        const auto c = static_cast<std::size_t>(w_.column(b, a));
        return lipped_[c] != 0 && static_cast<double>(d - top_[c]) > hidden_rows_;
    }

    // The refinement's decision levels: for every updated band voxel under a lip, the midpoint
    // of the means of the hidden band voxels on either side of the interface in a box of
    // ±W A-scans, ±1 B-scan (volumes) and ±W rows around it — the midpoint of the local edge,
    // whatever the tissue's brightness there. NaN (the global level) where a side has fewer
    // than kMinSide voxels or the local contrast is below a quarter of the global one (no
    // edge there: a shadow's tissue against a leak).
    void local_levels() {
        constexpr int kMinSide = 4;
        level_.assign(band_.size(), std::numeric_limits<float>::quiet_NaN());
        const int r = p_.band_layers;
        const int rb = w_.nb > 1 ? 1 : 0;
        const double global = c_tissue() - c_vitreous();
        for (std::size_t k = 0; k < band_.size(); ++k) {
            const Voxel& vx = band_[k];
            if (layer_[static_cast<std::size_t>(vx.index)] >= p_.band_layers) continue;
            if (!tile_active_[static_cast<std::size_t>(tile_of(vx.b, vx.a))]) continue;
            if (!is_hidden(vx.b, vx.a, vx.depth)) continue;
            double s_out = 0.0, s_in = 0.0;
            int n_out = 0, n_in = 0;
            for (int nb = std::max(0, vx.b - rb); nb <= std::min(w_.nb - 1, vx.b + rb); ++nb) {
                for (int na = std::max(0, vx.a - r); na <= std::min(w_.na - 1, vx.a + r); ++na) {
                    const Column& col = cols_[static_cast<std::size_t>(w_.column(nb, na))];
                    for (int nd = std::max(col.lo, vx.depth - r); nd < std::min(col.hi, vx.depth + r + 1); ++nd) {
                        const auto i = static_cast<std::size_t>(col.base + nd);
                        if (layer_[i] > p_.band_layers || !is_hidden(nb, na, nd)) continue;
                        if (phi_[i] > 0.0F) {
                            s_out += image_[i];
                            ++n_out;
                        } else {
                            s_in += image_[i];
                            ++n_in;
                        }
                    }
                }
            }
            if (n_out < kMinSide || n_in < kMinSide) continue;
            const double m_out = s_out / n_out, m_in = s_in / n_in;
            if (!(m_in - m_out >= 0.25 * global)) continue;
            // Under a lip the tissue is dimmer than where the global means are taken, so the
            // hidden edge's midpoint lies below the global level; one above it has tissue on its
            // vitreous side (a leak into a shadow), and taking it would pull the front on.
            if (0.5 * (m_out + m_in) > 0.5 * (c_vitreous() + c_tissue())) continue;
            level_[k] = static_cast<float>(0.5 * (m_out + m_in));
            level_sum_ += level_[k];
            ++level_n_;
        }
    }

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
        if (counted_.empty()) counted_.assign(layer_.size(), 0);
        for (std::size_t t = 0; t < region_.size(); ++t) {
            if (region_[t]) tile_sums_[t] = TileSums{};
        }
        for (const Voxel& vx : band_) {
            const auto i = static_cast<std::size_t>(vx.index);
            counted_[i] = std::abs(phi_[i]) <= means_reach_ ? 1 : 0;
            if (counted_[i] == 0) continue;
            TileSums& ts = tile_sums_[static_cast<std::size_t>(tile_of(vx.b, vx.a))];
            if (phi_[i] > 0.0F) {
                if (!is_open(vx)) continue;
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
    // Vitreous here counts towards c_vitreous: not deeper than leak_depth_mm below the device
    // ILM (every voxel without a device ILM given).
    [[nodiscard]] bool is_open(const Voxel& vx) const {
        return vx.depth < open_end_[static_cast<std::size_t>(w_.column(vx.b, vx.a))];
    }
    [[nodiscard]] int tile_of(int b, int a) const {
        return column_tile_[static_cast<std::size_t>(w_.column(b, a))];
    }
    [[nodiscard]] bool in_region(int b, int a) const {
        return region_[static_cast<std::size_t>(tile_of(b, a))] != 0;
    }
    // Calls f(axis, b, a, d) for each of the 6 face neighbours of (b, a, d) inside the scan's
    // columns (axis 0: A-scans, 1: B-scans, 2: rows; any row: value() answers outside a window).
    template <class F>
    void for_each_scan_neighbour(int b, int a, int d, F&& f) const {
        for (int axis = 0; axis < 3; ++axis) {
            for (int dir = -1; dir <= 1; dir += 2) {
                int nb = b, na = a, nd = d;
                if (axis == 0) na += dir;
                if (axis == 1) nb += dir;
                if (axis == 2) nd += dir;
                if (na < 0 || na >= w_.na || nb < 0 || nb >= w_.nb) continue;
                f(axis, nb, na, nd);
            }
        }
    }
    // Calls f(neighbour) for each of the 6 face neighbours of vx that lie in an evolving tile
    // and inside their column's window.
    template <class F>
    void for_each_neighbour(const Voxel& vx, F&& f) const {
        for_each_scan_neighbour(vx.b, vx.a, vx.depth, [&](int, int nb, int na, int nd) {
            if (!in_region(nb, na)) return;
            const Column& col = cols_[static_cast<std::size_t>(w_.column(nb, na))];
            if (nd < col.lo || nd >= col.hi) return;
            f(make_voxel(col.base + nd, nb, na, nd));
        });
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
    std::vector<int> open_end_;  // per column: first row whose vitreous is not open (is_open)
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
    float means_reach_ = 1.0F;          // band means: |φ| up to this (mm)
    std::vector<std::uint8_t> counted_;  // band voxel held by the band-mean sums
    double dt_ = 0.0;
    double sum_in_ = 0.0, sum_out_ = 0.0;
    std::int64_t n_in_ = 0, n_out_ = 0;
    bool reached_edge_ = false;
    // Refinement under lips (begin_refinement): each column's top crossing, the depth (rows)
    // below it that counts as hidden, the local decision level of each band voxel (NaN: global).
    bool refining_ = false;
    std::vector<int> top_;
    std::vector<std::uint8_t> lipped_;  // column holds, or lies beside, a cavity under a lip
    double hidden_rows_ = 0.0;
    std::vector<float> level_;
    double level_sum_ = 0.0;  // over every local level set (a diagnostic)
    std::int64_t level_n_ = 0;
};

}  // namespace

void evolve(const Windows& w, std::vector<float>& phi, const std::vector<float>& image,
            const LevelSetParams& params, const Spacing& h, LevelSetResult& res,
            const float* device_ilm) {
    Evolver ev(w, phi, image, params, h, device_ilm);
    res.time_step = ev.dt();
    ev.update_activity(0);
    ev.rebuild();
    res.band_voxels = ev.band_size();
    int it = 0;
    // Steps until every tile is frozen or `cap` iterations have been run in all; true if frozen.
    auto run = [&](int cap) {
        while (it < cap) {
            if (ev.update_activity(it + 1) == 0) return true;
            ++it;
            if (it % params.reinit_interval == 0) ev.rebuild();
            std::int64_t updated = 0;
            const std::int64_t changes = ev.step(it, updated);
            res.voxel_updates += updated;
            res.last_updated_voxels = updated;
            res.last_sign_changes = changes;
        }
        return ev.update_activity(it + 1) == 0;
    };
    res.converged = run(params.max_iterations);
    // Under a lip, each voxel's own decision level (docs/algorithms/levelset.md "Overhang
    // volumes"): only once the global force has opened the cavity.
    if (params.hidden_local_level && ev.begin_refinement(it) > 0) {
        ev.update_activity(it + 1);
        ev.rebuild();
        const int start = it;
        // The interface moves from one level to the other on the same edge (a pixel or two);
        // a quarter of the main run's cap bounds the time where a leak keeps it moving.
        const bool refined = run(it + std::max(1, params.max_iterations / 4));
        res.converged = res.converged && refined;
        res.refine_iterations = it - start;
        res.local_level_voxels = ev.local_level_voxels();
        res.mean_local_level = ev.mean_local_level();
    }
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

}  // namespace octshape::retina::levelset_detail
