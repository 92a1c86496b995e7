// .vol read time with and without pixels: writes a 61-B-scan x 768 x 496 volume (17 lines,
// 768 x 768 SLO, as a Spectralis 25x30 degree macular volume) with write_vol to the temp
// directory, then reads it RUNS times each way and prints the median per case.
// Usage: read_bench [RUNS]   (default 5)

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>
#include <vector>

#include "octshape/io/vol.h"

namespace {

using namespace octshape::io;

Scan make_volume() {
    constexpr int kB = 61, kX = 768, kZ = 496, kLines = 17;
    Scan s;
    ScanMeta& m = s.meta;
    m.size_x = kX;
    m.size_z = kZ;
    m.scale_x_mm = 0.011483;
    m.scale_z_mm = 0.0038717;
    m.distance_mm = 0.1237;
    m.size_x_slo = 768;
    m.size_y_slo = 768;
    m.scale_x_slo_mm = 0.011483;
    m.scale_y_slo_mm = 0.011483;
    m.field_size_slo_deg = 30;
    m.laterality = Laterality::kOD;
    m.pattern = ScanPattern::kVolume;
    m.scan_pattern_code = 3;
    for (int b = 0; b < kB; ++b) {
        BScan bs;
        bs.start_x_mm = 0.0;
        bs.start_y_mm = 0.1237 * b;
        bs.end_x_mm = 0.011483 * kX;
        bs.end_y_mm = bs.start_y_mm;
        bs.seg.assign(kLines, std::vector<float>(kX));
        for (int k = 0; k < kLines; ++k) {
            for (int a = 0; a < kX; ++a) bs.seg[k][a] = 100.0F + 10.0F * k + 0.01F * a;
        }
        bs.pixels.resize(static_cast<std::size_t>(kX) * kZ);
        for (std::size_t i = 0; i < bs.pixels.size(); ++i) {
            bs.pixels[i] = static_cast<float>((i * 2654435761U) % 1000U) / 1000.0F;
        }
        s.bscans.push_back(std::move(bs));
    }
    s.slo.assign(768U * 768U, 100);
    s.pixels_loaded = true;
    return s;
}

double read_seconds(const std::string& path, bool pixels) {
    const auto t0 = std::chrono::steady_clock::now();
    std::ifstream in(path, std::ios::binary);
    ReadOptions opt;
    opt.pixels = pixels;
    const Scan s = read_vol(in, std::filesystem::file_size(path), path, opt);
    const auto t1 = std::chrono::steady_clock::now();
    if (s.num_bscans() != 61) std::fprintf(stderr, "unexpected B-scan count\n");
    return std::chrono::duration<double>(t1 - t0).count();
}

double median(std::vector<double> v) {
    std::sort(v.begin(), v.end());
    return v[v.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
    const int runs = argc > 1 ? std::max(1, std::atoi(argv[1])) : 5;
    const std::string path =
        (std::filesystem::temp_directory_path() / "octshape_read_bench.vol").string();
    write_vol_file(make_volume(), path);
    const auto size = std::filesystem::file_size(path);
    std::vector<double> with_px;
    std::vector<double> without_px;
    (void)read_seconds(path, true);  // warm the page cache
    for (int r = 0; r < runs; ++r) {
        with_px.push_back(read_seconds(path, true));
        without_px.push_back(read_seconds(path, false));
    }
    const double tp = median(with_px);
    const double tn = median(without_px);
    std::printf("read_vol, 61 B-scans x 768 x 496, 17 lines (%d runs, median, warm cache)\n", runs);
    std::printf("%-22s | %-14s | %-10s | %s\n", "case", "size", "time", "ratio to pixels");
    std::printf("%-22s | %9.1f MB | %7.2f ms | %.3f\n", "with pixels + SLO", size / 1e6, tp * 1e3,
                1.0);
    std::printf("%-22s | %9.1f MB | %7.2f ms | %.3f\n", "headers + segmentation", size / 1e6,
                tn * 1e3, tn / tp);
    std::filesystem::remove(path);
    return 0;
}
