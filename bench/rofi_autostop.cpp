// RoFi's automatic rule with its discrepancy stop against an oracle (docs/algorithms/rofi.md,
// "Stopping"). Usage:
//   rofi_autostop [--full] [--no-oracle] [--noise] [--curves FILE] [--trace FILE] [--cost]
//                 [--reps N] [--only NAME,...] [--one stop|plain|none|hash] [--bunny OBJ]
//                 [--meshes DIR]
// The family (clean geometry known, noise added here): a sphere with fine relief, a
// super-ellipsoid (rounded cube), VTK's random hills, the Stanford bunny (Loop-subdivided
// once; `--bunny`, written by scripts/mesh_family.sh, skipped if absent), each with Gaussian
// noise of level × l_e along the vertex normals ("n") and per coordinate ("c"); plus the shared
// pairs of ../shared/meshes. Default: level 0.3, both models, seed 1 (about 2 minutes on an
// idle core); --full: levels 0.1, 0.3, 0.5 and seeds 1, 2.
// For each mesh: the oracle (the best MSAE over a grid of (σ_s, λ_I, p, r, σ_c), p read off
// every run at the iterations listed in kEval), the automatic rule (its chosen p and time),
// the session-8 rule (p = 30, no stop), the bilateral filter (automatic and its own oracle
// over σ_s and p) and ENVT (automatic). MSAE in degrees; "cr" = flips created (flipped in the
// output, not in the input). The cost table times the rule with its stop against the same
// parameters and the same p without it (CPU s, one thread, min of 5, interleaved).
// --curves FILE writes every run's (k, δ_k / l_e, MSAE_k, created_k) as TSV, for the analysis
// (bench/rofi_oracle_analysis.py CURVES TRACE [SIGMAS]: the gap to the oracle split into the
// stop's part and the parameters' part; scripts/bench.sh runs it on the default cases).
// --trace FILE: the automatic rule's parameters alone, run to kMaxIterations without a stop,
// every iteration's RofiProgress, MSAE and created flips, and the mesh's noise estimate (σ̂_n in
// l_e, θ in degrees) and the rule's maximum p as TSV (the curves of "Stopping"; bench/rofi_oracle_analysis.py);
// --trace-sigma A,B,...: the same with these σ_s instead of the rule's.
// --cost: the cost table alone, --reps N interleaved pairs (default 9), medians.
// --only NAME,...: the cases whose name starts with one of these.
// --one MODE: one call on the first case, for `valgrind --tool=callgrind` instruction counts
// (load-independent): the rule with its stop ("stop"), the same p without it ("plain"), or
// none (the set-up of the process); the test's cost is (stop − plain) / (plain − none).
// "hash": every case's automatic result as a hash of its bits, p, W and δ (refactoring check).

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>
#include <vector>

#include <vtkCellArray.h>
#include <vtkCleanPolyData.h>
#include <vtkIdList.h>
#include <vtkLoopSubdivisionFilter.h>
#include <vtkNew.h>
#include <vtkParametricFunctionSource.h>
#include <vtkParametricRandomHills.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkTriangleFilter.h>

#include "mesh/mesh_fixtures.h"
#include "octshape/io/mesh_io.h"
#include "octshape/mesh/envt.h"
#include "octshape/mesh/folds.h"
#include "octshape/mesh/metrics.h"
#include "octshape/mesh/rofi.h"

