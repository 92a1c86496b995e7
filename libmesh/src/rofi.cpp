#include "octshape/mesh/rofi.h"

#include "octshape/error.h"
#include "octshape/mesh/simd_exp.h"
#include "octshape/mesh/folds.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <string>
#include <type_traits>

#include "denoise_setup.h"
#include "parallel.h"
#include "simd.h"

namespace octshape::mesh {
namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t0) {
    return std::chrono::duration<double>(Clock::now() - t0).count();
}

// The pairs of Ω whose weight f g is computed once per iteration, in one flat list (no
// per-row loop, so no branch on a row's length): pair k = (first[k], second[k]), and
// slot_pair[p] = the pair whose weight slot p of Ω uses. A pair (i, j) with j ∈ Ω_i and
// i ∈ Ω_j (nearly all) is listed once and used by both slots; a pair with j ∈ Ω_i but i ∉ Ω_j
// is listed for slot p alone. The centre slot of a row has no pair (its weight is 1):
// slot_pair = −1. The list is padded to a multiple of kPairBlock with the pair (0, 0).
constexpr int kPairBlock = 4;

// What dropping the fidelity term λ_I (D_i + D_t,i) of Eq. 5.9 may move a vertex in a whole
// run, in units of its longest edge (rofi.md, "Issue 35 (session 17b)"). The vertex step drops
// it once λ_I < negligible_lambda(decay) (from the 42nd iteration at the defaults λ_I 0.2,
// decay 0.6; never for decay 1): since D_i is a weighted mean of v_i's neighbours minus v_i,
// |λ_I (D_i + D_t,i)| ≤ 2 λ_I |D_i| ≤ 2 λ_I × v_i's longest edge, so all the dropped terms
// together (λ_I falling geometrically) move v_i by less than 2 negligible_lambda / (1 − decay)
// = kLambdaBudget of that edge: below what the test
// Rofi.RigidMotionOfTheInputMovesTheOutputTheSameWay grants rounding alone (1e−9 absolute,
// ~1e−8 of an edge). What later iterations make of it is measured in rofi.md (MSAE and
// flips unchanged).
constexpr double kLambdaBudget = 1e-9;

double negligible_lambda(double decay) { return 0.5 * kLambdaBudget * (1.0 - decay); }

struct PairTable {
    std::vector<int> first;      // pair k = (first[k], second[k])
    std::vector<int> second;
    std::vector<int> slot_pair;  // per slot of Ω
};

// Rows list f_i first and then ascending indices (mesh.h). Row j is searched for i only by
// the rows i > j, in ascending order of i, so a cursor per row that only moves forward finds
// every mirror slot in one sweep of the row (no bisection per slot). The loops index raw
// pointers taken once (through the vectors, each push_back made GCC reload their data
// pointers: 11.6 M more instructions at Fandisk0.3 ×16).
PairTable pair_table(const Csr& omega) {
    PairTable t;
    const int rows = omega.rows();
    t.slot_pair.assign(omega.items.size(), -1);
    std::vector<int> cursor(omega.offsets.begin(), omega.offsets.end() - 1);
    const int* const off = omega.offsets.data();
    const int* const items = omega.items.data();
    int* const slot_pair = t.slot_pair.data();
    int* const cur = cursor.data();
    for (int r = 0; r < rows; ++r) ++cur[r];  // past f_r
    const auto add = [&](int i, int j) {
        t.first.push_back(i);
        t.second.push_back(j);
        return static_cast<int>(t.first.size()) - 1;
    };
    t.first.reserve(omega.items.size() / 2 + kPairBlock);
    t.second.reserve(omega.items.size() / 2 + kPairBlock);
    for (int i = 0; i < rows; ++i) {
        for (int p = off[i] + 1; p < off[i + 1]; ++p) {
            const int j = items[p];
            if (j >= i) continue;
            const int k = add(i, j);
            slot_pair[p] = k;
            // The mirror slot of i in row j, if any.
            int c = cur[j];
            const int e = off[j + 1];
            while (c < e && items[c] < i) ++c;
            cur[j] = c;
            if (c < e && items[c] == i) slot_pair[c] = k;
        }
    }
    // The slots still without a pair: j > i with i ∉ Ω_j.
    for (int i = 0; i < rows; ++i) {
        for (int p = off[i] + 1; p < off[i + 1]; ++p) {
            if (slot_pair[p] < 0) slot_pair[p] = add(i, items[p]);
        }
    }
    while (t.first.size() % kPairBlock != 0) add(0, 0);
    return t;
}

// The differences of four pairs of face records, lane l: rec[a[l]] − rec[b[l]].
struct Diffs4 {
    detail::V4d nx, ny, nz;  // n_a − n_b
    detail::V4d cx, cy, cz;  // c_a − c_b
};

// Half h of a face record: 0 = normal and area, 1 = centroid and padding.
[[gnu::always_inline]] inline detail::V4d half(const detail::FaceState& f, int h) {
    static_assert(sizeof(detail::FaceState) == 2 * sizeof(detail::V4d));
    detail::V4d v;
    std::memcpy(&v, reinterpret_cast<const unsigned char*>(&f) + h * sizeof v, sizeof v);
    return v;
}

// The lanes 0, 1, 2 of d0..d3 as three vectors: x = {d0[0], d1[0], d2[0], d3[0]}, and so on.
[[gnu::always_inline]] inline void transpose3(const detail::V4d& d0, const detail::V4d& d1,
                                              const detail::V4d& d2, const detail::V4d& d3,
                                              detail::V4d& x, detail::V4d& y, detail::V4d& z) {
    const detail::V4d t0 = __builtin_shufflevector(d0, d1, 0, 4, 2, 6);
    const detail::V4d t1 = __builtin_shufflevector(d0, d1, 1, 5, 3, 7);
    const detail::V4d t2 = __builtin_shufflevector(d2, d3, 0, 4, 2, 6);
    const detail::V4d t3 = __builtin_shufflevector(d2, d3, 1, 5, 3, 7);
    x = __builtin_shufflevector(t0, t2, 0, 1, 4, 5);
    y = __builtin_shufflevector(t1, t3, 0, 1, 4, 5);
    z = __builtin_shufflevector(t0, t2, 2, 3, 6, 7);
}

