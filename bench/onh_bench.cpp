// Per-eye time of `octshape onh`'s work on full-size ONH phantom volumes (145 B-scans x 384
// A-scans x 496 px, ~111 MB with pixels, docs/phantoms.md): reading the .vol without and with
// pixels, SHA-256 of the file, building the device ILM graph mesh, and the parameter stage
// (RPE thin-plate fill, BMO detection and ellipse, regions and volumes, CONHT, bending energy,
// MRW) -- and the same with the local ENVT feature map that --mesh-out adds. The last row is a
// radial scan of the cupped eye (24 lines x 384 A-scans x 496 px, the Spectralis ONH radial
// protocol; onh_radial.cpp): its ILM is the device lines interpolated between the lines; then
// the radial cupped and overhanging eyes with the level-set ILM (onh_radial_levelset.cpp: a 2-D
// level set per B-scan, interpolated between the lines, marching cubes, RoFi), whose ILM time
// is built from the scan with pixels and whose total counts the read with pixels.
// Usage: onh_bench [RUNS]   (default 3; the median per case is printed)

#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <ctime>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "octshape/io/scan_reader.h"
#include "octshape/io/sha256.h"
#include "octshape/io/vol.h"
#include "octshape/retina/onh.h"
#include "octshape/retina/phantom_onh.h"

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

double peak_rss_mb() {
    rusage u{};
    getrusage(RUSAGE_SELF, &u);
    return static_cast<double>(u.ru_maxrss) / 1024.0;  // Linux: kB
}

}  // namespace

int main(int argc, char** argv) {
    const int runs = argc > 1 ? std::max(1, std::atoi(argv[1])) : 3;
    const auto dir = std::filesystem::temp_directory_path();
    std::printf("%-22s %8s %8s %9s %9s %8s %11s %8s %11s %13s %9s %10s\n", "shape", "file_MB",
                "read_ms", "pixels_ms", "sha256_ms", "ilm_ms", "ilm_cpu_ms", "faces", "params_ms",
                "+envt_map_ms", "total_ms", "peakRSS_MB");
    struct Case {
        retina::OnhShape shape;
        bool radial;
        retina::IlmSource source;
    };
    const retina::IlmSource dev = retina::IlmSource::kDevice;
    const retina::IlmSource lset = retina::IlmSource::kLevelSet;
    for (const auto& [shape, radial, source] :
         {Case{retina::OnhShape::kCupped, false, dev},
          Case{retina::OnhShape::kOverhang, false, dev},
          Case{retina::OnhShape::kCupped, true, dev},
          Case{retina::OnhShape::kCupped, true, lset},
          Case{retina::OnhShape::kOverhang, true, lset}}) {
        const bool levelset = source == lset;
        const std::string name = retina::to_string(shape) + (radial ? "/radial24" : "") +
                                 (levelset ? "/ls" : "");
        const auto path = (dir / ("octshape_onh_bench_" + retina::to_string(shape) +
                                  (radial ? "_radial" : "") + ".vol"))
                              .string();
        retina::OnhPhantomParams params = retina::onh_phantom_preset(shape);
        params.radial = radial;
        io::write_vol_file(retina::render_onh_scan(params), path);
        const double mb = static_cast<double>(std::filesystem::file_size(path)) / 1e6;
        std::vector<double> tr, tp, th, ti, tc, ta, tn;
        long faces = 0;
        for (int i = 0; i < runs; ++i) {
            auto t0 = Clock::now();
            const io::Scan scan = io::read_scan(path);
            tr.push_back(ms_since(t0));
            t0 = Clock::now();
            io::ReadOptions with_pixels;
            with_pixels.pixels = true;
            io::Scan full = io::read_scan(path, with_pixels);
            tp.push_back(ms_since(t0));
            if (!levelset) full = io::Scan();
            t0 = Clock::now();
            const std::string sha = io::sha256_file(path);
            th.push_back(ms_since(t0));
            t0 = Clock::now();
            const std::clock_t c0 = std::clock();
            const retina::IlmSurface ilm =
                levelset ? retina::build_ilm_surface_releasing_pixels(full, source)
                         : retina::device_ilm_surface(scan);
            ti.push_back(ms_since(t0));
            tc.push_back(1e3 * static_cast<double>(std::clock() - c0) / CLOCKS_PER_SEC);
            faces = static_cast<long>(ilm.F.rows());
            t0 = Clock::now();
            const retina::OnhResult r = retina::analyse_onh(scan, ilm);
            ta.push_back(ms_since(t0));
            retina::OnhParams with_envt;  // what --mesh-out adds
            with_envt.local_features = true;
            t0 = Clock::now();
            const retina::OnhResult r2 = retina::analyse_onh(scan, ilm, with_envt);
            tn.push_back(ms_since(t0));
            if (r.cup_volume_mm3 != r2.cup_volume_mm3 || sha.empty()) return 1;
        }
        const double total =
            (levelset ? median(tp) : median(tr)) + median(th) + median(ti) + median(ta);
        std::printf("%-22s %8.1f %8.1f %9.1f %9.1f %8.1f %11.1f %8ld %11.1f %13.1f %9.1f %10.1f\n",
                    name.c_str(), mb, median(tr), median(tp), median(th), median(ti), median(tc),
                    faces, median(ta), median(tn), total, peak_rss_mb());
        std::filesystem::remove(path);
    }
    std::printf(
        "total = read (no pixels; /ls: with pixels) + sha256 + ILM + parameters, device ILM "
        "(/ls: level set), one thread (wall clock; ilm_cpu_ms: the ILM's process CPU time); "
        "peak RSS of the whole run (a scan with pixels is held in memory once)\n");
    return 0;
}