namespace {

namespace mesh = octshape::mesh;
namespace test = octshape::test;

constexpr int kMaxIterations = 80;

bool evaluated(int k) { return k <= 20 || k % 5 == 0; }

struct Case {
    std::string name;
    mesh::Vertices clean;
    mesh::Vertices noisy;
    mesh::Faces F;
};

mesh::Vertices to_vertices(vtkPolyData* pd) {
    mesh::Vertices V(pd->GetNumberOfPoints(), 3);
    for (vtkIdType i = 0; i < pd->GetNumberOfPoints(); ++i) {
        double p[3];
        pd->GetPoint(i, p);
        V.row(i) << p[0], p[1], p[2];
    }
    return V;
}

mesh::Faces to_faces(vtkPolyData* pd) {
    mesh::Faces F(pd->GetNumberOfPolys(), 3);
    vtkNew<vtkIdList> ids;
    vtkCellArray* polys = pd->GetPolys();
    polys->InitTraversal();
    Eigen::Index f = 0;
    while (polys->GetNextCell(ids) != 0) {
        if (ids->GetNumberOfIds() != 3) continue;
        F.row(f++) << static_cast<int>(ids->GetId(0)), static_cast<int>(ids->GetId(1)),
            static_cast<int>(ids->GetId(2));
    }
    F.conservativeResize(f, 3);
    return F;
}

test::TestMesh random_hills() {
    vtkNew<vtkParametricRandomHills> hills;
    hills->AllowRandomGenerationOn();
    hills->SetRandomSeed(3);
    hills->SetNumberOfHills(40);
    vtkNew<vtkParametricFunctionSource> source;
    source->SetParametricFunction(hills);
    source->SetUResolution(80);
    source->SetVResolution(80);
    source->SetScalarModeToNone();
    source->GenerateTextureCoordinatesOff();
    source->GenerateNormalsOff();
    vtkNew<vtkTriangleFilter> tri;
    tri->SetInputConnection(source->GetOutputPort());
    tri->Update();
    return {"random_hills", to_vertices(tri->GetOutput()), to_faces(tri->GetOutput())};
}

test::TestMesh bunny(const std::filesystem::path& obj) {
    const auto data = octshape::io::read_mesh(obj);
    vtkNew<vtkPoints> points;
    for (Eigen::Index i = 0; i < data.V.rows(); ++i) {
        points->InsertNextPoint(data.V(i, 0), data.V(i, 1), data.V(i, 2));
    }
    vtkNew<vtkCellArray> cells;
    for (Eigen::Index f = 0; f < data.F.rows(); ++f) {
        const vtkIdType ids[3] = {data.F(f, 0), data.F(f, 1), data.F(f, 2)};
        cells->InsertNextCell(3, ids);
    }
    vtkNew<vtkPolyData> pd;
    pd->SetPoints(points);
    pd->SetPolys(cells);
    vtkNew<vtkCleanPolyData> clean;
    clean->SetInputData(pd);
    vtkNew<vtkLoopSubdivisionFilter> loop;
    loop->SetInputConnection(clean->GetOutputPort());
    loop->SetNumberOfSubdivisions(1);
    loop->Update();
    return {"bunny", to_vertices(loop->GetOutput()), to_faces(loop->GetOutput())};
}

double cpu_seconds() { return static_cast<double>(std::clock()) / CLOCKS_PER_SEC; }

struct Point {
    int k = 0;
    double delta = 0;  // δ_k / l_e
    double whiteness = 0;  // W_k
    double msae = 0;
    int created = 0;
};

struct Config {
    std::string label;
    mesh::RofiParams params;
};

struct Best {
    double msae = std::numeric_limits<double>::infinity();
    int created = 0;
    std::string where;
};

// One run of `params` up to kMaxIterations, MSAE and created flips (after the fold repair, as
// rofi_denoise returns them) at every evaluated k.
std::vector<Point> curve(const Case& c, mesh::RofiParams params, double le,
                         const std::vector<std::uint8_t>& fixed) {
    std::vector<Point> out;
    params.iterations = kMaxIterations;
    params.stop = mesh::RofiStop::kNone;
    params.observer = [&](int k, const mesh::Vertices& V, const mesh::RofiProgress& progress) {
        if (!evaluated(k)) return;
        mesh::Vertices W = V;
        (void)mesh::repair_folds(W, c.F, fixed);
        out.push_back({k, progress.displacement / le, progress.whiteness,
                       mesh::mean_angle_error_deg(W, c.F, c.clean, c.F),
                       mesh::flip_transitions(W, c.noisy, c.clean, c.F).created});
    };
    (void)mesh::rofi_denoise(c.noisy, c.F, params);
    return out;
}

std::string fmt(const char* f, double a, double b, double c2, double d, double e) {
    char buf[96];
    std::snprintf(buf, sizeof buf, f, a, b, c2, d, e);
    return buf;
}

double median(std::vector<double> v) {
    std::sort(v.begin(), v.end());
    const std::size_t n = v.size();
    return n == 0 ? 0.0 : n % 2 == 1 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

bool selected(const std::string& name, const std::string& only) {
    if (only.empty()) return true;
    std::size_t b = 0;
    while (b <= only.size()) {
        const std::size_t e = std::min(only.find(',', b), only.size());
        if (e > b && name.compare(0, e - b, only, b, e - b) == 0) return true;
        b = e + 1;
    }
    return false;
}

}  // namespace

// Long (323 lines, over the 150 of the style) on purpose: a benchmark's main is its protocol, read
// top to bottom against the tables it prints (docs/algorithms); it ships no result.
int main(int argc, char** argv) {
    bool full = false;
    bool no_oracle = false;   // --no-oracle: the automatic rules only (no grid)
    bool noise_only = false;  // --noise: the noise estimates of every case, nothing else
    bool cost_only = false;   // --cost: the cost table alone
    int reps = 9;
    std::string curves_path, trace_path, only, one;
    std::vector<double> trace_sigmas;  // --trace-sigma: σ_s values traced instead of the rule's
    std::filesystem::path bunny_obj = "build/mesh_family/bunny.obj";
    std::filesystem::path meshes = OCTSHAPE_SHARED_MESHES;
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        if (a == "--full") {
            full = true;
        } else if (a == "--no-oracle") {
            no_oracle = true;
        } else if (a == "--noise") {
            noise_only = true;
        } else if (a == "--cost") {
            cost_only = true;
        } else if (a == "--reps" && i + 1 < argc) {
            reps = std::max(1, std::atoi(argv[++i]));
        } else if (a == "--curves" && i + 1 < argc) {
            curves_path = argv[++i];
        } else if (a == "--trace" && i + 1 < argc) {
            trace_path = argv[++i];
        } else if (a == "--trace-sigma" && i + 1 < argc) {
            const std::string list = argv[++i];
            for (std::size_t b = 0; b < list.size();) {
                const std::size_t e = std::min(list.find(',', b), list.size());
                trace_sigmas.push_back(std::atof(list.substr(b, e - b).c_str()));
                b = e + 1;
            }
        } else if (a == "--only" && i + 1 < argc) {
            only = argv[++i];
        } else if (a == "--one" && i + 1 < argc) {
            one = argv[++i];
        } else if (a == "--bunny" && i + 1 < argc) {
            bunny_obj = argv[++i];
        } else if (a == "--meshes" && i + 1 < argc) {
            meshes = argv[++i];
        } else {
            std::fprintf(stderr,
                         "usage: rofi_autostop [--full] [--no-oracle] [--noise] [--curves FILE] "
                         "[--trace FILE] [--trace-sigma A,B,...] [--cost] [--reps N] [--only NAME,...] "
                         "[--one stop|plain|none|hash] [--bunny OBJ] [--meshes DIR]\n");
            return 2;
        }
    }
    std::vector<test::TestMesh> shapes = {test::relief_sphere(5), test::superellipsoid(5),
                                          random_hills()};
    if (std::filesystem::exists(bunny_obj)) {
        shapes.push_back(bunny(bunny_obj));
    } else {
        std::printf("(no %s: run scripts/mesh_family.sh for the bunny)\n", bunny_obj.c_str());
    }
    const std::vector<double> levels = full ? std::vector<double>{0.1, 0.3, 0.5}
                                            : std::vector<double>{0.3};
    const std::vector<std::uint32_t> seeds = full ? std::vector<std::uint32_t>{1, 2}
                                                  : std::vector<std::uint32_t>{1};
    // The shared pairs first, then the family seed by seed (a partial run still covers every
    // shape and level).
    std::vector<Case> cases;
    for (const char* pair : {"Fandisk0.3", "Block0.4", "Twelve0.5Impulsive", "SharpSphere0.3"}) {
        const auto dir = meshes / pair;
        if (!selected(pair, only) || !std::filesystem::exists(dir / "Noisy.obj")) continue;
        const auto o = octshape::io::read_mesh(dir / "Original.obj");
        const auto n = octshape::io::read_mesh(dir / "Noisy.obj");
        cases.push_back({pair, o.V, n.V, n.F});
    }
    for (const auto seed : seeds) {
        for (const auto& s : shapes) {
            const double le = mesh::mean_edge_length(s.V, s.F);
            for (const double level : levels) {
                for (const char model : {'n', 'c'}) {
                    char name[96];
                    std::snprintf(name, sizeof name, "%s %.1f%c s%u", s.name.c_str(), level,
                                  model, seed);
                    if (!selected(name, only)) continue;
                    const test::TestMesh noisy =
                        model == 'n' ? test::with_normal_noise(s, level * le, seed)
                                     : test::with_noise(s, level * le, seed);
                    cases.push_back({name, s.V, noisy.V, s.F});
                }
            }
        }
    }

