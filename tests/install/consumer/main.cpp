// Denoises a noisy flat 40x40 grid with the installed libmesh (RoFi): exit 0 when the result
// is closer to the plane (MSAE) than the input.
#include <cstdio>
#include <random>

#include "octshape/mesh/metrics.h"
#include "octshape/mesh/rofi.h"
#include "octshape/version.h"

int main() {
    using namespace octshape::mesh;
    const int n = 40;
    Vertices flat(n * n, 3), noisy(n * n, 3);
    Faces F(2 * (n - 1) * (n - 1), 3);
    std::mt19937 rng(1);
    std::normal_distribution<double> noise(0.0, 0.2);  // 0.2 of the edge length, along z
    for (int k = 0; k < n * n; ++k) {
        flat.row(k) << k % n, k / n, 0.0;
        noisy.row(k) << k % n, k / n, noise(rng);
    }
    for (int i = 0, f = 0; i + 1 < n; ++i)
        for (int j = 0; j + 1 < n; ++j, f += 2) {
            F.row(f) << i * n + j, i * n + j + 1, (i + 1) * n + j + 1;
            F.row(f + 1) << i * n + j, (i + 1) * n + j + 1, (i + 1) * n + j;
        }
    const double before = compare_meshes(noisy, F, flat, F).msae_deg;
    const double after = compare_meshes(rofi_denoise(noisy, F, {}).V, F, flat, F).msae_deg;
    std::printf("octshape %s libmesh: MSAE %.2f -> %.2f deg\n", octshape::kVersion, before, after);
    return after < before ? 0 : 1;
}