// kWide (the AVX2 copy): each record is loaded as two 4-double halves, the halves of each
// pair subtracted and the four difference vectors transposed into lanes. Otherwise (the
// baseline copy, where GCC lowers 4-double shuffles poorly) lane by lane from scalar loads.
// The same IEEE subtraction per component either way.
template <bool kWide>
[[gnu::always_inline]] inline void diffs4(const detail::FaceState* rec, const int* a,
                                          const int* b, Diffs4& d) {
    if constexpr (kWide) {
        detail::V4d n[4];
        detail::V4d c[4];
        for (int l = 0; l < 4; ++l) {
            const detail::FaceState& fa = rec[a[l]];
            const detail::FaceState& fb = rec[b[l]];
            n[l] = half(fa, 0) - half(fb, 0);
            c[l] = half(fa, 1) - half(fb, 1);
        }
        transpose3(n[0], n[1], n[2], n[3], d.nx, d.ny, d.nz);
        transpose3(c[0], c[1], c[2], c[3], d.cx, d.cy, d.cz);
    } else {
        const detail::FaceState* A[4] = {rec + a[0], rec + a[1], rec + a[2], rec + a[3]};
        const detail::FaceState* B[4] = {rec + b[0], rec + b[1], rec + b[2], rec + b[3]};
        const auto lanes = [&](const detail::FaceState* const* f, auto field) {
            return detail::V4d{field(*f[0]), field(*f[1]), field(*f[2]), field(*f[3])};
        };
        const auto nx = [](const detail::FaceState& f) { return f.normal[0]; };
        const auto ny = [](const detail::FaceState& f) { return f.normal[1]; };
        const auto nz = [](const detail::FaceState& f) { return f.normal[2]; };
        const auto cx = [](const detail::FaceState& f) { return f.centroid[0]; };
        const auto cy = [](const detail::FaceState& f) { return f.centroid[1]; };
        const auto cz = [](const detail::FaceState& f) { return f.centroid[2]; };
        d.nx = lanes(A, nx) - lanes(B, nx);
        d.ny = lanes(A, ny) - lanes(B, ny);
        d.nz = lanes(A, nz) - lanes(B, nz);
        d.cx = lanes(A, cx) - lanes(B, cx);
        d.cy = lanes(A, cy) - lanes(B, cy);
        d.cz = lanes(A, cz) - lanes(B, cz);
    }
}

// The differences of eight pairs (the AVX-512 copy), lane l: rec[a[l]] − rec[b[l]].
struct Diffs8 {
    detail::V8d nx, ny, nz;  // n_a − n_b
    detail::V8d cx, cy, cz;  // c_a − c_b
};

// Each record is loaded whole (8 doubles), the records of each pair subtracted (lanes 0–2:
// normal, 3: area, 4–6: centroid, 7: padding, the same IEEE subtractions as diffs4) and the
// eight difference vectors transposed into lanes in three rounds of two-source shuffles.
[[gnu::always_inline]] inline void diffs8(const detail::FaceState* rec, const int* a,
                                          const int* b, Diffs8& d) {
    using detail::V8d;
    static_assert(sizeof(detail::FaceState) == sizeof(V8d));
    V8d r[8];
    for (int l = 0; l < 8; ++l) {
        V8d ra;
        V8d rb;
        std::memcpy(&ra, rec + a[l], sizeof ra);
        std::memcpy(&rb, rec + b[l], sizeof rb);
        r[l] = ra - rb;
    }
    // lo[m]: the even lanes of r[2m] and r[2m + 1] interleaved; hi[m]: the odd lanes.
    V8d lo[4];
    V8d hi[4];
    for (int m = 0; m < 4; ++m) {
        lo[m] = __builtin_shufflevector(r[2 * m], r[2 * m + 1], 0, 8, 2, 10, 4, 12, 6, 14);
        hi[m] = __builtin_shufflevector(r[2 * m], r[2 * m + 1], 1, 9, 3, 11, 5, 13, 7, 15);
    }
    // Quad q (records 4q .. 4q + 3): x = lanes 0 then lanes 4, y = 1 then 5, z = 2 then 6.
    V8d x[2];
    V8d y[2];
    V8d z[2];
    for (int q = 0; q < 2; ++q) {
        x[q] = __builtin_shufflevector(lo[2 * q], lo[2 * q + 1], 0, 1, 8, 9, 4, 5, 12, 13);
        y[q] = __builtin_shufflevector(hi[2 * q], hi[2 * q + 1], 0, 1, 8, 9, 4, 5, 12, 13);
        z[q] = __builtin_shufflevector(lo[2 * q], lo[2 * q + 1], 2, 3, 10, 11, 6, 7, 14, 15);
    }
    d.nx = __builtin_shufflevector(x[0], x[1], 0, 1, 2, 3, 8, 9, 10, 11);
    d.cx = __builtin_shufflevector(x[0], x[1], 4, 5, 6, 7, 12, 13, 14, 15);
    d.ny = __builtin_shufflevector(y[0], y[1], 0, 1, 2, 3, 8, 9, 10, 11);
    d.cy = __builtin_shufflevector(y[0], y[1], 4, 5, 6, 7, 12, 13, 14, 15);
    d.nz = __builtin_shufflevector(z[0], z[1], 0, 1, 2, 3, 8, 9, 10, 11);
    d.cz = __builtin_shufflevector(z[0], z[1], 4, 5, 6, 7, 12, 13, 14, 15);
}

