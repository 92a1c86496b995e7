#pragma once
// The vectorised exp() that RoFi's pair weights use (libmesh/src/simd.h), exposed so that its
// accuracy and its bit-identity across instruction sets can be tested.

#include <cstddef>

namespace octshape::mesh {

// Which code path runs the 4-lane kernels: the best the CPU offers (AVX2 if
// __builtin_cpu_supports says so, else baseline x86-64 SSE2), or one forced. Both do the same
// IEEE operations per lane, so they give the same bits.
enum class SimdPath { kBest, kBaseline, kAvx2 };

// True if this CPU can run SimdPath::kAvx2.
[[nodiscard]] bool simd_avx2_available();

// out[i] = exp(x[i]) for finite x[i] ≤ 0 (0 below −708), relative error ≤ 1e−15 (the bound's
// argument is in simd.h). Throws std::invalid_argument for kAvx2 on a CPU without AVX2.
void simd_exp_nonpositive(const double* x, double* out, std::size_t n,
                          SimdPath path = SimdPath::kBest);

}  // namespace octshape::mesh
