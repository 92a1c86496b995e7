// `octshape denoise IN -o OUT --method rofi|envt|bilateral`: feature-preserving mesh
// denoising (thesis §5 RoFi, §3 ENVT; docs/algorithms/rofi.md, envt.md).

#include <chrono>
#include <iostream>
#include <optional>
#include <string>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include "commands/command.h"
#include "commands/mesh_common.h"
#include "octshape/io/pointset_io.h"
#include "octshape/io/sha256.h"
#include "octshape/mesh/envt.h"
#include "octshape/mesh/pointset.h"
#include "octshape/mesh/rofi.h"

namespace octshape::app {
namespace {

struct DenoiseOptions {
    std::string input;
    std::string output;
    std::string method = "rofi";
    bool record_paths = false;
    std::string similarity;
    bool use_auto = false;
    std::optional<double> sigma_s;
    std::optional<double> lambda_i;
    std::optional<int> iterations;
    std::optional<double> tau;
    std::optional<double> radius_mm;
    std::optional<double> radius_factor;   // rofi/bilateral: r in units of c_a
    std::optional<double> sigma_c_factor;  // rofi/bilateral: σ_c in units of c_a
    int threads = 1;
    bool json = false;
    std::optional<double> rho;
    std::optional<double> epsilon_mm;
    std::optional<std::string> normals;  // pointset: pca | shifted
    bool no_edge_snap = false;           // pointset: skip the final edge snapping
    bool no_fold_repair = false;         // Eq. 5.1–5.9 / 3.1–3.7 alone (folds.h)
};

// --method pointset: point-set NVT denoising (thesis §4, docs/algorithms/pointset.md).
void run_pointset_denoise(const DenoiseOptions& o) {
    Provenance prov("denoise");
    if (o.use_auto) throw UsageError("--auto applies to the mesh methods");
    mesh::PointSetParams p;
    if (o.tau) p.tau = *o.tau;
    if (o.rho) p.rho = *o.rho;
    if (o.radius_mm) p.radius = *o.radius_mm;
    if (o.epsilon_mm) p.epsilon = *o.epsilon_mm;
    if (o.normals) {
        p.normals = *o.normals == "shifted" ? mesh::NormalEstimator::kShifted
                                            : mesh::NormalEstimator::kPca;
    }
    if (o.iterations) p.iterations = *o.iterations;
    p.snap_edges = !o.no_edge_snap;
    p.threads = o.threads;
    p.validate();
    const mesh::Vertices points = io::read_point_set(o.input);
    (void)io::point_set_format_from_extension(o.output);
    mesh::PointSetResult r;
    try {
        r = mesh::pointset_denoise(points, p);
    } catch (const DataError& e) {
        throw InputError::corrupt(o.input, e.what());
    }
    const std::string input_sha = io::sha256_file(o.input);
    const nlohmann::json parameters = {
        {"tau", p.tau}, {"rho_rad", p.rho}, {"iterations", p.iterations},
        {"damping", p.damping}, {"lambda", p.lambda}, {"radius_mm", r.radius},
        {"epsilon_mm", r.epsilon},
        {"normals", p.normals == mesh::NormalEstimator::kShifted ? "shifted" : "pca"},
        {"snap_edges", p.snap_edges}};
    describe_mesh_run(prov, {o.input}, {input_sha},
                      {{"method", o.method}, {"parameters", parameters}, {"threads", o.threads}},
                      o.record_paths);
    io::write_point_set(o.output, r.V, &r.normals, mesh_provenance_line(prov));
    spdlog::info("{}: {} iterations of pointset in {:.3f} s (+{:.3f} s set-up), written",
                 log_name(o.input, "points"), r.iterations, r.seconds_iterations,
                 r.seconds_setup);
    if (!o.json) return;
    const nlohmann::json j = {
        {"provenance", nlohmann::json(prov.json())},
        {"input", shown_path(o.input, o.record_paths)},
        {"input_sha256", input_sha},
        {"output", shown_path(o.output, o.record_paths)},
        {"method", o.method},
        {"parameters", parameters},
        {"points", points.rows()},
        {"mean_spacing_mm", r.mean_spacing},
        {"mean_neighbourhood_points", r.mean_neighbourhood},
        {"corner_points", r.corners},
        {"edge_points", r.edges},
        {"flat_points", r.flats},
        {"updates_held_by_epsilon", r.held_points},
        {"snapped_points", r.snapped_points},
        {"threads", o.threads},
        {"seconds_setup", r.seconds_setup},
        {"seconds_iterations", r.seconds_iterations},
        {"seconds_snap", r.seconds_snap},
        {"warnings", r.warnings}};
    std::cout << j.dump(2) << '\n';
}

// RoFi's (or bilateral filtering's) parameters: the automatic ones from the noise when
// `use_auto`, then each explicit option.
mesh::RofiParams rofi_params(const DenoiseOptions& o, const mesh::NoiseEstimate& noise,
                             bool use_auto) {
    mesh::RofiParams p;
    if (o.method == "bilateral") {
        // Classic bilateral normal filtering: Gaussian similarity, no fidelity term.
        p.similarity = mesh::Similarity::kGaussian;
        p.sigma_s = 0.35;
        p.lambda_i = 0.0;
    }
    if (use_auto) {
        // Bilateral filtering, the classic method for comparison, keeps the paper's disk.
        const mesh::RofiParams a = o.method == "bilateral"
                                       ? mesh::paper_disk_rofi_params(noise)
                                       : mesh::auto_rofi_params(noise);
        // A Gaussian of width σ weighs like a Tukey window of about 2.2 σ.
        p.sigma_s = o.method == "bilateral" ? a.sigma_s / 2.2 : a.sigma_s;
        if (o.method == "rofi") p.lambda_i = a.lambda_i;
        p.iterations = a.iterations;
        // RoFi's stop (docs/algorithms/rofi.md, "Stopping"): `iterations` is then the
        // maximum; an explicit --iterations runs exactly that many.
        if (o.method == "rofi") p.stop = a.stop;
        p.radius_factor = a.radius_factor;
        p.sigma_c_factor = a.sigma_c_factor;
    }
    if (o.similarity == "gaussian") p.similarity = mesh::Similarity::kGaussian;
    if (o.similarity == "tukey") p.similarity = mesh::Similarity::kTukey;
    if (o.sigma_s) p.sigma_s = *o.sigma_s;
    if (o.lambda_i) p.lambda_i = *o.lambda_i;
    if (o.iterations) {
        p.iterations = *o.iterations;
        p.stop = mesh::RofiStop::kNone;
    }
    if (o.radius_factor) p.radius_factor = *o.radius_factor;
    if (o.sigma_c_factor) p.sigma_c_factor = *o.sigma_c_factor;
    p.threads = o.threads;
    p.repair_folds = !o.no_fold_repair;
    // Progress on stderr for long runs (a 5 M-face mesh takes minutes): a line every
    // 5 s once 5 s have passed, none for a run that ends sooner.
    const auto started = std::chrono::steady_clock::now();
    auto reported = started;
    p.progress = [&o, started, reported](int k, int total) mutable {
        const auto now = std::chrono::steady_clock::now();
        if (now - reported < std::chrono::seconds(5)) return;
        reported = now;
        spdlog::info("{}: iteration {} of at most {} ({:.0f} s)", log_name(o.input, "mesh"),
                     k, total, std::chrono::duration<double>(now - started).count());
    };
    return p;
}

void run_denoise(const DenoiseOptions& o) {
    Provenance prov("denoise");
    const bool rofi_option = o.sigma_s || o.lambda_i || !o.similarity.empty() ||
                             o.radius_factor || o.sigma_c_factor;
    const auto rofi_only = [] {
        return UsageError("--sigma-s, --lambda-i, --similarity, --radius-factor and "
                          "--sigma-c-factor apply to rofi and bilateral");
    };
    if (o.method == "pointset") {
        if (rofi_option) throw rofi_only();
        if (o.no_fold_repair) {
            throw UsageError("--no-fold-repair applies to rofi, bilateral and envt");
        }
        run_pointset_denoise(o);
        return;
    }
    if (o.rho || o.epsilon_mm || o.normals || o.no_edge_snap) {
        throw UsageError("--rho, --epsilon, --normals and --no-edge-snap apply to pointset");
    }
    const bool rofi_like = o.method == "rofi" || o.method == "bilateral";
    if (!rofi_like && rofi_option) throw rofi_only();
    if (rofi_like && (o.tau || o.radius_mm)) {
        throw UsageError("--tau and --radius apply to envt");
    }
    const bool explicit_params = o.sigma_s || o.lambda_i || o.iterations || o.tau ||
                                 o.radius_mm || o.radius_factor || o.sigma_c_factor;
    const bool use_auto = o.use_auto || !explicit_params;

    const io::MeshData in = read_valid_mesh(o.input);
    // Fail on a bad output name before the work, not after it.
    (void)io::mesh_format_from_extension(o.output);
    const mesh::NoiseEstimate noise = mesh::estimate_noise(in.V, in.F);
    nlohmann::json params;
    mesh::DenoiseResult result;
    if (rofi_like) {
        mesh::RofiParams p = rofi_params(o, noise, use_auto);
        p.validate();
        params = {{"sigma_s", p.sigma_s},
                  {"lambda_i", p.lambda_i},
                  {"iterations", p.iterations},
                  {"lambda_decay", p.lambda_decay},
                  {"radius_factor", p.radius_factor},
                  {"sigma_c_factor", p.sigma_c_factor},
                  {"similarity", p.similarity == mesh::Similarity::kTukey ? "tukey" : "gaussian"},
                  {"repair_folds", p.repair_folds},
                  {"fix_boundary", p.fix_boundary},
                  {"stop", p.stop == mesh::RofiStop::kNone ? "none" : "white_residual"}};
        result = run_on_mesh(o.input, o.radius_factor.has_value(),
                             [&] { return mesh::rofi_denoise(in.V, in.F, p); });
    } else {
        mesh::EnvtParams p;
        if (use_auto) p = mesh::auto_envt_params(noise);
        if (o.tau) p.tau = *o.tau;
        if (o.radius_mm) p.radius = *o.radius_mm;
        if (o.iterations) p.iterations = *o.iterations;
        p.threads = o.threads;
        if (o.no_fold_repair) p.fold_repair_interval = 0;
        p.validate();
        params = {{"tau", p.tau}, {"iterations", p.iterations}, {"rho_rad", p.rho},
                  {"damping", p.damping}, {"fold_repair_interval", p.fold_repair_interval}};
        result = run_on_mesh(o.input, o.radius_mm.has_value(),
                             [&] { return mesh::envt_denoise(in.V, in.F, p); });
    }
    for (const auto& w : result.warnings) spdlog::warn("{}: {}", log_name(o.input, "mesh"), w);
    params["radius_mm"] = result.radius;
    if (rofi_like) {
        params["sigma_c_mm"] =
            params["sigma_c_factor"].get<double>() * result.mean_centroid_distance;
    }
    require_finite_result(o.input, result.V);
    const std::string input_sha = io::sha256_file(o.input);
    nlohmann::json options = {{"method", o.method}, {"auto", use_auto}, {"parameters", params},
                              {"threads", o.threads}};
    describe_mesh_run(prov, {o.input}, {input_sha}, options, o.record_paths);
    io::write_mesh(o.output, result.V, in.F, {}, mesh_provenance_line(prov));
    spdlog::info("{}: {} iterations of {} in {:.3f} s (+{:.3f} s set-up), written",
                 log_name(o.input, "mesh"), result.iterations, o.method,
                 result.seconds_iterations, result.seconds_setup);
    if (o.json) {
        const nlohmann::json j = {
            {"provenance", nlohmann::json(prov.json())},
            {"input", shown_path(o.input, o.record_paths)},
            {"input_sha256", input_sha},
            {"output", shown_path(o.output, o.record_paths)},
            {"method", o.method},
            {"auto", use_auto},
            {"parameters", params},
            {"noise", {{"normal_angle_deg", noise.normal_angle_deg},
                       {"noise_sigma_per_edge", noise.noise_sigma},
                       {"mean_edge_length_mm", noise.mean_edge_length},
                       {"mean_centroid_distance_mm", noise.mean_centroid_distance}}},
            {"iterations_run", result.iterations},
            {"residual_rms_mm", result.displacement},
            {"residual_whiteness", result.residual_whiteness},
            {"vertices", in.V.rows()},
            {"faces", in.F.rows()},
            {"fixed_boundary_vertices", result.fixed_vertices},
            {"mean_neighbourhood_faces", result.mean_neighbourhood},
            {"threads", o.threads},
            {"seconds_setup", result.seconds_setup},
            {"seconds_iterations", result.seconds_iterations},
            {"seconds_fold_repair", result.seconds_fold_repair},
            {"folds_repaired", result.folds_repaired},
            {"folds_left", result.folds_left},
            {"warnings", result.warnings}};
        std::cout << j.dump(2) << '\n';
    }
}

}  // namespace

void add_denoise_command(CLI::App& app, RunContext& /*ctx*/) {
    auto opts = std::make_shared<DenoiseOptions>();
    CLI::App* cmd = app.add_subcommand(
        "denoise",
        "Denoise a triangle mesh, keeping its sharp features (RoFi, ENVT or bilateral normal "
        "filtering). Without parameters, they are chosen from the estimated noise (--auto).");
    cmd->add_option("input", opts->input, "Mesh to denoise (.ply .obj .off .stl .vtp)")
        ->required();
    cmd->add_option("-o,--output", opts->output, "Denoised mesh (.ply .obj .off .stl .vtp)")
        ->required();
    cmd->add_option("--method", opts->method,
                    "rofi (default), envt, bilateral, or pointset (a point set: .xyz .txt .ply "
                    ".obj; uses --tau --rho --radius --epsilon -p)")
        ->check(CLI::IsMember({"rofi", "envt", "bilateral", "pointset"}));
    cmd->add_flag("--auto", opts->use_auto,
                  "Choose the parameters from the estimated noise level (the default when no "
                  "parameter is given; explicit parameters override the automatic ones)");
    cmd->add_option("--similarity", opts->similarity,
                    "rofi/bilateral: tukey (RoFi, Eq. 5.3) or gaussian (classic bilateral)")
        ->check(CLI::IsMember({"tukey", "gaussian"}));
    cmd->add_option("--sigma-s", opts->sigma_s,
                    "rofi/bilateral: similarity width on |n_i - n_j| (default 0.5; 0.35 bilateral)");
    cmd->add_option("--lambda-i", opts->lambda_i,
                    "rofi: initial fidelity factor lambda_I, x0.6 per iteration (default 0.2)");
    cmd->add_option("--iterations,-p", opts->iterations, "Iterations p (rofi 100, envt 50)");
    cmd->add_option("--tau", opts->tau, "envt: eigenvalue threshold tau (default 0.3)");
    cmd->add_option("--radius", opts->radius_mm,
                    "envt: neighbourhood radius in mesh units (default 2 c_a)");
    cmd->add_option("--radius-factor", opts->radius_factor,
                    "rofi/bilateral: disk radius r in units of c_a, the mean distance between "
                    "adjacent face centroids (default 2, thesis 5.2)");
    cmd->add_option("--sigma-c-factor", opts->sigma_c_factor,
                    "rofi/bilateral: closeness width sigma_c in units of c_a (default 1, thesis "
                    "5.2)");
    cmd->add_option("--threads", opts->threads,
                    "Threads (results are identical for any number)")
        ->check(CLI::Range(1, 256));
    cmd->add_option("--rho", opts->rho,
                    "pointset: normal-similarity angle rho in radians (default 0.3)");
    cmd->add_option("--epsilon", opts->epsilon_mm,
                    "pointset: largest distance a point may move, mesh units (default: radius)");
    cmd->add_option("--normals", opts->normals,
                    "pointset: initial normals, pca (default, thesis 4.1) or shifted (flattest "
                    "neighbourhood containing the point: sharper edges, docs/algorithms/"
                    "pointset.md)")
        ->check(CLI::IsMember({"pca", "shifted"}));
    cmd->add_flag("--no-edge-snap", opts->no_edge_snap,
                  "pointset: skip the final edge snapping (on by default: points near an edge "
                  "or corner move onto the planes of its faces, docs/algorithms/pointset.md)");
    cmd->add_flag("--no-fold-repair", opts->no_fold_repair,
                  "rofi/bilateral/envt: skip the repair of fold-overs (on by default, after "
                  "the last iteration and for envt every 10: a face turned over against an "
                  "edge-neighbour has its crossed corner moved to its 1-ring centroid, "
                  "docs/algorithms/rofi.md, envt.md)");
    cmd->add_flag("--json", opts->json, "Print the parameters and timings as JSON on stdout");
    add_record_paths_flag(cmd, opts->record_paths);
    cmd->callback([opts] { run_denoise(*opts); });
}

}  // namespace octshape::app