// The running sum of Eq. 5.1: lanes 0–2 of a V4d (kWide) or three scalars.
struct Sum3 {
    double x, y, z;
};
template <bool kWide>
using Sum = std::conditional_t<kWide, detail::V4d, Sum3>;

// The per-row work of Eq. 5.1 on flat arrays (Ω in CSR, the pair table and weights, the face
// records). The pair weights are computed four pairs at a time (detail::V4d lanes, simd.h);
// each lane does the same operations whatever lanes it shares a vector with, so a weight has
// the same bits in either PairWeights mode and on either instruction set.
struct PairKernel {
    const int* off;                   // Ω offsets
    const int* items;                 // Ω items: f_i, then ascending indices
    const int* first;                 // PairTable
    const int* second;
    const int* slot_pair;
    float* pair_weight;               // f g per pair of the table, rounded to float
    const detail::FaceState* rec;     // current normal, area, centroid
    detail::FaceState* out;           // filtered normal ñ_i, area, centroid
    double inv_s2;                    // 1 / σ_s²
    double inv_two_sc2;               // 1 / (2 σ_c²)
    double inv_two_s2;                // 1 / (2 σ_s²)

    // f(|c_a − c_b|; σ_c) g(|n_a − n_b|; σ_s) of the pairs (a[l], b[l]), lane l. Symmetric in
    // a and b bit for bit (the squares of negated differences are equal).
    template <bool kTukey, bool kWide>
    [[gnu::always_inline]] void weights4(const int* a, const int* b, detail::V4d& w) const {
        Diffs4 d;
        diffs4<kWide>(rec, a, b, d);
        weight_lanes<kTukey, detail::V4d, detail::V4i>(d, w);
    }

    // The same for eight pairs (the AVX-512 copy): the same operations in every lane.
    template <bool kTukey>
    [[gnu::always_inline]] void weights8(const int* a, const int* b, detail::V8d& w) const {
        Diffs8 d;
        diffs8(rec, a, b, d);
        weight_lanes<kTukey, detail::V8d, detail::V8i>(d, w);
    }

    // f g from the differences d (Diffs4 or Diffs8), V = V4d or V8d.
    template <bool kTukey, class V, class VI, class D>
    [[gnu::always_inline]] void weight_lanes(const D& d, V& w) const {
        const V x2 = d.nx * d.nx + d.ny * d.ny + d.nz * d.nz;  // |n_a − n_b|²
        const V d2 = d.cx * d.cx + d.cy * d.cy + d.cz * d.cz;  // |c_a − c_b|²
        if constexpr (kTukey) {
            // Eq. 5.3 without its constant ½ (it cancels in K_i): (1 − x²/σ_s²)² for x ≤ σ_s,
            // else 0 — no diffusion across the cut-off. Eq. 5.2's Gaussian closeness.
            const V t = detail::splat_as<V>(1.0) - x2 * detail::splat_as<V>(inv_s2);
            V e{};
            detail::exp_lanes_t<V, VI>(-d2 * detail::splat_as<V>(inv_two_sc2), e);
            w = t > detail::splat_as<V>(0.0) ? t * t * e : detail::splat_as<V>(0.0);
        } else {
            detail::exp_lanes_t<V, VI>(
                -d2 * detail::splat_as<V>(inv_two_sc2) - x2 * detail::splat_as<V>(inv_two_s2), w);
        }
    }

    // The weights of the pair blocks [b0, b1) of the table.
    template <bool kTukey, bool kWide>
    [[gnu::always_inline]] void pairs(int b0, int b1) const {
        detail::V4d v{};
        for (int k = b0 * kPairBlock; k < b1 * kPairBlock; k += kPairBlock) {
            weights4<kTukey, kWide>(first + k, second + k, v);
            const detail::V4f f = __builtin_convertvector(v, detail::V4f);
            std::memcpy(pair_weight + k, &f, sizeof f);
        }
    }

    // The weights of the pair blocks [b0, b1), eight pairs at a time (the AVX-512 copy; an
    // odd last block by weights4: the same bits).
    template <bool kTukey>
    [[gnu::always_inline]] void pairs8(int b0, int b1) const {
        int k = b0 * kPairBlock;
        const int e = b1 * kPairBlock;
        detail::V8d v{};
        for (; k + 8 <= e; k += 8) {
            weights8<kTukey>(first + k, second + k, v);
            const detail::V8f f = __builtin_convertvector(v, detail::V8f);
            std::memcpy(pair_weight + k, &f, sizeof f);
        }
        detail::V4d u{};
        for (; k < e; k += kPairBlock) {
            weights4<kTukey, true>(first + k, second + k, u);
            const detail::V4f f = __builtin_convertvector(u, detail::V4f);
            std::memcpy(pair_weight + k, &f, sizeof f);
        }
    }

    // The weights of row i's slots [p0, p1) into w[0 .. p1 − p0) (PairWeights::kPerRow),
    // rounded to float as the shared ones are.
    template <bool kTukey, bool kWide>
    [[gnu::always_inline]] void row_weights(int i, int p0, int p1, float* w) const {
        const int centre[4] = {i, i, i, i};
        int p = p0;
        detail::V4d v{};
        for (; p + 4 <= p1; p += 4) {
            weights4<kTukey, kWide>(centre, items + p, v);
            const detail::V4f f = __builtin_convertvector(v, detail::V4f);
            std::memcpy(w + (p - p0), &f, sizeof f);
        }
        if (p < p1) {  // the last 1–3 slots; the other lanes pair f_i with itself, unused
            int j[4] = {i, i, i, i};
            for (int l = 0; p + l < p1; ++l) j[l] = items[p + l];
            weights4<kTukey, kWide>(centre, j, v);
            const detail::V4f f = __builtin_convertvector(v, detail::V4f);
            for (int l = 0; p + l < p1; ++l) w[p - p0 + l] = f[l];
        }
    }

