#pragma once
// Private to libmesh: 4- and 8-lane double vectors (GCC vector extensions) and exp() on them.
//
// Every function here does the same IEEE-754 double operations in every lane whatever the
// instruction set it is compiled for (baseline x86-64: two SSE2 registers per V4d; inside a
// function with __attribute__((target("avx2"))): one AVX register; V8d only inside AVX-512
// functions: one ZMM register), so the results are the same bits on any x86-64 machine. No
// fused multiply-add: the including file is compiled with -ffp-contract=off
// (libmesh/CMakeLists.txt), so even the AVX-512 paths (where FMA exists) do not contract.
// Everything is always inlined (no call passes a vector between code for different targets,
// whose ABIs differ: hence -Wno-psabi for the including file). No lambdas on vectors: a lambda
// is not always inlined early, and GCC then lowers its V8d code for the baseline target (a
// splat became eight masked broadcasts, measured 1.6x slower pair weights).

#include <bit>
#include <cstdint>

namespace octshape::mesh::detail {

using V4d = double __attribute__((vector_size(32)));
using V4i = std::int64_t __attribute__((vector_size(32)));
// 8 lanes: the AVX-512 copy of RoFi's pair weights (rofi.cpp) only.
using V8d = double __attribute__((vector_size(64)));
using V8i = std::int64_t __attribute__((vector_size(64)));
// Single-precision lanes for stored pair weights (rofi.cpp): 4 and 8 floats.
using V4f = float __attribute__((vector_size(16)));
using V8f = float __attribute__((vector_size(32)));

// s in every lane of a V (V4d or V8d).
template <class V>
[[gnu::always_inline]] inline V splat_as(double s) {
    if constexpr (sizeof(V) == sizeof(V4d)) {
        return V{s, s, s, s};
    } else {
        // A broadcast (GCC builds V{s, s, s, s, s, s, s, s} lane by lane).
        const V one{s};
        return __builtin_shufflevector(one, one, 0, 0, 0, 0, 0, 0, 0, 0);
    }
}

[[gnu::always_inline]] inline V4d splat(double s) { return splat_as<V4d>(s); }

// exp(x) lane by lane for x ≤ 0 (the closeness and Gaussian similarity weights of RoFi):
// x = k ln2 + r with k = round(x / ln2), |r| ≤ ln2/2 (+ rounding); exp(r) by its Taylor
// polynomial of degree 12 (Estrin's scheme); 2^k written into the exponent field. Below −708 the result
// is 0 (exp(−708) ≈ 3e−308 is at the bottom of the normal range; for RoFi such a weight is
// nothing beside the centre face's weight 1). NaN is not handled (inputs are finite).
// Error: the truncation |r|^13/13! e^|r| ≤ 2.4e−16 relative (|r| ≤ 0.3466), the rounding of r
// (one rounding of size ≤ 2^−53 |r|, the product k·ln2_hi is exact: ln2_hi has 32 significant
// bits and |k| ≤ 1022) and the polynomial's roundings (≤ ~2 ulp: the terms after 1 + r are < 0.07) — about
// 7e−16 in all; the test (tests/mesh/rofi_test.cpp) bounds it at 1e−15 against std::exp.
// V = V4d or V8d, VI the 64-bit integer vector of the same width (the same operations in
// every lane whatever the width).
template <class V, class VI>
[[gnu::always_inline]] inline void exp_lanes_t(const V& x_in, V& out) {
    const V lo = splat_as<V>(-708.0);
    const VI under = x_in < lo;
    const V x = under ? lo : x_in;
    // Round x / ln2 to the nearest integer: adding 1.5·2^52 leaves k in the low mantissa bits.
    const V shifter = splat_as<V>(0x1.8p52);
    const V kd_shifted = x * splat_as<V>(1.4426950408889634) + shifter;
    const V kd = kd_shifted - shifter;
    // Cody–Waite reduction with fdlibm's split of ln 2.
    const V r = (x - kd * splat_as<V>(6.93147180369123816490e-01)) -
                kd * splat_as<V>(1.90821492927058770002e-10);
    // Estrin's scheme (independent products, a short dependency chain) for
    // Σ_{n=0}^{12} r^n / n!.
    const V r2 = r * r;
    const V r4 = r2 * r2;
    const V r8 = r4 * r4;
    const V q0 = splat_as<V>(1.0) + r;
    const V q1 = splat_as<V>(0.5) + r * splat_as<V>(1.0 / 6.0);
    const V q2 = splat_as<V>(1.0 / 24.0) + r * splat_as<V>(1.0 / 120.0);
    const V q3 = splat_as<V>(1.0 / 720.0) + r * splat_as<V>(1.0 / 5040.0);
    const V q4 = splat_as<V>(1.0 / 40320.0) + r * splat_as<V>(1.0 / 362880.0);
    const V q5 = splat_as<V>(1.0 / 3628800.0) + r * splat_as<V>(1.0 / 39916800.0);
    const V q6 = splat_as<V>(1.0 / 479001600.0);
    const V s0 = q0 + r2 * q1;
    const V s1 = q2 + r2 * q3;
    const V s2 = q4 + r2 * q5;
    const V p = (s0 + r4 * s1) + r8 * (s2 + r4 * q6);
    // k + 1023 ∈ [1, 1023] into the exponent field: 2^k exactly.
    const VI k = std::bit_cast<VI>(kd_shifted) - std::bit_cast<VI>(shifter);
    const V scale = std::bit_cast<V>((k + 1023) << 52);
    out = under ? splat_as<V>(0.0) : p * scale;
}

}  // namespace octshape::mesh::detail
