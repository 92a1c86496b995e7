#pragma once
// Shared by the mesh commands (denoise, metrics, features, meanshape): reading a mesh (an
// invalid one is an InputError naming the file), and the provenance line written into their
// output meshes.

#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "octshape/error.h"
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
    } catch (const DataError& e) {
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

}  // namespace octshape::app