    // Eq. 5.1: ñ_i = normalise(Σ_j a_j w_ij n_j) over Ω_i in row order (K_i cancels in the
    // normalisation); the centre face has w = 1. kWide (the AVX2 copy): the sum is lanes 0–2
    // of a V4d (x, y, z, each added in row order; lane 3 adds a_j w_ij a_j alongside and is
    // not used); otherwise three scalars: the same operations. 0.0 + keeps the bits of a sum
    // that starts from zero (−0 becomes +0).
    template <bool kWide>
    [[gnu::always_inline]] Sum<kWide> sum_start(int i) const {
        const detail::FaceState& fi = rec[i];
        if constexpr (kWide) {
            return detail::splat(0.0) + detail::splat(fi.area) * half(fi, 0);
        } else {
            return {0.0 + fi.area * fi.normal[0], 0.0 + fi.area * fi.normal[1],
                    0.0 + fi.area * fi.normal[2]};
        }
    }

    // Adds slot p's term with the weight w (f g of its pair).
    template <bool kWide>
    [[gnu::always_inline]] void sum_add(int p, double w, Sum<kWide>& s) const {
        const detail::FaceState& fj = rec[items[p]];
        if constexpr (kWide) {
            s = s + detail::splat(fj.area * w) * half(fj, 0);
        } else {
            const double aw = fj.area * w;
            s.x += aw * fj.normal[0];
            s.y += aw * fj.normal[1];
            s.z += aw * fj.normal[2];
        }
    }

    // Writes out[i]: ñ_i, and the area and centroid of rec[i].
    template <bool kWide>
    [[gnu::always_inline]] void sum_finish(int i, const Sum<kWide>& s) const {
        double sx;
        double sy;
        double sz;
        if constexpr (kWide) {
            sx = s[0];
            sy = s[1];
            sz = s[2];
        } else {
            sx = s.x;
            sy = s.y;
            sz = s.z;
        }
        const double len = std::sqrt(sx * sx + sy * sy + sz * sz);
        detail::FaceState& o = out[i];
        o = rec[i];
        if (len > 0.0) {  // else keep n_i
            if constexpr (kWide) {
                const detail::V4d n = s / detail::splat(len);
                o.normal[0] = n[0];
                o.normal[1] = n[1];
                o.normal[2] = n[2];
            } else {
                o.normal[0] = sx / len;
                o.normal[1] = sy / len;
                o.normal[2] = sz / len;
            }
        }
    }

    // Row i from the pair weights.
    template <bool kWide>
    [[gnu::always_inline]] void row_sum(int i) const {
        Sum<kWide> s = sum_start<kWide>(i);
        for (int p = off[i] + 1; p < off[i + 1]; ++p) {
            sum_add<kWide>(p, pair_weight[slot_pair[p]], s);
        }
        sum_finish<kWide>(i, s);
    }

    // Row i with its weights computed here in blocks (PairWeights::kPerRow), the same bits.
    template <bool kTukey, bool kWide>
    [[gnu::always_inline]] void row_sum_per_row(int i) const {
        Sum<kWide> s = sum_start<kWide>(i);
        const int e = off[i + 1];
        constexpr int kBlock = 64;
        float block[kBlock];
        for (int p0 = off[i] + 1; p0 < e; p0 += kBlock) {
            const int p1 = std::min(e, p0 + kBlock);
            row_weights<kTukey, kWide>(i, p0, p1, block);
            for (int p = p0; p < p1; ++p) sum_add<kWide>(p, block[p - p0], s);
        }
        sum_finish<kWide>(i, s);
    }
};

// The passes, one copy per instruction set (simd.h): kind 0 = the pair weights of pair blocks
// [begin, end), 1 = the sums of rows [begin, end) from them, 2 = the sums with the weights
// computed per row.
template <bool kTukey, bool kWide>
[[gnu::always_inline]] inline void rows_impl(const PairKernel& k, int kind, int begin,
                                             int end) {
    if (kind == 0) {
        k.pairs<kTukey, kWide>(begin, end);
    } else if (kind == 1) {
        for (int i = begin; i < end; ++i) k.row_sum<kWide>(i);
    } else {
        for (int i = begin; i < end; ++i) k.row_sum_per_row<kTukey, kWide>(i);
    }
}

void rows_baseline(const PairKernel& k, bool tukey, int kind, int begin, int end) {
    if (tukey) {
        rows_impl<true, false>(k, kind, begin, end);
    } else {
        rows_impl<false, false>(k, kind, begin, end);
    }
}

__attribute__((target("avx2"))) void rows_avx2(const PairKernel& k, bool tukey, int kind,
                                               int begin, int end) {
    if (tukey) {
        rows_impl<true, true>(k, kind, begin, end);
    } else {
        rows_impl<false, true>(k, kind, begin, end);
    }
}

// The AVX-512 copy: the pair weights eight at a time; the sums as in the AVX2 copy.
__attribute__((target("avx512f,avx512dq,avx512vl,avx2"))) void rows_avx512(
    const PairKernel& k, bool tukey, int kind, int begin, int end) {
    if (kind != 0) {
        rows_avx2(k, tukey, kind, begin, end);
    } else if (tukey) {
        k.pairs8<true>(begin, end);
    } else {
        k.pairs8<false>(begin, end);
    }
}

