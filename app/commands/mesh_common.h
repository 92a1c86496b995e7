#pragma once
// Shared by the mesh commands (denoise, metrics, features, meanshape): reading a mesh with
// libmesh's std::invalid_argument mapped to the user-facing error types, and the provenance
// line written into their output meshes.

#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "octshape/io/error.h"
#include "octshape/io/mesh_io.h"
#include "octshape/io/sha256.h"
#include "octshape/mesh/mesh.h"
#include "octshape/version.h"

namespace octshape::app {

// Reads and validates a mesh; an invalid mesh is an InputError naming the file.
inline io::MeshData read_valid_mesh(const std::filesystem::path& path) {
    io::MeshData mesh = io::read_mesh(path);
    try {
        mesh::validate_mesh(mesh.V, mesh.F);
    } catch (const std::invalid_argument& e) {
        throw InputError::corrupt(path.string(), e.what());
    }
    return mesh;
}

// The provenance of an output mesh (io::write_mesh): one line of JSON with the software
// version, the command, every input with its SHA-256 (`hashes`, in the order of `inputs`) and
// the options used.
inline std::string mesh_provenance(const std::string& command,
                                   const std::vector<std::string>& inputs,
                                   const std::vector<std::string>& hashes,
                                   const nlohmann::json& options) {
    nlohmann::json in = nlohmann::json::array();
    for (std::size_t i = 0; i < inputs.size(); ++i) {
        in.push_back({{"path", inputs[i]}, {"sha256", hashes.at(i)}});
    }
    return nlohmann::json{{"software", std::string("octshape ") + kVersion},
                          {"command", command},
                          {"inputs", in},
                          {"options", options}}
        .dump();
}

// Runs `compute` (a libmesh denoiser or feature estimate on the mesh read from `path`) and
// turns libmesh's std::invalid_argument (e.g. a neighbourhood past its bound, mesh.h) into an
// error naming the file: a UsageError when the user chose the radius (`user_radius`), else an
// InputError (the radius came from the mesh itself, e.g. inflated by a far vertex).
template <class Compute>
auto run_on_mesh(const std::string& path, bool user_radius, const Compute& compute) {
    try {
        return compute();
    } catch (const std::invalid_argument& e) {
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

// Runs `validate` and turns libmesh's std::invalid_argument into a UsageError.
template <class Params>
void validate_options(const Params& params) {
    try {
        params.validate();
    } catch (const std::invalid_argument& e) {
        throw UsageError(e.what());
    }
}

}  // namespace octshape::app
