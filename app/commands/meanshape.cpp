// `octshape meanshape MESH… -o OUT`: statistical shape analysis of surfaces (thesis §8.2,
// docs/algorithms/meanshape.md). Every surface is rigidly registered to the first (VTK's ICP),
// the mean shape (Eq. 8.25) and the per-vertex SD are computed from closest-point
// correspondences, and the mean is written with the SD as the vertex scalar "sd_mm". stdout:
// a JSON report with each surface's ICP residual.

#include <chrono>
#include <iostream>
#include <stdexcept>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include "commands/command.h"
#include "commands/mesh_common.h"
#include "octshape/io/registration.h"
#include "octshape/mesh/meanshape.h"

namespace octshape::app {
namespace {

struct MeanShapeOptions {
    std::vector<std::string> inputs;
    std::string output;
    bool record_paths = false;
    int max_iterations = io::IcpParams{}.max_iterations;
    int refine_iterations = io::IcpParams{}.refine_iterations;
    int threads = 1;
};

void run_meanshape(const MeanShapeOptions& o) {
    if (o.inputs.size() < 2) throw UsageError("meanshape needs at least two surfaces");
    const io::MeshFormat format = io::mesh_format_from_extension(o.output);
    if (format != io::MeshFormat::kVtp && format != io::MeshFormat::kPly) {
        throw UsageError(o.output + ": the mean shape carries per-vertex SD: use .vtp or .ply");
    }
    const auto t0 = std::chrono::steady_clock::now();
    Provenance prov("meanshape");
    io::IcpParams icp;
    icp.max_iterations = o.max_iterations;
    icp.refine_iterations = o.refine_iterations;
    icp.validate();
    const io::MeshData first = read_valid_mesh(o.inputs[0]);
    const mesh::Surface reference{first.V, first.F};
    std::vector<mesh::Surface> aligned;
    nlohmann::json surfaces = nlohmann::json::array();
    surfaces.push_back({{"input", shown_path(o.inputs[0], o.record_paths)},
                        {"vertices", first.V.rows()},
                        {"icp_iterations", 0},
                        {"icp_refine_iterations", 0},
                        {"icp_rotation_deg", 0.0},
                        {"icp_translation_mm", 0.0},
                        {"icp_mean_distance_mm", 0.0},
                        {"icp_rms_distance_mm", 0.0},
                        {"icp_max_distance_mm", 0.0}});
    for (std::size_t s = 1; s < o.inputs.size(); ++s) {
        const io::MeshData m = read_valid_mesh(o.inputs[s]);
        const io::IcpResult r = io::icp_rigid(m.V, reference.V, reference.F, icp);
        spdlog::info("{}: ICP {} + {} point-to-plane iterations, rotation {:.3f} deg, RMS "
                     "residual {:.4g} mm",
                     log_name(o.inputs[s], "mesh"), r.iterations, r.refine_iterations,
                     r.rotation_deg,
                     r.rms_distance);
        surfaces.push_back({{"input", shown_path(o.inputs[s], o.record_paths)},
                            {"vertices", m.V.rows()},
                            {"icp_iterations", r.iterations},
                            {"icp_refine_iterations", r.refine_iterations},
                            {"icp_rotation_deg", r.rotation_deg},
                            {"icp_translation_mm", r.translation},
                            {"icp_mean_distance_mm", r.mean_distance},
                            {"icp_rms_distance_mm", r.rms_distance},
                            {"icp_max_distance_mm", r.max_distance}});
        aligned.push_back({io::transformed(m.V, r.transform), m.F});
    }
    mesh::MeanShapeParams params;
    params.threads = o.threads;
    params.validate();
    mesh::MeanShapeResult result;
    try {
        result = mesh::mean_shape(reference, aligned, params);
    } catch (const DataError& e) {
        throw AnalysisError(o.inputs[0] + " (the reference): mean shape: " + e.what());
    }
    require_finite_result(o.inputs[0], result.mean);
    for (std::size_t s = 0; s < surfaces.size(); ++s) {
        surfaces[s]["correspondence_mean_distance_mm"] = result.mean_distance[s];
        surfaces[s]["correspondence_rms_distance_mm"] = result.rms_distance[s];
    }
    std::vector<std::string> hashes;
    for (const auto& f : o.inputs) hashes.push_back(io::sha256_file(f));
    describe_mesh_run(prov, o.inputs, hashes,
                      {{"icp_max_iterations", icp.max_iterations},
                       {"icp_refine_iterations", icp.refine_iterations},
                       {"icp_tolerance", icp.tolerance},
                       {"icp_max_landmarks", icp.max_landmarks},
                       {"icp_match_centroids", icp.match_centroids},
                       {"threads", o.threads}},
                      o.record_paths);
    io::write_mesh_vertex_scalars(o.output, result.mean, reference.F, {{"sd_mm", result.sd}},
                                  mesh_provenance_line(prov));
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    const nlohmann::json j = {{"provenance", nlohmann::json(prov.json())},
                              {"output", shown_path(o.output, o.record_paths)},
                              {"reference", shown_path(o.inputs[0], o.record_paths)},
                              {"surfaces", surfaces},
                              {"mean_sd_mm", result.sd.size() > 0 ? result.sd.mean() : 0.0},
                              {"max_sd_mm", result.sd.size() > 0 ? result.sd.maxCoeff() : 0.0},
                              {"icp_max_iterations", o.max_iterations},
                              {"icp_refine_iterations", o.refine_iterations},
                              {"seconds", seconds}};
    std::cout << j.dump(2) << '\n';
}

}  // namespace

void add_meanshape_command(CLI::App& app, RunContext& /*ctx*/) {
    auto opts = std::make_shared<MeanShapeOptions>();
    CLI::App* cmd = app.add_subcommand(
        "meanshape",
        "Mean shape of surfaces (thesis 8.2): rigid ICP of every surface to the first, "
        "closest-point correspondences, mean (Eq. 8.25) and per-vertex SD (scalar sd_mm). "
        "Prints each surface's ICP residual as JSON.");
    cmd->add_option("inputs", opts->inputs,
                    "Surfaces (.ply .obj .off .stl .vtp); the first is the reference")
        ->required();
    add_record_paths_flag(cmd, opts->record_paths);
    cmd->add_option("-o,--output", opts->output, "Mean shape with sd_mm (.vtp or .ply)")
        ->required();
    cmd->add_option("--max-iterations", opts->max_iterations,
                    "VTK point-to-point ICP iterations at most")
        ->check(CLI::Range(1, 100000))
        ->capture_default_str();
    cmd->add_option("--refine-iterations", opts->refine_iterations,
                    "Point-to-plane refinement steps after it at most (0 = none)")
        ->check(CLI::Range(0, 10000))
        ->capture_default_str();
    cmd->add_option("--threads", opts->threads, "Threads (results are identical for any number)")
        ->check(CLI::Range(1, 256));
    cmd->callback([opts] { run_meanshape(*opts); });
}

}  // namespace octshape::app