// One body for all paths (inlined into each, compiled for its instruction set); V = V4d or
// V8d, VI its integer vector.
template <class V, class VI>
[[gnu::always_inline]] inline void exp_impl(const double* x, double* out, std::size_t n) {
    constexpr std::size_t kLanes = sizeof(V) / sizeof(double);
    V e{};
    for (std::size_t i = 0; i < n; i += kLanes) {
        V v{};
        for (std::size_t l = 0; l < kLanes; ++l) v[l] = i + l < n ? x[i + l] : 0.0;
        detail::exp_lanes_t<V, VI>(v, e);
        for (std::size_t l = 0; l < kLanes && i + l < n; ++l) out[i + l] = e[l];
    }
}

__attribute__((target("avx2"))) void exp_avx2(const double* x, double* out, std::size_t n) {
    exp_impl<detail::V4d, detail::V4i>(x, out, n);
}

__attribute__((target("avx512f,avx512dq,avx512vl,avx2"))) void exp_avx512(const double* x,
                                                                         double* out,
                                                                         std::size_t n) {
    exp_impl<detail::V8d, detail::V8i>(x, out, n);
}

void exp_baseline(const double* x, double* out, std::size_t n) {
    exp_impl<detail::V4d, detail::V4i>(x, out, n);
}

// The path that runs for `requested`: kBest becomes the best this CPU has. A forced path the
// CPU lacks throws UsageError naming `who`.
SimdPath run_path(SimdPath requested, const char* who) {
    if (requested == SimdPath::kAvx2 && !simd_avx2_available()) {
        throw UsageError(std::string(who) + " is kAvx2 but this CPU has no AVX2");
    }
    if (requested == SimdPath::kAvx512 && !simd_avx512_available()) {
        throw UsageError(std::string(who) +
                                    " is kAvx512 but this CPU has no AVX-512");
    }
    if (requested != SimdPath::kBest) return requested;
    if (simd_avx512_available()) return SimdPath::kAvx512;
    return simd_avx2_available() ? SimdPath::kAvx2 : SimdPath::kBaseline;
}

void require(bool ok, const std::string& field, const std::string& rule, double value) {
    if (!ok) {
        throw UsageError("RofiParams." + field + " must be " + rule + ", got " +
                                    std::to_string(value));
    }
}

// Work arrays of residual_progress, kept across iterations (no allocation after the first).
struct ResidualWork {
    std::vector<double> r;          // r_i
    std::vector<double> term;       // (r_i − ring mean)² / (1 + 1/k_i), where kind == 3
    std::vector<std::uint8_t> kind; // 0 fixed/none, 1 candidate, 2 on a feature, 3 in W
};

// True when two of the normals of faces[0..count) (records in `current`) are further apart
// than σ_s (dot < feature_dot) — the same dot products, in the same order, as testing every
// pair. First every face against faces[0]: a pair found there decides; if every normal is
// within h = 0.49 σ_s of n_0 (dot ≥ near_dot), any two are within 2h < σ_s of each other
// (triangle inequality), so none is a feature pair — the margin 0.02 σ_s, ~1e-2 σ_s² in the dot,
// far above its rounding (~1e-15) for σ_s ≥ 1e-4 (a zero normal, from a degenerate face,
// passes near_dot only for σ_s > 2.8, where no pair is a feature). Only a vertex in neither
// case tests the remaining pairs: O(valence) per vertex instead of O(valence²) (rofi.md,
// "Stopping", cost).
[[gnu::always_inline]] inline bool on_feature(const detail::FaceState* current,
                                              const int* faces, int count, double feature_dot,
                                              double near_dot) {
    const detail::FaceState& f0 = current[faces[0]];
    bool feature = false;
    bool near = true;
    for (int p = 1; p < count; ++p) {
        const detail::FaceState& f = current[faces[p]];
        const double dot = f.normal[0] * f0.normal[0] + f.normal[1] * f0.normal[1] +
                           f.normal[2] * f0.normal[2];
        feature = feature || dot < feature_dot;
        near = near && dot >= near_dot;
    }
    if (feature || near) return feature;
    for (int p = 2; p < count; ++p) {
        const detail::FaceState& f = current[faces[p]];
        for (int q = 1; q < p; ++q) {
            const detail::FaceState& g = current[faces[q]];
            const double dot = f.normal[0] * g.normal[0] + f.normal[1] * g.normal[1] +
                               f.normal[2] * g.normal[2];
            if (dot < feature_dot) return true;
        }
    }
    return false;
}

