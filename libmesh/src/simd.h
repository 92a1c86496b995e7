#pragma once
// Private to libmesh: 4-lane double vectors (GCC vector extensions) and exp() on them.
//
// Every function here does the same IEEE-754 double operations in every lane whatever the
// instruction set it is compiled for (baseline x86-64: two SSE2 registers per vector; inside a
// function with __attribute__((target("avx2"))): one AVX register), so the results are the same
// bits on any x86-64 machine. No fused multiply-add: the including file is compiled with
// -ffp-contract=off (libmesh/CMakeLists.txt) and the AVX2 paths do not enable FMA.
// Everything is always inlined (no call passes a 32-byte vector between code for different
// targets, whose ABIs differ: hence -Wno-psabi for the including file).

#include <bit>
#include <cstdint>

namespace octshape::mesh::detail {

using V4d = double __attribute__((vector_size(32)));
using V4i = std::int64_t __attribute__((vector_size(32)));

[[gnu::always_inline]] inline V4d splat(double s) { return V4d{s, s, s, s}; }

// exp(x) lane by lane for x ≤ 0 (the closeness and Gaussian similarity weights of RoFi):
// x = k ln2 + r with k = round(x / ln2), |r| ≤ ln2/2 (+ rounding); exp(r) by its Taylor
// polynomial of degree 12 (Estrin's scheme); 2^k written into the exponent field. Below −708 the result
// is 0 (exp(−708) ≈ 3e−308 is at the bottom of the normal range; for RoFi such a weight is
// nothing beside the centre face's weight 1). NaN is not handled (inputs are finite).
// Error: the truncation |r|^13/13! e^|r| ≤ 2.4e−16 relative (|r| ≤ 0.3466), the rounding of r
// (one rounding of size ≤ 2^−53 |r|, the product k·ln2_hi is exact: ln2_hi has 32 significant
// bits and |k| ≤ 1022) and the polynomial's roundings (≤ ~2 ulp: the terms after 1 + r are < 0.07) — about
// 7e−16 in all; the test (tests/mesh/rofi_test.cpp) bounds it at 1e−15 against std::exp.
[[gnu::always_inline]] inline void exp_lanes(const V4d& x_in, V4d& out) {
    const V4d lo = splat(-708.0);
    const V4i under = x_in < lo;
    const V4d x = under ? lo : x_in;
    // Round x / ln2 to the nearest integer: adding 1.5·2^52 leaves k in the low mantissa bits.
    const V4d shifter = splat(0x1.8p52);
    const V4d kd_shifted = x * splat(1.4426950408889634) + shifter;
    const V4d kd = kd_shifted - shifter;
    // Cody–Waite reduction with fdlibm's split of ln 2.
    const V4d r = (x - kd * splat(6.93147180369123816490e-01)) - kd * splat(1.90821492927058770002e-10);
    // Estrin's scheme (independent products, a short dependency chain) for
    // Σ_{n=0}^{12} r^n / n!.
    const V4d r2 = r * r;
    const V4d r4 = r2 * r2;
    const V4d r8 = r4 * r4;
    const V4d q0 = splat(1.0) + r;
    const V4d q1 = splat(0.5) + r * splat(1.0 / 6.0);
    const V4d q2 = splat(1.0 / 24.0) + r * splat(1.0 / 120.0);
    const V4d q3 = splat(1.0 / 720.0) + r * splat(1.0 / 5040.0);
    const V4d q4 = splat(1.0 / 40320.0) + r * splat(1.0 / 362880.0);
    const V4d q5 = splat(1.0 / 3628800.0) + r * splat(1.0 / 39916800.0);
    const V4d q6 = splat(1.0 / 479001600.0);
    const V4d s0 = q0 + r2 * q1;
    const V4d s1 = q2 + r2 * q3;
    const V4d s2 = q4 + r2 * q5;
    const V4d p = (s0 + r4 * s1) + r8 * (s2 + r4 * q6);
    // k + 1023 ∈ [1, 1023] into the exponent field: 2^k exactly.
    const V4i k = std::bit_cast<V4i>(kd_shifted) - std::bit_cast<V4i>(shifter);
    const V4d scale = std::bit_cast<V4d>((k + 1023) << 52);
    out = under ? splat(0.0) : p * scale;
}

}  // namespace octshape::mesh::detail
