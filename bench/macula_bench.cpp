// Per-eye time of `octshape macula`'s work on full-size phantom volumes (768 A-scans x 496 px,
// pixels included as the device writes them): reading the .vol (segmentation only, pixels
// skipped), SHA-256 of the file, and the CuBe analysis, for 61/97/193 B-scans.
// Usage: macula_bench [RUNS]   (default 5; the median per case is printed)

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include "octshape/io/scan_reader.h"
#include "octshape/io/sha256.h"
#include "octshape/io/vol.h"
#include "octshape/retina/cube.h"
#include "octshape/retina/phantom_macula.h"

namespace {

using namespace octshape;
using Clock = std::chrono::steady_clock;

double ms_since(Clock::time_point t0) {
    return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

double median(std::vector<double> v) {
    std::sort(v.begin(), v.end());
    return v[v.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
    const int runs = argc > 1 ? std::max(1, std::atoi(argv[1])) : 5;
    const auto dir = std::filesystem::temp_directory_path();
    std::printf("%-8s %-10s %10s %10s %12s %12s %12s\n", "B-scans", "file_MB", "read_ms",
                "sha256_ms", "analysis_ms", "total_ms", "rmse_um");
    for (const int nb : {61, 97, 193}) {
        retina::MaculaPhantomParams p;
        p.num_bscans = nb;
        p.pixels = false;  // the file still holds every pixel (kNoPixelData), as large as real
        const auto path = (dir / ("octshape_macula_bench_" + std::to_string(nb) + ".vol")).string();
        io::write_vol_file(retina::make_macula_phantom(p).scan, path);
        std::vector<double> tr, th, ta;
        double rmse = 0.0;
        std::string sha;
        for (int i = 0; i < runs; ++i) {
            auto t0 = Clock::now();
            const io::Scan scan = io::read_scan(path);
            tr.push_back(ms_since(t0));
            t0 = Clock::now();
            sha = io::sha256_file(path);
            th.push_back(ms_since(t0));
            t0 = Clock::now();
            const retina::CubeResult r = retina::analyse_macula(scan);
            ta.push_back(ms_since(t0));
            rmse = r.rmse_um;
        }
        const double mb = static_cast<double>(std::filesystem::file_size(path)) / 1e6;
        std::printf("%-8d %-10.1f %10.1f %10.1f %12.1f %12.1f %12.3f\n", nb, mb, median(tr),
                    median(th), median(ta), median(tr) + median(th) + median(ta), rmse);
        std::filesystem::remove(path);
        if (sha.size() != 64) return 1;
    }
    return 0;
}
