// Per-eye time of `octshape macula`'s work on full-size phantom volumes (768 A-scans x 496 px,
// pixels included as the device writes them): reading the .vol (segmentation only, pixels
// skipped), SHA-256 of the file, and the CuBe analysis, for 61/97/193 B-scans, without noise
// and with 2 um of segmentation noise (the cohort bench's eyes: noisy half-lines take more
// fitting rounds). A second table: radial scans (ScanPattern 5) of 12 and 24 lines of 768
// A-scans over 6 mm, the same eyes (target: the analysis <= 100 ms per eye).
// Usage: macula_bench [RUNS]   (default 5; the median per case is printed, and for the analysis
// also the least CPU time of the runs, which other load on the machine inflates least)

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <ctime>
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

double cpu_ms() {
    timespec ts{};
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return 1e3 * static_cast<double>(ts.tv_sec) + 1e-6 * static_cast<double>(ts.tv_nsec);
}

double median(std::vector<double> v) {
    std::sort(v.begin(), v.end());
    return v[v.size() / 2];
}

// One row: write the phantom `p` to `path`, then read, hash and analyse it `runs` times
// (medians; the analysis's CPU time is the fastest run's). `size` is the row's first column
// (B-scans or radial lines). False when the hash is not a SHA-256.
bool bench_row(const retina::MaculaPhantomParams& p, int size, const std::string& path, int runs) {
    io::write_vol_file(retina::make_macula_phantom(p).scan, path);
    std::vector<double> tr, th, ta;
    double ta_cpu = 1e300;
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
        const double c0 = cpu_ms();
        const retina::CubeResult r = retina::analyse_macula(scan);
        ta_cpu = std::min(ta_cpu, cpu_ms() - c0);
        ta.push_back(ms_since(t0));
        rmse = r.rmse_um;
    }
    const double mb = static_cast<double>(std::filesystem::file_size(path)) / 1e6;
    std::printf("%-8d %-9.1f %-10.1f %10.1f %10.1f %12.1f %16.1f %12.1f %12.3f\n", size,
                p.noise_um, mb, median(tr), median(th), median(ta), ta_cpu,
                median(tr) + median(th) + median(ta), rmse);
    std::filesystem::remove(path);
    return sha.size() == 64;
}

void print_header(const char* first) {
    std::printf("%-8s %-9s %-10s %10s %10s %12s %16s %12s %12s\n", first, "noise_um", "file_MB",
                "read_ms", "sha256_ms", "analysis_ms", "analysis_cpu_ms", "total_ms", "rmse_um");
}

}  // namespace

int main(int argc, char** argv) {
    const int runs = argc > 1 ? std::max(1, std::atoi(argv[1])) : 5;
    const auto dir = std::filesystem::temp_directory_path();
    print_header("B-scans");
    for (const double noise_um : {0.0, 2.0}) {
        for (const int nb : {61, 97, 193}) {
            retina::MaculaPhantomParams p;
            p.num_bscans = nb;
            p.noise_um = noise_um;
            p.pixels = false;  // the file still holds every pixel (kNoPixelData), as large as real
            const auto path = dir / ("octshape_macula_bench_" + std::to_string(nb) + ".vol");
            if (!bench_row(p, nb, path.string(), runs)) return 1;
        }
    }
    std::printf("\n");
    print_header("lines");
    for (const double noise_um : {0.0, 2.0}) {
        for (const int lines : {12, 24}) {
            retina::MaculaPhantomParams p;
            p.radial = true;
            p.radial_lines = lines;
            p.fovea_dx_mm = 0.03;  // the crossing 30 um off the fovea
            p.noise_um = noise_um;
            p.pixels = false;
            const auto path =
                dir / ("octshape_macula_bench_radial_" + std::to_string(lines) + ".vol");
            if (!bench_row(p, lines, path.string(), runs)) return 1;
        }
    }
    return 0;
}
