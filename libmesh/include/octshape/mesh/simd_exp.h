#pragma once
// The vectorised exp() that RoFi's pair weights use (libmesh/src/simd.h), exposed so that its
// accuracy and its bit-identity across instruction sets can be tested.

#include <cstddef>

namespace octshape::mesh {

// Which code path runs the vector kernels: the best the CPU offers (AVX-512 if
// __builtin_cpu_supports says so, else AVX2, else baseline x86-64 SSE2), or one forced. All do
// the same IEEE operations per lane, so they give the same bits. kAvx512 runs RoFi's pair
// weights and this exp() 8 lanes at a time and everything else as kAvx2.
enum class SimdPath { kBest, kBaseline, kAvx2, kAvx512 };

// True if this CPU can run SimdPath::kAvx2.
[[nodiscard]] bool simd_avx2_available();

// True if this CPU can run SimdPath::kAvx512 (AVX-512 F, DQ and VL, and AVX2).
[[nodiscard]] bool simd_avx512_available();

// out[i] = exp(x[i]) for finite x[i] ≤ 0 (0 below −708), relative error ≤ 1e−15 (the bound's
// argument is in simd.h). Throws UsageError for kAvx2 / kAvx512 on a CPU without
// that instruction set.
void simd_exp_nonpositive(const double* x, double* out, std::size_t n,
                          SimdPath path = SimdPath::kBest);

}  // namespace octshape::mesh
