#pragma once
// Shared by the mesh commands (denoise, metrics, features, meanshape): reading a mesh (an
// invalid one is an InputError naming the file), and their provenance block (in their JSON
// and, as one line, in their output meshes).

#include <filesystem>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "commands/eye_record.h"
#include "commands/provenance.h"
#include "octshape/error.h"
#include "octshape/io/mesh_io.h"
#include "octshape/io/sha256.h"
#include "octshape/mesh/mesh.h"

namespace octshape::app {

// Reads and validates a mesh; an invalid mesh is an InputError naming the file.
inline io::MeshData read_valid_mesh(const std::filesystem::path& path) {
    io::MeshData mesh = io::read_mesh(path);
    try {
        mesh::validate_mesh(mesh.V, mesh.F);
    } catch (const DataError& e) {
        throw InputError::corrupt(path.string(), e.what());
    }
    return mesh;
}

// Fills the provenance block of a mesh command (commands/provenance.h; `p` made when the run
// started, with the command's name): every input by its SHA-256 (`hashes`, in the order of
// `inputs`; the path too only with `record_paths`, --record-paths: a file name may name the
// patient) and the effective options. Its JSON (`p.json()`) goes into the command's JSON
// output, its untimed JSON (`mesh_provenance_line`) into the output mesh (io::write_mesh), so
// that a re-run writes the same mesh byte for byte.
inline void describe_mesh_run(Provenance& p,
                              const std::vector<std::string>& inputs,
                              const std::vector<std::string>& hashes,
                              const nlohmann::json& options,
                              bool record_paths = false) {
    for (std::size_t i = 0; i < inputs.size(); ++i) {
        p.add_input(hashes.at(i), record_paths ? inputs[i] : std::string());
    }
    p.set_options(nlohmann::ordered_json::parse(options.dump()));
}

// The one line of JSON written into an output mesh (`octshape_provenance`).
inline std::string mesh_provenance_line(const Provenance& p) { return p.json_untimed().dump(); }

// A path field of a command's JSON: the path with --record-paths (identifying: a file name may
// name the patient), else null; the SHA-256 beside it identifies the file.
inline nlohmann::json shown_path(const std::string& path, bool record_paths) {
    return record_paths ? nlohmann::json(path) : nlohmann::json(nullptr);
}

// --record-paths on a command (docs/outputs.md, "Privacy").
inline void add_record_paths_flag(CLI::App* cmd, bool& record_paths) {
    cmd->add_flag("--record-paths", record_paths,
                  "Also write the input and output paths into the JSON (identifying: a file or "
                  "folder name may name the patient; by default each input is identified by its "
                  "SHA-256 only)");
}

// Runs `compute` (a libmesh denoiser or feature estimate on the mesh read from `path`) and
// turns libmesh's DataError (e.g. a neighbourhood past its bound, mesh.h) into an
// error naming the file: a UsageError when the user chose the radius (`user_radius`), else an
// InputError (the radius came from the mesh itself, e.g. inflated by a far vertex).
template <class Compute>
auto run_on_mesh(const std::string& path, bool user_radius, const Compute& compute) {
    try {
        return compute();
    } catch (const DataError& e) {
        if (user_radius) throw UsageError(path + ": " + e.what() + "; choose a smaller radius");
        throw InputError::corrupt(path, e.what());
    }
}

// A result about to be written must be finite: a non-finite vertex is refused (a bug, exit 70,
// since finite inputs within io::kMaxMeshCoordinate cannot overflow), so that a success never
// writes one.
inline void require_finite_result(const std::string& path, const mesh::Vertices& V) {
    for (Eigen::Index i = 0; i < V.rows(); ++i) {
        if (!V.row(i).allFinite()) {
            throw Error(path + ": the result has a non-finite vertex " + std::to_string(i) +
                        " (nothing written; please report this input)");
        }
    }
}

}  // namespace octshape::app