// The residual r_i = n̂_i · (v⁰_i − v_i) of V against the input V0, n̂_i = normalised
// Σ_{f ∋ i} a_f n_f from `current` (the geometry of V); r_i = 0 for fixed vertices. Returns
// δ = RMS of r over the free vertices and W = Σ (r_i − mean_{j ∈ ring(i)} r_j)² / (1 + 1/k_i)
// / Σ r_i² over the free vertices with k_i ≥ 3 ring neighbours that are not on a feature: two
// of their faces' normals differ by more than σ_s (x = |n_a − n_b|, the Tukey cut-off)
// (RofiStop::kWhiteResidual).
// Per-vertex terms in parallel, summed in vertex order: the same bits for any thread count.
RofiProgress residual_progress(const Vertices& V, const Vertices& V0,
                               const detail::FaceState* current, const Adjacency& adjacency,
                               const std::vector<std::uint8_t>& fixed, double sigma_s,
                               int threads, ResidualWork& work) {
    // |n_a − n_b| > σ_s ⇔ n_a · n_b < 1 − σ_s²/2 (unit normals).
    const double feature_dot = 1.0 - 0.5 * sigma_s * sigma_s;
    // The shortcut of on_feature (h = 0.49 σ_s), off below σ_s = 1e-4 (near_dot > 1: never).
    const double h = 0.49 * sigma_s;
    const double near_dot = sigma_s >= 1e-4 ? 1.0 - 0.5 * h * h : 2.0;
    const auto n = static_cast<int>(V.rows());
    const auto sn = static_cast<std::size_t>(n);
    work.r.resize(sn);
    work.term.resize(sn);
    work.kind.resize(sn);
    double* const r = work.r.data();
    double* const term = work.term.data();
    std::uint8_t* const kind = work.kind.data();
    const int* const vf_offsets = adjacency.vertex_faces.offsets.data();
    const int* const vf_items = adjacency.vertex_faces.items.data();
    const int* const vv_offsets = adjacency.vertex_vertices.offsets.data();
    const int* const vv_items = adjacency.vertex_vertices.items.data();
    const std::uint8_t* const is_fixed = fixed.data();
    const double* const v = V.data();
    const double* const v0 = V0.data();
    detail::parallel_for(n, threads, [&](int begin, int end) {
        for (int i = begin; i < end; ++i) {
            const int fb = vf_offsets[i];
            const int fe = vf_offsets[i + 1];
            r[i] = 0.0;
            kind[i] = 0;
            if (is_fixed[i] != 0 || fb == fe) continue;
            double s0 = 0.0, s1 = 0.0, s2 = 0.0;
            for (int p = fb; p < fe; ++p) {
                const detail::FaceState& f = current[vf_items[p]];
                s0 += f.area * f.normal[0];
                s1 += f.area * f.normal[1];
                s2 += f.area * f.normal[2];
            }
            const double norm = std::sqrt(s0 * s0 + s1 * s1 + s2 * s2);
            if (!(norm > 0.0)) continue;
            const std::ptrdiff_t o = 3 * static_cast<std::ptrdiff_t>(i);
            double d = 0.0;
            d += s0 * (v0[o] - v[o]);
            d += s1 * (v0[o + 1] - v[o + 1]);
            d += s2 * (v0[o + 2] - v[o + 2]);
            r[i] = d / norm;
            // Counted in δ; 1 = a candidate for W's sums, 2 = on a feature (not in W).
            kind[i] = on_feature(current, vf_items + fb, fe - fb, feature_dot, near_dot) ? 2 : 1;
        }
    });
    detail::parallel_for(n, threads, [&](int begin, int end) {
        for (int i = begin; i < end; ++i) {
            if (kind[i] != 1) continue;  // fixed or on a feature
            const int b = vv_offsets[i];
            const int k = vv_offsets[i + 1] - b;
            if (k < 3) continue;
            double mean = 0.0;
            for (int p = b; p < b + k; ++p) mean += r[vv_items[p]];
            const double l = r[i] - mean / k;
            kind[i] = 3;  // in W's sums
            term[i] = l * l / (1.0 + 1.0 / k);
        }
    });
    double sum = 0.0, num = 0.0, den = 0.0, on_features = 0.0;
    int count = 0, tested = 0, features = 0;
    for (int i = 0; i < n; ++i) {
        if (kind[i] == 0) continue;
        const double r2 = r[i] * r[i];
        sum += r2;
        ++count;
        if (kind[i] == 2) {
            on_features += r2;
            ++features;
        }
        if (kind[i] != 3) continue;
        num += term[i];
        den += r2;
        ++tested;
    }
    RofiProgress out;
    out.displacement = count > 0 ? std::sqrt(sum / count) : 0.0;
    out.whiteness = den > 0.0 ? num / den : 0.0;
    out.tested_vertices = tested;
    out.threshold = tested > 0 ? 1.0 - 1.5 / std::sqrt(static_cast<double>(tested)) : 0.0;
    out.feature_vertices = features;
    out.feature_rms = features > 0 ? std::sqrt(on_features / features) : 0.0;
    out.flat_rms = tested > 0 ? std::sqrt(den / tested) : 0.0;
    return out;
}

}  // namespace

void RofiParams::validate() const {
    require(std::isfinite(sigma_s) && sigma_s > 0.0, "sigma_s", "finite and > 0", sigma_s);
    require(std::isfinite(lambda_i) && lambda_i >= 0.0, "lambda_i", "finite and >= 0", lambda_i);
    require(iterations >= 0, "iterations", ">= 0", iterations);
    require(lambda_decay >= 0.0 && lambda_decay <= 1.0, "lambda_decay", "in [0, 1]",
            lambda_decay);
    require(std::isfinite(radius_factor) && radius_factor > 0.0, "radius_factor",
            "finite and > 0", radius_factor);
    require(std::isfinite(sigma_c_factor) && sigma_c_factor > 0.0, "sigma_c_factor",
            "finite and > 0", sigma_c_factor);
    require(threads >= 1, "threads", ">= 1", threads);
    if (stop != RofiStop::kNone && stop != RofiStop::kWhiteResidual) {
        throw UsageError("RofiParams.stop must be kNone or kWhiteResidual");
    }
    (void)run_path(simd, "RofiParams.simd");
}

bool simd_avx2_available() {
    static const bool available = __builtin_cpu_supports("avx2") != 0;
    return available;
}

bool simd_avx512_available() {
    static const bool available =
        __builtin_cpu_supports("avx512f") != 0 && __builtin_cpu_supports("avx512dq") != 0 &&
        __builtin_cpu_supports("avx512vl") != 0 && simd_avx2_available();
    return available;
}

void simd_exp_nonpositive(const double* x, double* out, std::size_t n, SimdPath path) {
    const SimdPath run = run_path(path, "simd_exp_nonpositive: path");
    if (run == SimdPath::kAvx512) {
        exp_avx512(x, out, n);
    } else if (run == SimdPath::kAvx2) {
        exp_avx2(x, out, n);
    } else {
        exp_baseline(x, out, n);
    }
}

