// Writes the seed corpus for topcon_fuzz into DIR: small .fda files written by write_topcon of a
// few sizes and eyes, with missing values (nothing is copied from ../shared).
// Usage: make_topcon_seeds DIR

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>

#include "octshape/io/topcon.h"

int main(int argc, char** argv) {
    if (argc != 2) {
        std::cerr << "usage: make_topcon_seeds DIR\n";
        return 64;
    }
    const std::filesystem::path dir(argv[1]);
    std::filesystem::create_directories(dir);
    int n = 0;
    for (const int x : {3, 8}) {
        for (const int bscans : {2, 5}) {
            for (const auto eye : {octshape::io::Laterality::kOD, octshape::io::Laterality::kOS}) {
                octshape::io::Scan s;
                s.meta.size_x = x;
                s.meta.size_z = 40;
                s.meta.scale_x_mm = 6.0 / x;
                s.meta.scale_z_mm = 0.0035;
                s.meta.distance_mm = 6.0 / (bscans - 1);
                s.meta.laterality = eye;
                s.bscans.resize(static_cast<std::size_t>(bscans));
                for (int b = 0; b < bscans; ++b) {
                    auto& seg = s.bscans[static_cast<std::size_t>(b)].seg;
                    seg.assign(2, std::vector<float>(static_cast<std::size_t>(x)));
                    for (int a = 0; a < x; ++a) {
                        seg[0][static_cast<std::size_t>(a)] = static_cast<float>(5 + (a + b) % 3);
                        seg[1][static_cast<std::size_t>(a)] = static_cast<float>(30 + a % 2);
                    }
                }
                s.bscans[0].seg[0][0] = std::numeric_limits<float>::quiet_NaN();
                std::ofstream f(dir / ("seed" + std::to_string(n++) + ".fda"), std::ios::binary);
                octshape::io::write_topcon(s, f, 4);
            }
        }
    }
    return 0;
}
