// Per-eye time of `octshape macula`'s work on full-size phantom volumes (768 A-scans x 496 px,
// pixels included as the device writes them): reading the .vol (segmentation only, pixels
// skipped), SHA-256 of the file, the lateral registration of the B-scans (estimated on every
// volume, as `octshape macula` does, and applied when it moves something) and the CuBe
// analysis, for 61/97/193 B-scans, without noise and with 2 um of segmentation noise (the
// cohort bench's eyes: noisy half-lines take more fitting rounds). A second table: radial scans
// (ScanPattern 5) of 12 and 24 lines of 768 A-scans over 6 mm, the same eyes (target: the
// analysis <= 100 ms per eye). A third: the real macular files of ../shared/realdata when
// present (Topcon 128 x 512 cube, Cirrus 128 x 512 cube, Spectralis 19 x 512 Iowa surfaces;
// target of issue 32: <= 0.2 s per eye).
// Usage: macula_bench [RUNS] [--real]   (default 5; the median per case is printed, and for the
// registration and the analysis also the least CPU time of the runs, which other load on the
// machine inflates least; --real: only the real files, e.g. under valgrind --tool=callgrind)

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "octshape/io/scan_reader.h"
#include "octshape/io/sha256.h"
#include "octshape/io/vol.h"
#include "octshape/retina/cube.h"
#include "octshape/retina/lateral_registration.h"
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

// One row: read, hash, register and analyse the file `path` `runs` times (medians; the CPU
// times are the fastest run's). `first` is the row's first column. False when the hash is not
// a SHA-256.
bool bench_file(const std::string& first, double noise_um, const std::string& path, int runs) {
    std::vector<double> tr, th, tl, ta;
    double tl_cpu = 1e300;
    double ta_cpu = 1e300;
    double rmse = 0.0;
    std::string sha;
    const retina::CubeParams params;
    for (int i = 0; i < runs; ++i) {
        auto t0 = Clock::now();
        const io::Scan read = io::read_scan(path);
        tr.push_back(ms_since(t0));
        t0 = Clock::now();
        sha = io::sha256_file(path);
        th.push_back(ms_since(t0));
        // As `octshape macula` (app/commands/macula_eye.cpp): estimated on every volume, the
        // scan copied and moved only when the shifts are applied.
        t0 = Clock::now();
        double c0 = cpu_ms();
        const retina::LateralRegistration lateral =
            retina::estimate_lateral_motion(read, params.lateral_registration);
        io::Scan registered;
        if (lateral.applied) {
            registered = read;
            retina::apply_lateral_registration(registered, lateral);
        }
        const io::Scan& scan = lateral.applied ? registered : read;
        tl_cpu = std::min(tl_cpu, cpu_ms() - c0);
        tl.push_back(ms_since(t0));
        t0 = Clock::now();
        c0 = cpu_ms();
        const retina::CubeResult r = retina::analyse_macula(scan, params);
        ta_cpu = std::min(ta_cpu, cpu_ms() - c0);
        ta.push_back(ms_since(t0));
        rmse = r.rmse_um;
    }
    const double mb = static_cast<double>(std::filesystem::file_size(path)) / 1e6;
    std::printf("%-12s %-9.1f %-10.1f %10.1f %10.1f %12.1f %15.1f %12.1f %16.1f %12.1f %12.3f\n",
                first.c_str(), noise_um, mb, median(tr), median(th), median(tl), tl_cpu,
                median(ta), ta_cpu, median(tr) + median(th) + median(tl) + median(ta), rmse);
    return sha.size() == 64;
}

// A phantom row: write `p` to `path`, bench it, remove it.
bool bench_row(const retina::MaculaPhantomParams& p, int size, const std::string& path, int runs) {
    io::write_vol_file(retina::make_macula_phantom(p).scan, path);
    const bool ok = bench_file(std::to_string(size), p.noise_um, path, runs);
    std::filesystem::remove(path);
    return ok;
}

void print_header(const char* first) {
    std::printf("%-12s %-9s %-10s %10s %10s %12s %15s %12s %16s %12s %12s\n", first, "noise_um",
                "file_MB", "read_ms", "sha256_ms", "lateral_ms", "lateral_cpu_ms", "analysis_ms",
                "analysis_cpu_ms", "total_ms", "rmse_um");
}

// The real macular files (their own segmentation; no noise column: "-"), when present.
bool bench_real(int runs) {
    const std::filesystem::path dir = std::filesystem::path(OCTSHAPE_SHARED_DIR) / "realdata";
    print_header("real");
    const std::pair<const char*, const char*> files[] = {
        {"topcon", "topcon_ukb_example_min.fda"},
        {"cirrus", "cirrus_macular_cube_512x128_os_Surfaces_Iowa.xml"},
        {"spectralis", "T566581_Surfaces_Iowa.xml"}};
    for (const auto& [name, file] : files) {
        const auto path = dir / file;
        if (!std::filesystem::exists(path)) {
            std::printf("%-12s (absent: %s)\n", name, path.string().c_str());
            continue;
        }
        if (!bench_file(name, 0.0, path.string(), runs)) return false;
    }
    return true;
}

}  // namespace

int main(int argc, char** argv) {
    int runs = 5;
    bool real_only = false;
    for (int i = 1; i < argc; ++i) {
        if (std::string(argv[i]) == "--real") {
            real_only = true;
        } else {
            runs = std::max(1, std::atoi(argv[i]));
        }
    }
    if (real_only) return bench_real(runs) ? 0 : 1;
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
    std::printf("\n");
    return bench_real(runs) ? 0 : 1;
}