namespace {

// The arrays, pair table and kernel of one run's iterations (rofi_denoise), built once.
// Not copyable: `kernel` points into the vectors.
struct RofiRun {
    RofiRun(const Vertices& V, const Faces& faces_in, const RofiParams& run_params,
            const Csr& omega, double mean_centroid_distance)
        : F(faces_in),
          params(run_params),
          n(static_cast<int>(V.rows())),
          m(static_cast<int>(faces_in.rows())),
          current(static_cast<std::size_t>(m)),
          faces(static_cast<std::size_t>(m)),
          shared(run_params.pair_weights == PairWeights::kShared),
          table(shared ? timed_pair_table(omega, table_seconds) : PairTable{}),
          pair_weight(table.first.size()),
          pair_blocks(static_cast<int>(table.first.size()) / kPairBlock),
          tukey(run_params.similarity == Similarity::kTukey) {
        const double sigma_c = params.sigma_c_factor * mean_centroid_distance;
        const double s2 = params.sigma_s * params.sigma_s;
        kernel = PairKernel{omega.offsets.data(), omega.items.data(), table.first.data(),
                            table.second.data(), table.slot_pair.data(), pair_weight.data(),
                            current.data(), faces.data(), 1.0 / s2,
                            1.0 / (2.0 * sigma_c * sigma_c), 1.0 / (2.0 * s2)};
        // The same bits on every path (simd.h). kAvx512 runs the pair weights 8 lanes wide
        // and everything else as kAvx2.
        const SimdPath path = run_path(params.simd, "RofiParams.simd");
        avx512 = path == SimdPath::kAvx512;
        avx2 = path != SimdPath::kBaseline;
    }
    RofiRun(const RofiRun&) = delete;
    RofiRun& operator=(const RofiRun&) = delete;

    static PairTable timed_pair_table(const Csr& omega, double& seconds) {
        const auto t0 = Clock::now();
        PairTable t = pair_table(omega);
        seconds = seconds_since(t0);
        return t;
    }

    // The records (normal, area, centroid) of X's faces into out[0 .. m).
    void update_faces(const Vertices& X, detail::FaceState* out) const {
        detail::parallel_for(m, params.threads, [&](int begin, int end) {
            detail::update_faces(X, F, begin, end, out, avx2);
        });
    }

    // One pass of the kernel over the pair blocks (kind 0) or the rows (1, 2): rows_impl.
    void pass(int kind) const {
        detail::parallel_for(kind == 0 ? pair_blocks : m, params.threads,
                             [&](int begin, int end) {
            if (avx512) {
                rows_avx512(kernel, tukey, kind, begin, end);
            } else if (avx2) {
                rows_avx2(kernel, tukey, kind, begin, end);
            } else {
                rows_baseline(kernel, tukey, kind, begin, end);
            }
        });
    }

    const Faces& F;
    const RofiParams& params;
    int n;
    int m;
    // current[f]: normal, area and centroid of the current mesh; faces[f]: the same with the
    // filtered normal ñ_f (what the vertex step reads).
    std::vector<detail::FaceState> current;
    std::vector<detail::FaceState> faces;
    // The weight f g of a pair (Eq. 5.1 without a_j) is symmetric in i and j, and bit for bit
    // so (|c_i − c_j|² and |n_i − n_j|² square the same differences up to sign). Where j ∈ Ω_i
    // and i ∈ Ω_j (nearly always), it is computed once (PairTable) and read by both slots.
    // Each weight has one writer, so any thread count gives the same bits. The centre face's
    // own weight is exactly 1 (x = 0, d = 0: (1 − 0)² exp(−0) = 1) and is not computed.
    bool shared;
    double table_seconds = 0;  // building `table` (DenoiseResult::phases.pair_table)
    PairTable table;
    std::vector<float> pair_weight;
    int pair_blocks;
    PairKernel kernel{};
    bool tukey;
    bool avx512 = false;
    bool avx2 = false;
};

// Adds the time since the last mark to a phase of DenoiseResult::phases and moves the mark.
struct PhaseClock {
    Clock::time_point mark = Clock::now();
    void lap(double& phase) {
        const auto now = Clock::now();
        phase += std::chrono::duration<double>(now - mark).count();
        mark = now;
    }
};

// The residual test of RofiStop::kWhiteResidual and the observer's reports. The stop's test
// runs after every even iteration and after the last (`tested`), and after every iteration
// once the fall of W between its last two tests, extrapolated one iteration, would reach the
// threshold (`dense`: the untested iteration could be the one). When it fires after an even k
// with k − 1 untested, the state after k − 1 (still in `next`, the vertex step's other buffer)
// is tested too and taken if it fires there. This equals testing after every iteration when W
// crosses its threshold at most once in a run, as on every mesh measured (rofi.md, "Stopping",
// cost), at about half the tests. The observer sees every iteration either way; the stop
// decides from the same tests with or without it.
struct ResidualStop {
    ResidualStop(const RofiParams& run_params, const detail::DenoiseSetup& run_setup)
        : params(run_params),
          setup(run_setup),
          stop(run_params.stop == RofiStop::kWhiteResidual),
          measure(stop || static_cast<bool>(run_params.observer)) {}

    bool tested(int k) const { return dense || k % 2 == 0 || k == params.iterations; }

    // Whether the residual after `it` iterations is measured (run.current holds its records).
    bool due(int it) const { return measure && it > 0 && (params.observer || tested(it)); }