    const auto run = [](const Case& c, const mesh::RofiParams& p, double* seconds) {
        const double t0 = cpu_seconds();
        mesh::DenoiseResult r = mesh::rofi_denoise(c.noisy, c.F, p);
        if (seconds != nullptr) *seconds = cpu_seconds() - t0;
        return r;
    };
    if (one == "hash") {
        // Every case's automatic result as bits (FNV-1a of the output vertices), p, W and δ:
        // for checking that a change of the stopping test's code keeps its results.
        for (const Case& c : cases) {
            const mesh::DenoiseResult r =
                run(c, mesh::auto_rofi_params(mesh::estimate_noise(c.noisy, c.F)), nullptr);
            std::uint64_t h = 1469598103934665603ULL;
            const auto* bytes = reinterpret_cast<const unsigned char*>(r.V.data());
            for (std::size_t b = 0; b < sizeof(double) * static_cast<std::size_t>(r.V.size());
                 ++b) {
                h = (h ^ bytes[b]) * 1099511628211ULL;
            }
            std::printf("%-26s p=%2d W=%.17g delta=%.17g %016llx\n", c.name.c_str(),
                        r.iterations, r.residual_whiteness, r.displacement,
                        static_cast<unsigned long long>(h));
        }
        return 0;
    }
    if (!one.empty()) {
        // One call for an instruction count: everything above is the same in every mode.
        if (cases.empty()) return 2;
        const Case& c = cases.front();
        mesh::RofiParams ap = mesh::auto_rofi_params(mesh::estimate_noise(c.noisy, c.F));
        int p = 0;
        if (one == "stop") {
            p = run(c, ap, nullptr).iterations;
        } else if (one == "plain") {
            // The p the stop chooses, as a number (the stop's own run would be counted).
            const char* env = std::getenv("ROFI_P");
            ap.stop = mesh::RofiStop::kNone;
            ap.iterations = env != nullptr ? std::atoi(env) : ap.iterations;
            p = run(c, ap, nullptr).iterations;
        } else if (one != "none") {
            return 2;
        }
        std::printf("%s %s p=%d\n", c.name.c_str(), one.c_str(), p);
        return 0;
    }

