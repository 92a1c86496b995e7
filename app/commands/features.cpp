// `octshape features MESH -o OUT`: per-face ENVT eigenvalues, feature strength and dual-mesh
// mean curvature (thesis §2.4–2.5), written as face scalars (VTP or PLY).

#include <optional>
#include <string>

#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include "commands/command.h"
#include "commands/mesh_common.h"
#include "octshape/mesh/envt.h"

namespace octshape::app {
namespace {

struct FeaturesOptions {
    std::string input;
    std::string output;
    bool record_paths = false;
    std::optional<double> radius_mm;
    int threads = 1;
};

void run_features(const FeaturesOptions& o) {
    Provenance prov("features");
    const io::MeshFormat format = io::mesh_format_from_extension(o.output);
    if (format != io::MeshFormat::kVtp && format != io::MeshFormat::kPly) {
        throw UsageError(o.output + ": face scalars need a .vtp or .ply output");
    }
    mesh::FeatureParams p;
    p.radius = o.radius_mm;
    p.threads = o.threads;
    p.validate();
    const io::MeshData in = read_valid_mesh(o.input);
    const mesh::FaceFeatures f = run_on_mesh(o.input, o.radius_mm.has_value(),
                                             [&] { return mesh::face_features(in.V, in.F, p); });
    for (const auto* values : {&f.strength, &f.mean_curvature}) {
        if (!values->allFinite() || !f.eigenvalues.allFinite()) {
            throw Error(o.input + ": a face feature is not finite (nothing written; please "
                        "report this input)");
        }
    }
    describe_mesh_run(prov, {o.input}, {io::sha256_file(o.input)},
                      {{"radius_mm", f.radius}, {"threads", o.threads}}, o.record_paths);
    io::write_mesh(o.output, in.V, in.F,
                   {{"envt_lambda1", f.eigenvalues.col(0)},
                    {"envt_lambda2", f.eigenvalues.col(1)},
                    {"envt_lambda3", f.eigenvalues.col(2)},
                    {"feature_strength", f.strength},
                    {"mean_curvature_per_mm", f.mean_curvature}},
                   mesh_provenance_line(prov));
    spdlog::info("{}: features of {} faces (radius {:.4g} mm) written",
                 log_name(o.input, "mesh"), in.F.rows(), f.radius);
}

}  // namespace

void add_features_command(CLI::App& app, RunContext& /*ctx*/) {
    auto opts = std::make_shared<FeaturesOptions>();
    CLI::App* cmd = app.add_subcommand(
        "features",
        "Per-face ENVT eigenvalues, feature strength s_f = l2 + l3 and dual-mesh mean "
        "curvature, written as face scalars");
    cmd->add_option("input", opts->input, "Mesh (.ply .obj .off .stl .vtp)")->required();
    add_record_paths_flag(cmd, opts->record_paths);
    cmd->add_option("-o,--output", opts->output, "Output mesh with face scalars (.vtp or .ply)")
        ->required();
    cmd->add_option("--radius", opts->radius_mm, "Neighbourhood radius (default 2 c_a)");
    cmd->add_option("--threads", opts->threads, "Threads")->check(CLI::Range(1, 256));
    cmd->callback([opts] { run_features(*opts); });
}

}  // namespace octshape::app