    // The residual of the mesh after `it` iterations (result.V, records in run.current): the
    // observer sees it, the stop tests it (rofi.md, "Stopping": white while it is noise,
    // smoother once signal). True = the run ends here (result.V, its iteration count,
    // displacement and whiteness are then final; `next` holds V after it − 1).
    bool after(int it, const Vertices& V0, RofiRun& run, Vertices& next, DenoiseResult& result) {
        const RofiProgress progress = residual(result.V, V0, run.current.data());
        result.displacement = progress.displacement;
        result.residual_whiteness = progress.whiteness;
        if (params.observer) params.observer(it, result.V, progress);
        if (stop && tested(it) && progress.whiteness <= progress.threshold) {
            if (it > 1 && !tested(it - 1)) {
                RofiProgress before = previous;
                if (!params.observer) {
                    // `faces` is free until the next normal pass: V_{it−1}'s records.
                    run.update_faces(next, run.faces.data());
                    before = residual(next, V0, run.faces.data());
                }
                if (before.whiteness <= before.threshold) {
                    result.V.swap(next);
                    --result.iterations;
                    result.displacement = before.displacement;
                    result.residual_whiteness = before.whiteness;
                }
            }
            return true;
        }
        if (stop && tested(it)) {
            if (last_test > 0) {
                const double fall = (last_whiteness - progress.whiteness) / (it - last_test);
                dense = dense || progress.whiteness - fall <= progress.threshold;
            }
            last_test = it;
            last_whiteness = progress.whiteness;
        }
        previous = progress;
        return false;
    }

    RofiProgress residual(const Vertices& X, const Vertices& V0,
                          const detail::FaceState* records) {
        return residual_progress(X, V0, records, setup.adjacency, setup.fixed, params.sigma_s,
                                 params.threads, work);
    }

    const RofiParams& params;
    const detail::DenoiseSetup& setup;
    bool stop;
    bool measure;
    ResidualWork work;
    bool dense = false;
    RofiProgress previous;       // after it − 1, when the observer had it measured
    int last_test = 0;           // the iteration of the last test, 0 = none yet
    double last_whiteness = 0;   // its W
};

// rofi_denoise on a valid mesh as it is numbered (the caller renumbers it: local_order).
DenoiseResult rofi_denoise_numbered(const Vertices& V, const Faces& F,
                                    const RofiParams& params) {
    DenoiseResult result;
    detail::DenoiseSetup setup =
        detail::prepare_denoise(V, F, std::nullopt, params.radius_factor, params.fix_boundary,
                                params.iterations, params.threads, result);
    if (!setup.run) return result;
    // Not read by the iterations: the input's face geometry (56 bytes a face) and the
    // face-face adjacency (~16 bytes a face) are released before the iteration arrays exist.
    setup.geometry = FaceGeometry{};
    setup.adjacency.face_faces = Csr{};

    const auto t1 = Clock::now();
    RofiRun run(V, F, params, setup.omega, result.mean_centroid_distance);
    result.phases.pair_table = run.table_seconds;
    Vertices next(run.n, 3);
    ResidualStop residual(params, setup);
    double lambda = params.lambda_i;
    for (int it = 0; it <= params.iterations; ++it) {
        if (it == params.iterations && !residual.measure) break;
        PhaseClock clock;
        run.update_faces(result.V, run.current.data());
        clock.lap(result.phases.faces);
        if (residual.due(it)) {
            if (residual.after(it, V, run, next, result)) break;
            clock.lap(result.phases.stop);
        }
        if (it == params.iterations) break;
        if (run.shared) {
            // The pair weights (each row writes its own pairs and their mirror slots), then
            // the sums: two passes, so that every slot is written before any row reads it.
            run.pass(0);
            clock.lap(result.phases.weights);
            run.pass(1);
        } else {
            run.pass(2);  // weights and sums in one pass: counted as sums
        }
        clock.lap(result.phases.sums);
        // Eq. 5.9, without the λ_I term once it is negligible (kLambdaBudget).
        const double lambda_used =
            lambda < negligible_lambda(params.lambda_decay) ? 0.0 : lambda;
        detail::parallel_for(run.n, params.threads, [&](int begin, int end) {
            detail::vertex_step(result.V, run.faces.data(), setup.adjacency, setup.fixed,
                                lambda_used, begin, end, next, run.avx2);
        });
        clock.lap(result.phases.vertices);
        result.V.swap(next);
        lambda *= params.lambda_decay;
        ++result.iterations;
        if (params.progress) params.progress(result.iterations, params.iterations);
    }
    if (params.repair_folds && result.iterations > 0) {
        const auto t2 = Clock::now();
        const FoldRepairResult folds = repair_folds(result.V, F, setup.adjacency, setup.fixed);
        result.folds_repaired = folds.folds_found - folds.folds_left;
        result.folds_left = folds.folds_left;
        result.seconds_fold_repair = seconds_since(t2);
    }
    result.seconds_iterations = seconds_since(t1);
    return result;
}

}  // namespace

// The iterations run on the mesh renumbered for locality (detail::local_order: the order of
// the sums in Ω_i and in the vertex stars is the new numbering's; rofi.md, "Issue 35
// (session 21)"); the observer and the result see the caller's numbering.
DenoiseResult rofi_denoise(const Vertices& V, const Faces& F, const RofiParams& params) {
    params.validate();
    validate_mesh(V, F);
    if (params.iterations == 0 || F.rows() == 0) return rofi_denoise_numbered(V, F, params);
    return detail::denoise_in_local_order(V, F, [&](const detail::LocalOrder& local) {
        RofiParams run = params;
        Vertices seen;  // the observer's vertices in the caller's numbering
        if (params.observer) {
            seen = V;
            run.observer = [&](int it, const Vertices& X, const RofiProgress& progress) {
                detail::to_caller_order(X, local, seen);
                params.observer(it, seen, progress);
            };
        }
        return rofi_denoise_numbered(local.V, local.F, run);
    });
}

}  // namespace octshape::mesh
