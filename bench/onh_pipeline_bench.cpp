// Per-eye time and peak memory of the ONH pipeline on full-size phantom volumes (145 B-scans x
// 384 A-scans x 496 px, ~111 MB of pixels): reading the .vol with pixels, the level-set ILM
// (prepare + evolve), marching cubes, component/clip, RoFi — for the cupped, swollen and
// overhanging phantoms. Each eye runs in a fresh process (this program re-executes itself), so
// the peak resident memory (getrusage ru_maxrss) is that of one eye's pipeline alone.
// Usage: onh_pipeline_bench [BSCANS ASCANS]          generate the phantoms and print the table
//        onh_pipeline_bench --eye FILE.vol           (internal) run one eye, print one table row

#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <string>
#include <vector>

#include "octshape/io/scan_reader.h"
#include "octshape/io/vol.h"
#include "octshape/retina/levelset.h"
#include "octshape/retina/phantom_onh.h"

namespace {

using namespace octshape;

double max_rss_mb() {
    rusage ru{};
    getrusage(RUSAGE_SELF, &ru);
    return static_cast<double>(ru.ru_maxrss) / 1024.0;  // Linux: kilobytes
}

int run_eye(const std::string& path, const std::string& label) {
    const auto w0 = std::chrono::steady_clock::now();
    const std::clock_t c0 = std::clock();
    io::ReadOptions opt;
    opt.pixels = true;
    io::Scan scan = io::read_scan(path, opt);
    const double read_wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - w0).count();
    const double read_cpu = static_cast<double>(std::clock() - c0) / CLOCKS_PER_SEC;
    double pixel_mb = 0.0;
    for (const auto& b : scan.bscans) pixel_mb += static_cast<double>(b.pixels.size()) * 4.0 / 1048576.0;
    const retina::LevelSetResult r = retina::levelset_ilm_releasing_pixels(scan);
    const double ls_cpu = r.prepare.cpu_s + r.evolve.cpu_s;
    const double total_cpu = read_cpu + ls_cpu + r.marching_cubes.cpu_s + r.component_clip.cpu_s + r.rofi.cpu_s;
    const double total_wall = read_wall + r.prepare.wall_s + r.evolve.wall_s + r.marching_cubes.wall_s +
                              r.component_clip.wall_s + r.rofi.wall_s;
    const double rss = max_rss_mb();
    std::printf("%-9s %5d %8.3f %9.3f %9.3f %8.3f %8.3f %9.3f %9.3f %5d %4s %8lld %9.0f %8.0f %6.2f\n",
                label.c_str(), scan.num_bscans(), read_cpu, ls_cpu, r.marching_cubes.cpu_s,
                r.component_clip.cpu_s, r.rofi.cpu_s, total_cpu, total_wall, r.iterations,
                r.converged ? "yes" : "no", static_cast<long long>(r.F.rows()), rss, pixel_mb, rss / pixel_mb);
    return 0;
}

}  // namespace

int main(int argc, char** argv) {
    if (argc == 4 && std::string(argv[1]) == "--eye") return run_eye(argv[2], argv[3]);
    retina::OnhPhantomParams base;
    if (argc == 3) {
        base.num_bscans = std::atoi(argv[1]);
        base.num_ascans = std::atoi(argv[2]);
    }
    const auto dir = std::filesystem::temp_directory_path();
    std::printf("Full ONH pipeline per eye up to the ILM mesh (the ONH parameter stage is not included).\n"
                "CPU seconds of one process (one thread); wall = elapsed (machine load inflates it).\n"
                "peak_MB = ru_maxrss of the eye's process; ratio = peak / size of the volume's pixels.\n");
    std::printf("%-9s %5s %8s %9s %9s %8s %8s %9s %9s %5s %4s %8s %9s %8s %6s\n", "shape", "bscans", "read_s",
                "levelset", "march_s", "clip_s", "rofi_s", "total_cpu", "total_wall", "iter", "conv",
                "faces", "peak_MB", "vol_MB", "ratio");
    std::fflush(stdout);
    for (const auto shape : {retina::OnhShape::kCupped, retina::OnhShape::kSwollen, retina::OnhShape::kOverhang}) {
        retina::OnhPhantomParams p = retina::onh_phantom_preset(shape);
        p.num_bscans = base.num_bscans;
        p.num_ascans = base.num_ascans;
        const std::string name = retina::to_string(shape);
        const auto path = (dir / ("octshape_onh_bench_" + name + ".vol")).string();
        io::write_vol_file(retina::render_onh_scan(p), path);
        const pid_t pid = fork();
        if (pid == 0) {
            execl("/proc/self/exe", argv[0], "--eye", path.c_str(), name.c_str(), static_cast<char*>(nullptr));
            std::_Exit(127);
        }
        int status = 0;
        waitpid(pid, &status, 0);
        std::filesystem::remove(path);
        if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
            std::fprintf(stderr, "onh_pipeline_bench: the run for %s failed\n", name.c_str());
            return 1;
        }
    }
    return 0;
}