    std::ofstream curves, trace;
    if (!curves_path.empty()) {
        curves.open(curves_path);
        curves << "mesh\tconfig\tsigma_s\tlambda_i\tr\tsigma_c\tk\tdelta_le\twhiteness\tmsae\t"
                  "created\n";
    }
    if (!trace_path.empty()) {
        trace.open(trace_path);
        trace << "mesh\tsigma_s\tk\tdelta_le\twhiteness\tthreshold\ttested\tmsae\tcreated\t"
                 "features\tfeature_rms_le\tflat_rms_le\tnoise_sigma_le\tnormal_angle_deg\t"
                 "rule_iterations\n";
    }
    if (!cost_only) {
        std::printf("%-26s %7s %6s %6s | %4s %7s %4s | %7s %4s %-22s | %7s %4s | %7s %4s %7s "
                    "%4s | %7s %4s | %7s\n",
                    "mesh", "faces", "sig^n", "theta", "p", "auto", "cr", "oracle", "cr",
                    "(s_s, l_I, p, r, s_c)", "today", "cr", "bil.au", "cr", "bil.or", "cr",
                    "envt", "cr", "in.flip");
    }
    struct Cost {
        std::string name;
        int faces, p;
        double with_stop, without, ratio;
        double msae_auto, msae_oracle, msae_today;
    };
    std::vector<Cost> costs;
    for (const Case& c : cases) {
        const mesh::NoiseEstimate noise = mesh::estimate_noise(c.noisy, c.F);
        if (noise_only) {
            std::printf("%-26s %7d %6.3f %6.2f\n", c.name.c_str(),
                        static_cast<int>(c.F.rows()), noise.noise_sigma, noise.normal_angle_deg);
            continue;
        }
        const double le = noise.mean_edge_length;
        const mesh::Adjacency adj = mesh::build_adjacency(c.F, static_cast<int>(c.noisy.rows()));
        const std::vector<std::uint8_t>& fixed = adj.boundary_vertex;
        const auto score = [&](const mesh::Vertices& V) {
            return std::pair{mesh::mean_angle_error_deg(V, c.F, c.clean, c.F),
                             mesh::flip_transitions(V, c.noisy, c.clean, c.F).created};
        };
        const mesh::RofiParams ap = mesh::auto_rofi_params(noise);
        if (trace.is_open()) {
            std::vector<double> sigmas = trace_sigmas;
            if (sigmas.empty()) sigmas.push_back(ap.sigma_s);
            for (const double sigma : sigmas) {
                mesh::RofiParams tp = ap;
                tp.sigma_s = sigma;
                tp.stop = mesh::RofiStop::kNone;
                tp.iterations = kMaxIterations;
                tp.observer = [&](int k, const mesh::Vertices& V, const mesh::RofiProgress& q) {
                    mesh::Vertices W = V;
                    (void)mesh::repair_folds(W, c.F, fixed);
                    const auto [m, cr] = score(W);
                    trace << c.name << '\t' << sigma << '\t' << k << '\t'
                          << q.displacement / le << '\t' << q.whiteness << '\t' << q.threshold
                          << '\t' << q.tested_vertices << '\t' << m << '\t' << cr << '\t'
                          << q.feature_vertices << '\t' << q.feature_rms / le << '\t'
                          << q.flat_rms / le << '\t' << noise.noise_sigma << '\t'
                          << noise.normal_angle_deg << '\t' << ap.iterations << '\n';
                };
                (void)mesh::rofi_denoise(c.noisy, c.F, tp);
            }
            trace.flush();
            if (cost_only || no_oracle) continue;
        }
        std::vector<Config> grid;
        for (const double ss : {0.3, 0.5, 0.7, 0.9, 1.2}) {
            for (const double li : {0.05, 0.2}) {
                for (const double sc : {1.0, 1.5, 2.0}) {
                    mesh::RofiParams p;
                    p.sigma_s = ss;
                    p.lambda_i = li;
                    p.sigma_c_factor = sc;
                    p.radius_factor = 2.0 * sc;
                    grid.push_back({"grid", p});
                }
            }
        }
        grid.push_back({"today", mesh::fixed_p_rofi_params(noise)});
        grid.push_back({"paper_auto", mesh::paper_disk_rofi_params(noise)});
        std::vector<Config> bil;
        for (const double ss : {0.15, 0.25, 0.35, 0.5}) {
            mesh::RofiParams p;
            p.similarity = mesh::Similarity::kGaussian;
            p.sigma_s = ss;
            p.lambda_i = 0.0;
            bil.push_back({"bilateral", p});
        }
        mesh::RofiParams bil_auto = mesh::paper_disk_rofi_params(noise);
        bil_auto.similarity = mesh::Similarity::kGaussian;
        bil_auto.sigma_s /= 2.2;  // as `octshape denoise --method bilateral` (app/commands)
        bil_auto.lambda_i = 0.0;
        bil.push_back({"bilateral_auto", bil_auto});

        Best oracle, bil_oracle;
        const auto scan = [&](const std::vector<Config>& configs, Best& best) {
            for (const Config& cfg : configs) {
                const auto pts = curve(c, cfg.params, le, fixed);
                for (const Point& q : pts) {
                    if (curves.is_open()) {
                        curves << c.name << '\t' << cfg.label << '\t' << cfg.params.sigma_s
                               << '\t' << cfg.params.lambda_i << '\t'
                               << cfg.params.radius_factor << '\t' << cfg.params.sigma_c_factor
                               << '\t' << q.k << '\t' << q.delta << '\t' << q.whiteness << '\t'
                               << q.msae << '\t' << q.created << '\n';
                    }
                    if (cfg.label != "grid" && cfg.label != "bilateral") continue;
                    if (q.msae < best.msae) {
                        best.msae = q.msae;
                        best.created = q.created;
                        best.where = fmt("(%.2g, %.2g, %.0f, %.0f, %.1f)", cfg.params.sigma_s,
                                         cfg.params.lambda_i, q.k, cfg.params.radius_factor,
                                         cfg.params.sigma_c_factor);
                    }
                }
            }
        };
        if (!no_oracle && !cost_only) {
            scan(grid, oracle);
            scan(bil, bil_oracle);
        }

        // The stop against the same parameters and p without it: `reps` pairs of calls,
        // interleaved and in alternating order (the machine's load drifts); the ratio of each
        // pair, and the medians.
        const mesh::DenoiseResult ar = run(c, ap, nullptr);
        mesh::RofiParams plain = ap;
        plain.stop = mesh::RofiStop::kNone;
        plain.iterations = ar.iterations;
        std::vector<double> ts, tp, ratio;
        for (int rep = 0; rep < reps; ++rep) {
            double a = 0, b = 0;
            if (rep % 2 == 0) {
                (void)run(c, ap, &a);
                (void)run(c, plain, &b);
            } else {
                (void)run(c, plain, &b);
                (void)run(c, ap, &a);
            }
            ts.push_back(a);
            tp.push_back(b);
            ratio.push_back(a / b);
        }
        const mesh::DenoiseResult tr = run(c, mesh::fixed_p_rofi_params(noise), nullptr);
        const auto [am, ac] = score(ar.V);
        const auto [tm, tc] = score(tr.V);
        costs.push_back({c.name, static_cast<int>(c.F.rows()), ar.iterations, median(ts),
                         median(tp), median(ratio), am, no_oracle || cost_only ? -1.0 : oracle.msae,
                         tm});
        if (cost_only) continue;
        const mesh::DenoiseResult br = run(c, bil_auto, nullptr);
        const mesh::DenoiseResult er =
            mesh::envt_denoise(c.noisy, c.F, mesh::auto_envt_params(noise));
        const auto [bm, bc] = score(br.V);
        const auto [em, ec] = score(er.V);
        const int input_flips = mesh::flipped_faces(c.noisy, c.F, c.clean, c.F);
        // Without the grid (--no-oracle) the oracle columns print as "-".
        char orc[64] = "      -    -", bor[32] = "      -    -";
        if (!no_oracle) {
            std::snprintf(orc, sizeof orc, "%7.3f %4d", oracle.msae, oracle.created);
            std::snprintf(bor, sizeof bor, "%7.3f %4d", bil_oracle.msae, bil_oracle.created);
        }
        std::printf("%-26s %7d %6.3f %6.2f | %4d %7.3f %4d | %s %-22s | %7.3f %4d | "
                    "%7.3f %4d %s | %7.3f %4d | %7d\n",
                    c.name.c_str(), static_cast<int>(c.F.rows()), noise.noise_sigma,
                    noise.normal_angle_deg, ar.iterations, am, ac, orc, oracle.where.c_str(), tm,
                    tc, bm, bc, bor, em, ec, input_flips);
        std::fflush(stdout);
    }
    if (costs.empty()) return 0;
    std::printf("\nCost of the stopping test (CPU s of one call, one thread, medians of %d "
                "interleaved pairs): the automatic rule with its stop against the same "
                "parameters run for the same p without it; MSAE in degrees (today = session 8, "
                "p = 30)\n",
                reps);
    std::printf("%-26s %7s %4s %9s %9s %9s | %7s %7s %7s\n", "mesh", "faces", "p", "stop s",
                "no-stop s", "overhead", "auto", "oracle", "today");
    std::vector<double> all;
    for (const Cost& k : costs) {
        char orc[16] = "      -";
        if (k.msae_oracle >= 0) std::snprintf(orc, sizeof orc, "%7.3f", k.msae_oracle);
        std::printf("%-26s %7d %4d %9.4f %9.4f %8.1f%% | %7.3f %s %7.3f\n", k.name.c_str(),
                    k.faces, k.p, k.with_stop, k.without, 100.0 * (k.ratio - 1.0), k.msae_auto,
                    orc, k.msae_today);
        all.push_back(k.ratio);
    }
    std::printf("median overhead over the %zu meshes: %.1f%%\n", all.size(),
                100.0 * (median(all) - 1.0));
    return 0;
}
