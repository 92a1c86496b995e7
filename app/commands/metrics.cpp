// `octshape metrics MESH --reference REF`: E_v, MSAE, Q, flipped faces and volume change of a
// mesh against a reference surface (thesis §3.2.3, §5.2.2; docs/algorithms/mesh.md).

#include <cstdio>
#include <cmath>
#include <iostream>
#include <string>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "commands/command.h"
#include "commands/mesh_common.h"
#include "octshape/io/sha256.h"
#include "octshape/mesh/metrics.h"

namespace octshape::app {
namespace {

struct MetricsOptions {
    std::string mesh;
    std::string reference;
    std::string input;  // the denoiser's input: flips created / kept / fixed
    bool json = false;
    bool record_paths = false;
};

bool same_triangulation(const io::MeshData& a, const io::MeshData& b) {
    return a.F.rows() == b.F.rows() && a.V.rows() == b.V.rows() && a.F == b.F;
}

void run_metrics(const MetricsOptions& o) {
    const io::MeshData m = read_valid_mesh(o.mesh);
    const io::MeshData r = read_valid_mesh(o.reference);
    Provenance prov("metrics");
    const std::string mesh_sha = io::sha256_file(o.mesh);
    const std::string reference_sha = io::sha256_file(o.reference);
    prov.add_input(mesh_sha, o.record_paths ? o.mesh : std::string(), {{"role", "mesh"}});
    prov.add_input(reference_sha, o.record_paths ? o.reference : std::string(),
                   {{"role", "reference"}});
    prov.set_options({{"input", !o.input.empty()}, {"json", o.json}});
    nlohmann::json j = {{"provenance", nullptr},
                        {"mesh", shown_path(o.mesh, o.record_paths)},
                        {"mesh_sha256", mesh_sha},
                        {"reference", shown_path(o.reference, o.record_paths)},
                        {"reference_sha256", reference_sha},
                        {"vertices", m.V.rows()},
                        {"faces", m.F.rows()}};
    const bool same = same_triangulation(m, r);
    if (!same && !o.input.empty()) {
        throw UsageError(o.reference + ": --input needs the mesh and the reference to share "
                         "the triangulation (to count flips), and this reference does not");
    }
    if (same) {
        const mesh::MeshComparison c = mesh::compare_meshes(m.V, m.F, r.V, r.F);
        j["e_v_mm"] = c.vertex_error;
        j["msae_deg"] = c.msae_deg;
        j["quality_q"] = c.quality;
        j["reference_quality_q"] = c.reference_quality;
        j["flipped_faces"] = c.flipped_faces;
        j["volume_mm3"] = c.volume;
        j["reference_volume_mm3"] = c.reference_volume;
        j["volume_change_fraction"] = c.volume_change;
        j["closed"] = c.closed;
        if (!o.input.empty()) {
            const io::MeshData in = read_valid_mesh(o.input);
            const std::string input_sha = io::sha256_file(o.input);
            j["input_sha256"] = input_sha;
            prov.add_input(input_sha, o.record_paths ? o.input : std::string(),
                           {{"role", "input"}});
            if (!same_triangulation(in, m)) {
                throw UsageError(o.input + ": --input is not the same triangulation as " +
                                 o.mesh + " (flips created by a denoiser need the mesh it was "
                                 "given)");
            }
            const mesh::FlipTransitions t = mesh::flip_transitions(m.V, in.V, r.V, m.F);
            j["input"] = shown_path(o.input, o.record_paths);
            j["input_flipped_faces"] = t.input;
            j["flipped_faces_created"] = t.created;
            j["flipped_faces_kept"] = t.kept;
            j["flipped_faces_fixed"] = t.fixed;
        }
    } else {
        // Different triangulations: only the measures that need no face correspondence.
        const mesh::TriangleTree tree(r.V, r.F);
        j["e_v_mm"] = mesh::vertex_error(m.V, m.F, tree);
        j["quality_q"] = mesh::mesh_quality(m.V, m.F);
        j["reference_quality_q"] = mesh::mesh_quality(r.V, r.F);
        j["volume_mm3"] = mesh::signed_volume(m.V, m.F);
        j["reference_volume_mm3"] = mesh::signed_volume(r.V, r.F);
        j["note"] = "triangulations differ: msae_deg and flipped_faces need the same faces";
    }
    // Q is +inf on a mesh with a face of zero area (metrics.h): reported as undefined, never
    // printed as a number. Nothing else printed may be non-finite.
    for (const char* key : {"quality_q", "reference_quality_q"}) {
        if (j.contains(key) && !std::isfinite(j[key].get<double>())) {
            j.erase(key);
            const std::string which = std::string(key) == "quality_q" ? o.mesh : o.reference;
            j["note"] = (j.contains("note") ? j["note"].get<std::string>() + "; " : std::string()) +
                        std::string(key) + " undefined: " + which + " has a face of zero area";
        }
    }
    j["provenance"] = nlohmann::json(prov.json());
    for (const auto& [key, value] : j.items()) {
        if (value.is_number_float() && !std::isfinite(value.get<double>())) {
            throw Error(o.mesh + ": metric " + key + " is not finite (please report this input)");
        }
    }
    if (o.json) {
        std::cout << j.dump(2) << '\n';
        return;
    }
    for (const char* key : {"e_v_mm", "msae_deg", "quality_q", "reference_quality_q",
                            "flipped_faces", "input_flipped_faces", "flipped_faces_created",
                            "flipped_faces_kept", "flipped_faces_fixed", "volume_mm3", "reference_volume_mm3",
                            "volume_change_fraction"}) {
        if (!j.contains(key)) continue;
        std::cout << key << '\t' << j[key].dump() << '\n';
    }
    if (j.contains("note")) std::cout << "note\t" << j["note"].get<std::string>() << '\n';
}

}  // namespace

void add_metrics_command(CLI::App& app, RunContext& /*ctx*/) {
    auto opts = std::make_shared<MetricsOptions>();
    CLI::App* cmd = app.add_subcommand(
        "metrics",
        "Compare a mesh with a reference: E_v (closest point on the reference triangles), "
        "MSAE, mesh quality Q, flipped faces, volume change");
    cmd->add_option("mesh", opts->mesh, "Mesh to evaluate")->required();
    cmd->add_option("--reference", opts->reference, "Reference (ground-truth) mesh")->required();
    cmd->add_option("--input", opts->input,
                    "The denoiser's input (same triangulation): also count the flipped faces "
                    "it created, kept and fixed");
    cmd->add_flag("--json", opts->json, "Print JSON instead of tab-separated lines");
    add_record_paths_flag(cmd, opts->record_paths);
    cmd->callback([opts] { run_metrics(*opts); });
}

}  // namespace octshape::app
