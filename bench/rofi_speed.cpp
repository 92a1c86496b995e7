// RoFi at the hardware's limit (issue 35): three tables.
//
// 1. Speed against the authors' Java RoFi (the issue's four meshes; σ_s 0.55, λ_I 0.2,
//    100 iterations, r = 2 c_a): seconds of one call (set-up + iterations, as `denoise --json`
//    reports them), 1 and 2 threads, min over the rounds, and the ratio Java / ours.
// 2. Roofline: the time of each phase of an iteration per face and per face–neighbour pair,
//    its memory traffic, beside micro-benchmarks of this machine doing the same operations
//    at their limit (streaming read, the gather of face records by Ω, exp() throughput).
// 3. Scale: subdivided meshes from 10⁴ to 5·10⁶ faces (`--scale`), each in a fresh process
//    (its peak resident memory is its own): set-up, time per iteration, peak memory.
//
// The subdivided meshes (tables 1–3) are the issue's: the shared pair's Noisy.obj, each level
// splitting every face 1-to-4 at its edge midpoints in place (face f -> faces 4f .. 4f+3), then
// all vertices renumbered in order of first appearance when the faces are read in order, corner
// by corner (load() below; docs/algorithms/rofi.md, "Issue 35 (session 20)").
//
// Usage: rofi_speed [--quick] [--rounds N] [--scale MAX_FACES] [--scale-iterations P]
//                   [--write-subdivided MESH_NAME LEVELS OUT] [SHARED_MESHES_DIR]
//        rofi_speed --phases MESH_NAME LEVELS ITERATIONS THREADS [SHARED_MESHES_DIR]
// --phases: one call, its time per phase (e.g. under `valgrind --tool=callgrind`).
// --quick: the two smaller meshes of table 1, one round, no scale table (≈ 5 s).
// Default: tables 1 and 2 (≈ 1 min on 2 cores). --scale 5400000 adds table 3 up to 5.3 M faces
// (≈ 3 min, ≈ 3.5 GiB at the largest). Run it on a quiet machine: the figures are wall clock.

#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <unordered_map>
#include <vector>

#include "octshape/io/mesh_io.h"
#include "octshape/mesh/components.h"
#include "octshape/mesh/mesh.h"
#include "octshape/mesh/rofi.h"
#include "octshape/mesh/simd_exp.h"

