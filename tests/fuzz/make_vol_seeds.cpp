// Writes the seed corpus for vol_fuzz into DIR: small valid .vol files made with write_vol
// (every version 100..104 by patching the magics, circular / rectangular / trailing grids,
// 0..17 lines, with and without an SLO). Usage: make_vol_seeds DIR

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <sstream>
#include <string>

#include "octshape/error.h"
#include "octshape/io/vol.h"

namespace {

using namespace octshape::io;

Scan make_scan(int num_bscans, int size_x, int size_z, int lines, int slo) {
    Scan s;
    ScanMeta& m = s.meta;
    m.size_x = size_x;
    m.size_z = size_z;
    m.scale_x_mm = 0.0118;
    m.scale_z_mm = 0.0038717;
    m.distance_mm = num_bscans > 1 ? 0.12 : 0.0;
    m.size_x_slo = slo;
    m.size_y_slo = slo;
    m.scale_x_slo_mm = 0.0118;
    m.scale_y_slo_mm = 0.0118;
    m.field_size_slo_deg = 30;
    m.laterality = Laterality::kOD;
    m.pattern = num_bscans > 1 ? ScanPattern::kVolume : ScanPattern::kLine;
    m.scan_pattern_code = static_cast<int>(m.pattern);
    m.exam_time_filetime = 131000000000000000ULL;
    m.ids.dob_ole = 20000.0;
    m.prog_id = "seed";
    for (int b = 0; b < num_bscans; ++b) {
        BScan bs;
        bs.start_x_mm = 0.5;
        bs.start_y_mm = 1.0 + 0.12 * b;
        bs.end_x_mm = 0.5 + 0.0118 * size_x;
        bs.end_y_mm = bs.start_y_mm;
        bs.quality = 30.0F;
        bs.shift = b - 1;
        bs.iv_trafo = {1.0F, 0.0F, 0.0F, 1.0F, 0.5F, -0.5F};
        bs.seg.assign(static_cast<std::size_t>(lines),
                      std::vector<float>(static_cast<std::size_t>(size_x)));
        for (int k = 0; k < lines; ++k) {
            for (int a = 0; a < size_x; ++a) {
                bs.seg[k][a] = a % 5 == 0 ? std::numeric_limits<float>::quiet_NaN()
                                          : 1.0F + static_cast<float>(k + a) * 0.25F;
            }
        }
        bs.pixels.resize(static_cast<std::size_t>(size_x * size_z));
        for (std::size_t i = 0; i < bs.pixels.size(); ++i)
            bs.pixels[i] = static_cast<float>(i % 11) / 10.0F;
        s.bscans.push_back(std::move(bs));
    }
    s.slo.assign(static_cast<std::size_t>(slo * slo), 128);
    s.pixels_loaded = true;
    return s;
}

ThicknessGrid circular(bool from_header) {
    ThicknessGrid g;
    g.type = 3;
    g.from_header = from_header;
    g.diameters_mm = {1.0, 3.0, 6.0};
    g.centre_x_slo_mm = 2.0;
    g.centre_y_slo_mm = 2.0;
    g.cells.resize(9, {0.3F, 0.1F});
    return g;
}

ThicknessGrid rectangular() {
    ThicknessGrid g;
    g.type = 8;
    g.rows = 2;
    g.cols = 3;
    g.cell_width_mm = 0.5F;
    g.cell_height_mm = 0.5F;
    g.centre_x_slo_mm = 2.0;
    g.centre_y_slo_mm = 2.0;
    g.cells.resize(6, {0.3F, 0.1F});
    return g;
}

std::string to_bytes(const Scan& s) {
    std::ostringstream out(std::ios::binary);
    write_vol(s, out);
    return out.str();
}

}  // namespace

int main(int argc, char** argv) {
    if (argc != 2) {
        std::cerr << "usage: make_vol_seeds DIR\n";
        return 64;
    }
    const std::filesystem::path dir = argv[1];
    std::filesystem::create_directories(dir);
    int n = 0;
    const auto save = [&](const std::string& name, const std::string& bytes) {
        std::ofstream(dir / (name + ".vol"), std::ios::binary) << bytes;
        ++n;
    };
    Scan a = make_scan(2, 8, 6, 3, 4);
    a.grids.push_back(circular(true));
    const std::string base = to_bytes(a);
    save("circular_grid_v103", base);
    // Same bytes under the other versions: the reader branches on the digit.
    for (const char v : {'0', '1', '2', '4'}) {
        std::string f = base;
        f[10] = v;
        save(std::string("circular_grid_v10") + v, f);
    }
    Scan b = make_scan(3, 6, 4, 17, 0);
    b.grids.push_back(circular(true));
    b.grids.push_back(rectangular());
    save("two_grids_17_lines_no_slo", to_bytes(b));
    Scan c = make_scan(1, 16, 8, 2, 8);
    c.grids.push_back(circular(false));
    save("trailing_grid_line", to_bytes(c));
    save("no_lines", to_bytes(make_scan(2, 4, 4, 0, 2)));
    std::cout << "wrote " << n << " seeds to " << dir.string() << "\n";
    return 0;
}