namespace {

namespace om = octshape::mesh;
using Clock = std::chrono::steady_clock;

double since(Clock::time_point t0) {
    return std::chrono::duration<double>(Clock::now() - t0).count();
}

// Reference numbers: the authors' own Java RoFi, headless, one warm JVM, denoise only, on
// this 2-core machine; σ_s 0.55, λ_I 0.2, 100 iterations, r = 2 c_a (~11.2 faces per
// neighbourhood). Source: issue 35's measurement (minimum of two rounds).
struct JavaReference {
    const char* mesh;   // shared pair (Noisy.obj)
    int subdivisions;   // 1-to-4 midpoint subdivisions of it
    int faces;          // after subdivision
    double java_seconds;
};
constexpr JavaReference kJava[] = {
    {"Fandisk0.3", 0, 12946, 3.17},
    {"Fandisk0.3", 1, 51784, 13.47},
    {"Twelve0.5Impulsive", 2, 147456, 46.64},
    {"Fandisk0.3", 2, 207136, 57.70},
};

struct Mesh {
    om::Vertices V;
    om::Faces F;
};

// One level of 1-to-4 midpoint subdivision: face f becomes faces 4f .. 4f+3, (a, ab, ca),
// (b, bc, ab), (c, ca, bc), (ab, bc, ca), where ab is the midpoint of edge (a, b), created
// once and shared by the two faces of the edge. Vertex numbering is fixed afterwards, in load().
void subdivide(Mesh& m) {
    std::unordered_map<long long, int> mid;
    mid.reserve(static_cast<std::size_t>(m.F.rows()) * 2);
    std::vector<double> v(m.V.data(), m.V.data() + m.V.size());
    // Copied as row-major triples (the vector grows as midpoints are appended).
    for (Eigen::Index i = 0; i < m.V.rows(); ++i) {
        for (int k = 0; k < 3; ++k) v[static_cast<std::size_t>(3 * i + k)] = m.V(i, k);
    }
    const auto midpoint = [&](int a, int b) {
        const long long key = static_cast<long long>(std::min(a, b)) << 32 | std::max(a, b);
        if (const auto it = mid.find(key); it != mid.end()) return it->second;
        const int id = static_cast<int>(v.size() / 3);
        for (int k = 0; k < 3; ++k) {
            v.push_back(0.5 * (v[static_cast<std::size_t>(3 * a + k)] +
                               v[static_cast<std::size_t>(3 * b + k)]));
        }
        mid.emplace(key, id);
        return id;
    };
    om::Faces out(m.F.rows() * 4, 3);
    for (Eigen::Index f = 0; f < m.F.rows(); ++f) {
        const int a = m.F(f, 0), b = m.F(f, 1), c = m.F(f, 2);
        const int ab = midpoint(a, b), bc = midpoint(b, c), ca = midpoint(c, a);
        out.row(4 * f) << a, ab, ca;
        out.row(4 * f + 1) << b, bc, ab;
        out.row(4 * f + 2) << c, ca, bc;
        out.row(4 * f + 3) << ab, bc, ca;
    }
    const auto n = static_cast<Eigen::Index>(v.size() / 3);
    m.V.resize(n, 3);
    for (Eigen::Index i = 0; i < n; ++i) {
        for (int k = 0; k < 3; ++k) m.V(i, k) = v[static_cast<std::size_t>(3 * i + k)];
    }
    m.F = std::move(out);
}

// The issue's meshes: the shared pair's Noisy.obj as it is for 0 subdivisions; otherwise
// `subdivisions` levels of subdivide() (each face split in place into four, so the faces stay
// in the order the splits produce: the input's order refined), then all vertices renumbered
// in order of first appearance when the faces are read in order, corner by corner
// (compact_faces keeping every face; a vertex no face uses would be dropped: the shared meshes
// have none). Renumbering after each level instead gives the same mesh: the order of first
// appearance depends on the face list only. Before session 20 the subdivided meshes kept the
// input's vertices first and appended each level's midpoints, so vertex order swept the
// surface once per level.
Mesh load(const std::filesystem::path& dir, const std::string& name, int subdivisions) {
    const auto data = octshape::io::read_mesh(dir / name / "Noisy.obj");
    Mesh m{data.V, data.F};
    for (int s = 0; s < subdivisions; ++s) subdivide(m);
    if (subdivisions > 0) {
        const std::vector<std::uint8_t> all(static_cast<std::size_t>(m.F.rows()), 1);
        om::compact_faces(m.V, m.F, all);
    }
    return m;
}

om::RofiParams issue_params(int threads, int iterations) {
    om::RofiParams p;
    p.sigma_s = 0.55;
    p.lambda_i = 0.2;
    p.iterations = iterations;
    p.radius_factor = 2.0;
    p.threads = threads;
    return p;
}

// --phases: one call on one mesh, its time per phase (for a profiler such as callgrind, which
// runs a few iterations of the large meshes in a minute).
void phases(const std::filesystem::path& dir, const std::string& mesh, int levels,
            int iterations, int threads) {
    const Mesh m = load(dir, mesh, levels);
    const auto out = om::rofi_denoise(m.V, m.F, issue_params(threads, iterations));
    const double faces = static_cast<double>(m.F.rows());
    const double k = 1e9 / out.iterations / faces;
    std::printf("%s, %d subdivision(s), %ld faces, %d thread(s), %d iterations: set-up %.1f "
                "ns/face, pair table %.1f, fold repair %.1f (once); per iteration, ns/face: "
                "face update %.2f, weights %.2f, sums %.2f, vertex step %.2f, whole %.2f; "
                "call %.4f s\n",
                mesh.c_str(), levels, static_cast<long>(m.F.rows()), threads, out.iterations,
                1e9 * out.seconds_setup / faces, 1e9 * out.phases.pair_table / faces,
                1e9 * out.seconds_fold_repair / faces, k * out.phases.faces,
                k * out.phases.weights, k * out.phases.sums, k * out.phases.vertices,
                k * (out.seconds_iterations - out.seconds_fold_repair - out.phases.pair_table),
                out.seconds_setup + out.seconds_iterations);
}

// Table 1.
void java_table(const std::filesystem::path& dir, int rounds, bool quick) {
    std::printf("RoFi against the authors' Java (issue 35's measurement: sigma_s 0.55, lambda_I "
                "0.2, 100 iterations, r = 2 c_a). Seconds of one call (set-up + iterations, "
                "wall clock), min of %d round(s); ratio = Java / ours.\n",
                rounds);
    std::printf("| %-24s | %7s | %5s | %8s | %8s | %7s | %8s | %7s |\n", "mesh", "faces",
                "|Om|", "Java s", "1 thr s", "ratio", "2 thr s", "ratio");
    for (const auto& ref : kJava) {
        if (quick && ref.faces > 60000) continue;
        const Mesh m = load(dir, ref.mesh, ref.subdivisions);
        double best[2] = {1e300, 1e300};
        double omega = 0.0;
        for (int r = 0; r < rounds; ++r) {
            for (int t = 0; t < 2; ++t) {  // alternate 1 and 2 threads within a round
                const auto out = om::rofi_denoise(m.V, m.F, issue_params(t + 1, 100));
                best[t] = std::min(best[t], out.seconds_setup + out.seconds_iterations);
                omega = out.mean_neighbourhood;
            }
        }
        const std::string name =
            std::string(ref.mesh) + (ref.subdivisions > 0 ? " x" + std::to_string(1 << (2 * ref.subdivisions)) : "");
        std::printf("| %-24s | %7ld | %5.2f | %8.2f | %8.4f | %6.0fx | %8.4f | %6.0fx |\n",
                    name.c_str(), static_cast<long>(m.F.rows()), omega, ref.java_seconds,
                    best[0], ref.java_seconds / best[0], best[1], ref.java_seconds / best[1]);
        std::fflush(stdout);
    }
}

// Micro-benchmarks: the same memory operations and arithmetic as the phases, at their limit.
struct Peaks {
    double stream_gbs = 0;        // sequential read of a large array
    double gather_ns_per_slot = 0;  // Σ over Ω of a face record's 4 doubles, nothing else
    double exp_ns = 0;            // simd_exp_nonpositive on a contiguous array, per value
};

Peaks measure_peaks(const Mesh& m, int rounds) {
    Peaks p;
    // Streaming read: 256 MiB, far beyond the caches.
    {
        std::vector<double> a(std::size_t{32} << 20, 1.0);
        double best = 1e300;
        double sink = 0;
        for (int r = 0; r < rounds + 1; ++r) {
            const auto t0 = Clock::now();
            double s0 = 0, s1 = 0, s2 = 0, s3 = 0;
            for (std::size_t i = 0; i < a.size(); i += 4) {
                s0 += a[i];
                s1 += a[i + 1];
                s2 += a[i + 2];
                s3 += a[i + 3];
            }
            sink += s0 + s1 + s2 + s3;
            best = std::min(best, since(t0));
        }
        p.stream_gbs = static_cast<double>(a.size() * sizeof(double)) / best * 1e-9;
        if (sink == 0) std::printf("(sink)\n");
    }
    // Gather over Ω: the memory access of the sum pass with no arithmetic beyond one add.
    {
        const om::Adjacency adj = om::build_adjacency(m.F, static_cast<int>(m.V.rows()));
        const om::FaceGeometry g = om::face_geometry(m.V, m.F);
        const double ca = om::mean_centroid_distance(g, adj);
        const om::Csr omega = om::disk_neighbourhoods(m.F, g, adj, 2.0 * ca, 1);
        struct alignas(64) Rec {
            double v[8];
        };
        std::vector<Rec> rec(static_cast<std::size_t>(m.F.rows()));
        for (std::size_t f = 0; f < rec.size(); ++f) {
            for (int k = 0; k < 8; ++k) rec[f].v[k] = 1e-3 * static_cast<double>(k + f % 7);
        }
        double best = 1e300;
        double sink = 0;
        for (int r = 0; r < rounds + 2; ++r) {
            const auto t0 = Clock::now();
            for (int i = 0; i < omega.rows(); ++i) {
                double s0 = 0, s1 = 0, s2 = 0, s3 = 0;
                for (int q = omega.begin(i); q < omega.end(i); ++q) {
                    const Rec& x = rec[static_cast<std::size_t>(omega.item(q))];
                    s0 += x.v[0];
                    s1 += x.v[1];
                    s2 += x.v[2];
                    s3 += x.v[3];
                }
                sink += s0 + s1 + s2 + s3;
            }
            best = std::min(best, since(t0));
        }
        p.gather_ns_per_slot = 1e9 * best / static_cast<double>(omega.items.size());
        if (sink == 0) std::printf("(sink)\n");
    }
    // exp() throughput on the vector path RoFi uses.
    {
        std::vector<double> x(1 << 16), y(x.size());
        for (std::size_t i = 0; i < x.size(); ++i) x[i] = -0.001 * static_cast<double>(i % 5000);
        double best = 1e300;
        for (int r = 0; r < rounds + 2; ++r) {
            const auto t0 = Clock::now();
            for (int k = 0; k < 20; ++k) om::simd_exp_nonpositive(x.data(), y.data(), x.size());
            best = std::min(best, since(t0));
        }
        p.exp_ns = 1e9 * best / (20.0 * static_cast<double>(x.size()));
    }
    return p;
}

// Table 2 on one mesh: per-phase time of one thread beside the peaks.
void roofline(const std::filesystem::path& dir, int rounds) {
    const Mesh m = load(dir, "Fandisk0.3", 2);
    const Peaks peaks = measure_peaks(m, rounds);
    om::DenoiseResult best;
    double best_total = 1e300;
    for (int r = 0; r < rounds; ++r) {
        auto out = om::rofi_denoise(m.V, m.F, issue_params(1, 100));
        const double total = out.seconds_iterations;
        if (total < best_total) {
            best_total = total;
            best = std::move(out);
        }
    }
    const double faces = static_cast<double>(m.F.rows());
    const double slots = best.mean_neighbourhood * faces;  // face-neighbour pairs (centre incl.)
    const double it = best.iterations;
    std::printf("\nRoofline: Fandisk0.3 x16 (%ld faces, %.2f faces per neighbourhood), one thread, "
                "100 iterations (the run with the smallest iteration time of %d).\n"
                "Peaks measured here: streaming read %.1f GB/s; gather of a face record per "
                "slot of Omega (the sums' memory access, no arithmetic) %.2f ns/slot; exp() "
                "%.2f ns/value.\n",
                static_cast<long>(m.F.rows()), best.mean_neighbourhood, rounds, peaks.stream_gbs,
                peaks.gather_ns_per_slot, peaks.exp_ns);
    std::printf("| %-14s | %9s | %9s | %9s |\n", "phase", "ms/iter", "ns/face", "ns/slot");
    const auto line = [&](const char* phase, double seconds, double per_call) {
        std::printf("| %-14s | %9.3f | %9.2f | %9.3f |\n", phase, 1e3 * seconds / per_call,
                    1e9 * seconds / per_call / faces, 1e9 * seconds / per_call / slots);
    };
    line("neighbourhoods", best.seconds_setup, 1.0);
    line("pair table", best.phases.pair_table, 1.0);
    line("fold repair", best.seconds_fold_repair, 1.0);
    line("face update", best.phases.faces, it);
    line("weights", best.phases.weights, it);
    line("sums", best.phases.sums, it);
    line("vertex step", best.phases.vertices, it);
    line("iteration",
         best.seconds_iterations - best.seconds_fold_repair - best.phases.pair_table, it);
    // The stop test runs only with RofiStop::kWhiteResidual: one run with it, tested every
    // iteration where the stop asks (about every other).
    om::RofiParams p = issue_params(1, 100);
    p.stop = om::RofiStop::kWhiteResidual;
    const auto s = om::rofi_denoise(m.V, m.F, p);
    std::printf("| %-14s | %9.3f | %9.2f | %9.3f |   (per iteration run, %d iterations, stop on)\n",
                "stop test", 1e3 * s.phases.stop / s.iterations,
                1e9 * s.phases.stop / s.iterations / faces,
                1e9 * s.phases.stop / s.iterations / slots, s.iterations);
    std::fflush(stdout);
}

long peak_rss_kib() {
    rusage u{};
    getrusage(RUSAGE_SELF, &u);
    return u.ru_maxrss;
}

// One row of table 3, in this (fresh) process.
void scale_row(const std::filesystem::path& dir, const std::string& mesh, int subdivisions,
               int iterations, int threads) {
    const Mesh m = load(dir, mesh, subdivisions);
    const long before = peak_rss_kib();
    om::RofiParams p = issue_params(threads, iterations);
    p.repair_folds = false;
    const auto out = om::rofi_denoise(m.V, m.F, p);
    const long peak = peak_rss_kib();
    const double faces = static_cast<double>(m.F.rows());
    const double per = (out.seconds_iterations) / out.iterations;
    std::printf("| %-24s | %9ld | %5.2f | %3d | %8.3f | %9.2f | %8.1f | %8.1f | %8.0f | %8.0f |\n",
                (mesh + " x" + std::to_string(1 << (2 * subdivisions))).c_str(),
                static_cast<long>(m.F.rows()), out.mean_neighbourhood, threads, out.seconds_setup,
                1e3 * per, 1e9 * per / faces, 1e9 * out.seconds_setup / faces,
                static_cast<double>(peak) / 1024.0,
                1024.0 * static_cast<double>(peak - before) / faces);
    std::fflush(stdout);
}

// Table 3: each size in a child process (fresh peak memory).
void scale_table(const char* self, const std::filesystem::path& dir, long max_faces,
                 int iterations) {
    std::printf("\nScale: RoFi (issue parameters, no fold repair), %d iterations; subdivided "
                "shared meshes, each in a fresh process. peak MiB = the process's peak resident "
                "memory (mesh, its copy and RoFi); B/face = RoFi's part (peak minus the peak "
                "before the call) per face.\n",
                iterations);
    std::printf("| %-24s | %9s | %5s | %3s | %8s | %9s | %8s | %8s | %8s | %8s |\n", "mesh",
                "faces", "|Om|", "thr", "set-up s", "ms/iter", "ns/f/it", "ns/f set", "peak MiB",
                "B/face");
    std::fflush(stdout);
    struct Size {
        const char* mesh;
        int faces;
    };
    for (const Size base : {Size{"Fandisk0.3", 12946}, Size{"SharpSphere0.3", 20882}}) {
        for (int s = 0; s <= 5; ++s) {
            const long faces = static_cast<long>(base.faces) << (2 * s);
            if (faces > max_faces) break;
            // The second base fills in the largest size only.
            if (base.faces == 20882 && faces * 4 <= max_faces) continue;
            for (int threads = 1; threads <= 2; ++threads) {
                const pid_t pid = fork();
                if (pid == 0) {
                    scale_row(dir, base.mesh, s, iterations, threads);
                    std::_Exit(0);
                }
                int status = 0;
                waitpid(pid, &status, 0);
                if (status != 0) std::printf("(%s x%d failed: status %d)\n", base.mesh, 1 << (2 * s), status);
            }
        }
    }
    (void)self;
}

}  // namespace

int main(int argc, char** argv) {
    std::filesystem::path dir = OCTSHAPE_SHARED_MESHES;
    bool quick = false;
    int rounds = 3;
    long scale = 0;
    int scale_iterations = 10;
    for (int a = 1; a < argc; ++a) {
        const std::string arg = argv[a];
        if (arg == "--phases" && a + 4 < argc) {
            const std::filesystem::path at = a + 5 < argc ? argv[a + 5] : dir;
            phases(at, argv[a + 1], std::atoi(argv[a + 2]), std::atoi(argv[a + 3]),
                   std::atoi(argv[a + 4]));
            return 0;
        } else if (arg == "--quick") {
            quick = true;
            rounds = 1;
        } else if (arg == "--rounds" && a + 1 < argc) {
            rounds = std::max(1, std::atoi(argv[++a]));
        } else if (arg == "--scale" && a + 1 < argc) {
            scale = std::atol(argv[++a]);
        } else if (arg == "--scale-iterations" && a + 1 < argc) {
            scale_iterations = std::max(1, std::atoi(argv[++a]));
        } else if (arg == "--write-subdivided" && a + 3 < argc) {
            const std::string mesh = argv[a + 1];
            const int levels = std::atoi(argv[a + 2]);
            const Mesh m = load(dir, mesh, levels);
            octshape::io::write_mesh(argv[a + 3], m.V, m.F);
            std::printf("%s x%d: %ld faces -> %s\n", mesh.c_str(), 1 << (2 * levels),
                        static_cast<long>(m.F.rows()), argv[a + 3]);
            return 0;
        } else if (!arg.empty() && arg[0] != '-') {
            dir = arg;
        } else {
            std::fprintf(stderr,
                         "usage: rofi_speed [--quick] [--rounds N] [--scale MAX_FACES] "
                         "[--scale-iterations P] [--write-subdivided MESH LEVELS OUT] [DIR]\n"
                         "       rofi_speed --phases MESH LEVELS ITERATIONS THREADS [DIR]\n");
            return 64;
        }
    }
    // The scale table first: its children are forked before this process starts any thread.
    if (scale > 0) scale_table(argv[0], dir, scale, scale_iterations);
    java_table(dir, rounds, quick);
    if (!quick) roofline(dir, rounds);
    return 0;
}
